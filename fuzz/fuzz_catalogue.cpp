// Fuzz target: an object catalogue, text or FITS table (io/catalogue_source), cut from a fixed
// valid 40 x 30 image: validated, then every stamp cut. Catalogue PSF columns are read when the
// input's size is odd, so one corpus covers both column sets.
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "fuzz/fuzz_file.hpp"
#include "io/catalogue_source.hpp"

namespace {

const stampede::fuzz::FuzzFile& image() {
  static const stampede::fuzz::FuzzFile file(stampede::fuzz::fits_bytes([](stampede::io::FitsFile& f) {
    std::vector<double> pixels(40 * 30);
    for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<double>(i % 11);
    f.write_image(40, 30, pixels);
  }));
  return file;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile catalogue({data, size});
  stampede::io::CatalogueColumns columns;
  columns.with_psf = size % 2 == 1;
  try {
    const std::int64_t saved[] = {1};
    stampede::io::CatalogueStampSource source(image().path(), "", catalogue.path(), 8, columns,
                                              size % 3 == 0 ? std::span<const std::int64_t>(saved) : std::span<const std::int64_t>());
    stampede::StampBatch batch(4);
    while (source.fill(batch)) {
    }
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) or std::runtime_error naming the file, line or row
  }
  return 0;
}
