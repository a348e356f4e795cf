// `stampede demo`: fits the noise-free GREAT08-like example set and prints true vs recovered
// ellipticities, a readable first run of the fitting core.
#pragma once

int run_demo_command(int argc, char** argv);
