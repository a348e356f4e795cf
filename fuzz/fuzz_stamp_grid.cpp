// Fuzz target: a GREAT08-layout stamp grid image (io/grid_source, io/stamp_grid), read to its end.
#include <stdexcept>

#include "fuzz/fuzz_file.hpp"
#include "io/grid_source.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    // Stamp size from the header (STAMPSZ), as `stampede fit` takes it when the run sets none.
    stampede::io::GridStampSource source(input.path(), "", 0);
    stampede::StampBatch batch(4);
    while (source.fill(batch)) {
    }
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError): the documented answer to a bad file
  }
  return 0;
}
