// `stampede sim cells`: argv[0] = "sim", argv[1] = "cells", then the options (--help lists them).
#pragma once

int run_sim_cells_command(int argc, char** argv);
