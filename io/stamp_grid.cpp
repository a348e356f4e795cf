// Stamp-grid reader; see stamp_grid.hpp.
#include "io/stamp_grid.hpp"

#include <cstddef>

#include "io/fits_error.hpp"

namespace stampede::io {

StampGridReader::StampGridReader(const std::string& path, int stamp_size) : file_(FitsFile::open_read(path)) {
  const FitsFile::ImageShape shape = file_.image_shape();
  stamp_ = stamp_size > 0 ? stamp_size : static_cast<int>(file_.key_long("STAMPSZ"));
  if (stamp_ <= 0 || shape.nx % stamp_ != 0 || shape.ny % stamp_ != 0)
    throw FitsError(file_.describe() + ": stamp size " + std::to_string(stamp_) + " does not divide the " +
                    std::to_string(shape.nx) + " x " + std::to_string(shape.ny) + " image");
  nx_ = static_cast<int>(shape.nx / stamp_);
  ny_ = static_cast<int>(shape.ny / stamp_);
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
