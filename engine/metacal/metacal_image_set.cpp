// One stamp's five metacal images with fixnoise; see metacal_image_set.hpp.
#include "engine/metacal/metacal_image_set.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "kernels/math/blocked_loop.hpp"

namespace stampede {
namespace {

// 90 degrees counter-clockwise about the stamp's centre: in(x, y) lands at (S-1-y, x).
void rotate(std::span<const double> in, std::span<double> out, int s) {
  kernels::for_each_blocked(s, s, [&](int y, int x) {
    out[static_cast<std::size_t>(x) * s + (s - 1 - y)] = in[static_cast<std::size_t>(y) * s + x];
  });
}

}  // namespace

MetacalImageSet::MetacalImageSet(int stamp_size, FftPlanning planning, int period, Precision precision,
                                 NoiseDraw draw)
    : s_(stamp_size),
      period_(period > 0 ? period : MetacalImager::padded_size(stamp_size)),
      draw_(draw),
      spectrum_(stamp_size, period_) {
  if (precision == Precision::kSingle)
    single_imager_ = std::make_unique<BasicMetacalImager<float>>(stamp_size, period_, planning);
  else
    imager_ = std::make_unique<MetacalImager>(stamp_size, period_, planning);
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  noise_.resize(npix);
  data_.resize(npix);
  turned_.resize(npix);
}

bool MetacalImageSet::make(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                           double noise_sigma, const MetacalFilters& filters, const MetacalOptions& options,
                           RandomStream noise, std::span<double> out, double* image_variance, double fixnoise_sign,
                           std::vector<double>* noise_power, std::span<const double> noise_field) {
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  if (pixels.size() != npix || (!weight.empty() && weight.size() != npix) || out.size() != kNumMetacalTypes * npix ||
      (!noise_field.empty() && noise_field.size() != npix))
    throw std::invalid_argument("MetacalImageSet::make: sizes do not match the stamp");
  double variance_sum = 0;
  bool masked = false;
  // One variance for every pixel (no weight map, or a uniform one: a simulated cell's): one
  // division and square root, not one per pixel; the sum as the general loop's.
  const bool uniform = weight.empty() || (weight[0] != 0 && std::all_of(weight.begin(), weight.end(),
                                                                         [w0 = weight[0]](double w) { return w == w0; }));
  if (uniform) {
    double var = noise_sigma * noise_sigma;
    if (!weight.empty() && kind == WeightKind::kInverseVariance) var = 1.0 / weight[0];
    if (!std::isfinite(var)) var = 0;
    std::fill(noise_.begin(), noise_.end(), std::sqrt(var));
    for (std::size_t i = 0; i < npix; ++i) variance_sum += var;
  }
  for (std::size_t i = 0; i < npix && !uniform; ++i) {
    double var = noise_sigma * noise_sigma;
    if (!weight.empty() && weight[i] == 0) {
      masked = true;
      var = 0;
    } else if (!weight.empty() && kind == WeightKind::kInverseVariance) {
      var = 1.0 / weight[i];
    }
    if (!std::isfinite(var)) var = 0;
    noise_[i] = std::sqrt(var);
    variance_sum += var;
  }
  std::copy(pixels.begin(), pixels.end(), data_.begin());
  if (masked)
    for (std::size_t i = 0; i < npix; ++i)
      if (weight[i] == 0) data_[i] = 0;
  const double centre = 0.5 * (s_ - 1);
  const double mean_variance = variance_sum / static_cast<double>(npix);
  const bool fixnoise = options.fixnoise && mean_variance > 0;
  if (fixnoise) {
    if (noise_field.empty() && draw_ == NoiseDraw::kPairs) {
      noise.normals(turned_);
      for (std::size_t i = 0; i < npix; ++i) noise_[i] *= fixnoise_sign * turned_[i];
    } else if (noise_field.empty()) {
      for (std::size_t i = 0; i < npix; ++i) noise_[i] *= fixnoise_sign * noise.normal();
    } else
      for (std::size_t i = 0; i < npix; ++i) noise_[i] = noise_[i] > 0 ? fixnoise_sign * noise_field[i] : 0.0;
    rotate(noise_, turned_, s_);
  }
  const std::span<const double> turned = fixnoise ? std::span<const double>(turned_) : std::span<const double>();
  if (single_imager_)
    single_imager_->make_images(data_, filters, centre, centre, out, turned);
  else
    imager_->make_images(data_, filters, centre, centre, out, turned);
  *image_variance = mean_variance * filters.noise_gain() * (fixnoise ? 2.0 : 1.0);
  if (noise_power) {
    noise_power->clear();
    if (mean_variance > 0) metacal_noise_power(filters, mean_variance, fixnoise, noise_power);
  }
  return !masked;
}

}  // namespace stampede
