// `stampede calibrate build | apply`: the noise-bias calibration of im3shape section 5.3 and
// appendix C (engine/calibration/calibration_grid.hpp, engine/calibration/noise_bias.hpp; file layout in
// io/calibration_table.hpp).
#pragma once

int run_calibrate_command(int argc, char** argv);
