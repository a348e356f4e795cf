// Fuzz target: a weight map (io/grid_source's weight image) beside a fixed valid 2 x 2 grid of 8-pixel stamps.
#include <stdexcept>
#include <vector>

#include "fuzz/fuzz_file.hpp"
#include "io/grid_source.hpp"

namespace {

const stampede::fuzz::FuzzFile& grid_image() {
  static const stampede::fuzz::FuzzFile image(stampede::fuzz::fits_bytes([](stampede::io::FitsFile& f) {
    std::vector<double> pixels(16 * 16);
    for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<double>(i % 7);
    f.write_image(16, 16, pixels);
    f.write_key("STAMPSZ", 8, "stamp size");
  }));
  return image;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile weight({data, size});
  try {
    stampede::io::GridStampSource source(grid_image().path(), weight.path(), 0);
    stampede::StampBatch batch(3);
    while (source.fill(batch)) {
    }
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError): the documented answer to a bad file
  }
  return 0;
}
