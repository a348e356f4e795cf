// `stampede sim meds`: argv[0] = "sim", argv[1] = "meds", then the options (--help lists them).
#pragma once

int run_sim_meds_command(int argc, char** argv);
