// Fuzz target: the cell image reader (io/cell_image_reader) of `stampede metadetect IMAGE.fits`:
// the shape, the image with its planes and PSF, the scene record. An image read must hold what the
// reader promises: planes of the image's size, every pixel finite, weights >= 0 and finite, masked
// pixels zero and counted once by cause, a PSF with a middle pixel; else abort, a finding.
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "fuzz/fuzz_file.hpp"
#include "io/cell_image_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    stampede::io::read_cell_image_shape(input.path());
    stampede::io::read_scene_record(input.path());
    const stampede::io::CellImage im = stampede::io::read_cell_image(input.path(), true);
    const auto npix = static_cast<std::size_t>(im.width) * static_cast<std::size_t>(im.height);
    if (im.pixels.size() != npix || im.weight.size() != npix || (!im.noise.empty() && im.noise.size() != npix)) std::abort();
    long long masked = 0;
    for (std::size_t i = 0; i < npix; ++i) {
      if (!std::isfinite(im.pixels[i]) || !(im.weight[i] >= 0) || !std::isfinite(im.weight[i])) std::abort();
      if (im.weight[i] == 0 && im.pixels[i] != 0) std::abort();
      masked += im.weight[i] == 0;
    }
    if (masked != im.masked || im.masked != im.masked_by_bmask + im.masked_not_finite + im.masked_by_weight) std::abort();
    if (!im.psf || im.psf->nx % 2 == 0 || im.psf->ny % 2 == 0) std::abort();
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) naming the file, HDU, key or rule
  }
  return 0;
}
