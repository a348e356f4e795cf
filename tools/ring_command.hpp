// `stampede ring`: the noise-free ring-test studies of the im3shape paper's section 4 as CSV
// tables (figures 2, 4, 5 and 6); tools/plot_ring.py draws them.
#pragma once

int run_ring_command(int argc, char** argv);
