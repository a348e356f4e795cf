// Fuzz target: the noise-bias calibration table (io/calibration_table) that `calibrate apply` reads,
// and the bias model built from it (the interpolation between its grid nodes).
#include <stdexcept>

#include "engine/calibration/noise_bias.hpp"
#include "fuzz/fuzz_file.hpp"
#include "io/calibration_table.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  stampede::CalibrationTable table;
  try {
    table = stampede::io::read_calibration_table(input.path());
  } catch (const std::runtime_error&) {
    return 0;  // stampede::Error (FitsError) naming the file, HDU or key
  }
  try {
    const stampede::NoiseBiasModel model(table);
    bool clamped = false;
    for (double r : {0.0, 0.5, 2.0, 1e300})
      for (double f : {-1.0, 0.3, 2.0}) model.at({r, f, 0.4}, &clamped);
  } catch (const std::invalid_argument&) {
    // a table whose curves are missing, failed or out of order, or whose grid is not increasing
  }
  return 0;
}
