// `stampede sim great08`: GREAT08-like constant-shear simulations in the GalSim-mini file layout.
#pragma once

int run_sim_command(int argc, char** argv);
