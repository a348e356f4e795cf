// `stampede figure2`: the paper's figure 2 as a table: noise-free ring-test m1, m2 against the
// upsampling U1 for N_u in {1, 3, 5, 7}, U2 = 7; pure bulge and pure disc at sizes 1.14 and 1.4.
#pragma once

int run_figure2_command(int argc, char** argv);
