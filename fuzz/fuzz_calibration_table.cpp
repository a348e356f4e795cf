// Fuzz target: the noise-bias calibration table (io/calibration_table) that `calibrate apply` reads.
#include <stdexcept>

#include "fuzz/fuzz_file.hpp"
#include "io/calibration_table.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    stampede::io::read_calibration_table(input.path());
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) naming the file, HDU or key
  }
  return 0;
}
