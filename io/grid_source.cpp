// Grid stamp source; see grid_source.hpp.
#include "io/grid_source.hpp"

#include <algorithm>

#include "io/fits_error.hpp"

namespace stampede::io {

GridStampSource::GridStampSource(const std::string& image_path, const std::string& weight_path, int stamp_size)
    : image_(image_path, stamp_size) {
  const std::size_t row = static_cast<std::size_t>(image_.grid_nx()) * image_.stamp_size() * image_.stamp_size();
  row_.resize(row);
  if (!weight_path.empty()) {
    // The shape first: a weight map of another shape is that, whether or not the stamp size divides it.
    FitsFile weight = FitsFile::open_read(weight_path);
    const auto a = image_.file().image_shape(), b = weight.image_shape();
    if (a.nx != b.nx || a.ny != b.ny)
      throw FitsError(weight.describe() + ": weight image is " + std::to_string(b.nx) + " x " + std::to_string(b.ny) +
                      ", the input image " + std::to_string(a.nx) + " x " + std::to_string(a.ny));
    weight_ = std::make_unique<StampGridReader>(weight_path, image_.stamp_size());
    weight_row_.resize(row);
  }
}

bool GridStampSource::fill(StampBatch& batch) {
  const int s = image_.stamp_size(), nx = image_.grid_nx();
  const std::size_t npix = static_cast<std::size_t>(s) * s;
  batch.begin(next_);
  while (batch.count < batch.capacity() && next_ < total_objects()) {
    const int iy = static_cast<int>(next_ / nx), ix = static_cast<int>(next_ % nx);
    if (iy != loaded_row_) {
      image_.read_stamp_row(iy, row_);
      if (weight_) weight_->read_stamp_row(iy, weight_row_);
      loaded_row_ = iy;
    }
    const int k = batch.count++;
    std::span<double> pixels, weights;
    batch.observations.add_stamp(s, &pixels, &weights).weighted = static_cast<bool>(weight_);
    std::copy_n(row_.data() + ix * npix, npix, pixels.begin());
    if (weight_) std::copy_n(weight_row_.data() + ix * npix, npix, weights.begin());
    ObjectRecord& r = batch.records[k];
    r = ObjectRecord{};
    r.id = next_;
    r.ix = ix;
    r.iy = iy;
    r.stamp_x0 = static_cast<double>(ix) * s;
    r.stamp_y0 = static_cast<double>(iy) * s;
    ++next_;
  }
  return batch.count > 0;
}

}  // namespace stampede::io
