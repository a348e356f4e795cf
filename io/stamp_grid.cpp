// Stamp-grid reader; see stamp_grid.hpp.
#include "io/stamp_grid.hpp"

#include <cstddef>
#include <utility>

#include "io/fits_error.hpp"

namespace stampede::io {

StampGridReader::StampGridReader(const std::string& path, int stamp_size) : file_(FitsFile::open_read(path)) {
  const FitsFile::ImageShape shape = file_.image_shape();
  // An image without pixels divides by any stamp size: refused here, before a stamp size from a
  // corrupt header (972,308,181 in campaign finding F9) sizes the pipeline's buffers.
  if (shape.nx <= 0 || shape.ny <= 0)
    throw FitsError(file_.describe() + ": the image has no pixels (" + std::to_string(shape.nx) + " x " +
                    std::to_string(shape.ny) + "), so no stamps");
  // Checked in 64 bits: a STAMPSZ beyond the int range had wrapped (2^32 + 8 read as 8).
  const long long stamp = stamp_size > 0 ? stamp_size : file_.key_long("STAMPSZ");
  if (stamp <= 0 || shape.nx % stamp != 0 || shape.ny % stamp != 0)
    throw FitsError(file_.describe() + ": stamp size " + std::to_string(stamp) + " does not divide the " +
                    std::to_string(shape.nx) + " x " + std::to_string(shape.ny) + " image");
  if (!std::in_range<int>(stamp) || !std::in_range<int>(shape.nx / stamp) || !std::in_range<int>(shape.ny / stamp))
    throw FitsError(file_.describe() + ": a grid of " + std::to_string(shape.nx / stamp) + " x " +
                    std::to_string(shape.ny / stamp) + " stamps of " + std::to_string(stamp) + " pixels is too large");
  stamp_ = static_cast<int>(stamp);
  nx_ = static_cast<int>(shape.nx / stamp);
  ny_ = static_cast<int>(shape.ny / stamp);
  strip_.resize(static_cast<std::size_t>(shape.nx) * stamp_);
}

void StampGridReader::read_stamp_row(int iy, std::span<double> out) {
  const std::size_t s = stamp_, width = static_cast<std::size_t>(nx_) * s;
  file_.read_image_rows(static_cast<long>(iy) * stamp_, stamp_, strip_);
  for (int ix = 0; ix < nx_; ++ix)
    for (std::size_t y = 0; y < s; ++y)
      for (std::size_t x = 0; x < s; ++x) out[ix * s * s + y * s + x] = strip_[y * width + ix * s + x];
}

}  // namespace stampede::io
