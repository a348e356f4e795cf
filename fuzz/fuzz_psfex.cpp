// Fuzz target: a PSFEx model file (io/psfex_file), read and evaluated at the image's corner and
// at its polynomial's zero point, as a per-cutout PSF will be.
#include <stdexcept>
#include <string>
#include <vector>

#include "fuzz/fuzz_file.hpp"
#include "io/psfex_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    const stampede::PsfexModel m = stampede::io::read_psfex_model(input.path());
    std::vector<double> out(static_cast<std::size_t>(m.nx) * m.ny);
    std::string error;
    m.evaluate(1, 1, out, &error);
    m.evaluate(m.zero_x, m.zero_y, out, &error);
    m.image_at(m.zero_x, m.zero_y, &error);
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) naming the file, HDU, keyword or column
  }
  return 0;
}
