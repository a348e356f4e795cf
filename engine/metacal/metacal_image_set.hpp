// One stamp's (or cutout's) five metacal images with fixnoise: the data through MetacalImager, and,
// with fixnoise, a noise field of the data's per-pixel variance rotated by 90 degrees, taken
// through the same operations and rotated back, so that the images' correlated noise is
// isotropic (Sheldon & Huff 2017). Shared by the single-stamp and the multi-epoch metacal fits.
// Allocates at construction only.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "engine/common/random_stream.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/metacal/metacal_imager.hpp"
#include "engine/metacal/metacal_noise.hpp"
#include "engine/metacal/metacal_options.hpp"

namespace stampede {

// Keys an object's fixnoise stream: {seed, object id, kFixnoisePurpose} (then the cutout, from
// the second on).
inline constexpr std::uint64_t kFixnoisePurpose = 0x6669786e6f697365ull;  // "fixnoise"

class MetacalImageSet {
 public:
  // period: the grid's (MetacalImager::padded_size); 0: padded_size(stamp_size). precision: the
  // images' arithmetic (kSingle for metadetection cells: half the time, within ~2e-7 of their peak).
  // draw: how the fixnoise field's normals are drawn from its stream: one per RandomStream::normal()
  // (metacal's fits), or in pairs by RandomStream::normals() (cells: 4x faster, other values).
  enum class Precision { kDouble, kSingle };
  enum class NoiseDraw { kOneByOne, kPairs };
  MetacalImageSet(int stamp_size, FftPlanning planning, int period = 0, Precision precision = Precision::kDouble,
                  NoiseDraw draw = NoiseDraw::kOneByOne);

  int stamp_size() const { return s_; }
  int period() const { return period_; }

  // The five images (kMetacalTypes order, stamp_size^2 each) into `out`. The data's noise per
  // pixel: the weight map's (kInverseVariance), else noise_sigma. A masked pixel (weight 0) has
  // none to deconvolve: it is zeroed and make() returns false. *image_variance: the images'
  // per-pixel noise variance (the data's through the noshear filter, twice that with fixnoise; 0
  // for noise-free data). `noise` draws the fixnoise field (used only with options.fixnoise),
  // multiplied by fixnoise_sign (-1 for the noise-negated member of a simulated noise pair).
  // noise_power (when not null): the images' noise power (metacal_noise_power; empty for
  // noise-free data), for noise_spectrum()'s variances. noise_field (stamp_size^2, when not empty):
  // the fixnoise field itself, a realisation of the data's noise the input carries (a NOISE plane),
  // used instead of drawing one from `noise` (zero at masked pixels).
  bool make(std::span<const double> pixels, std::span<const double> weight, WeightKind kind, double noise_sigma,
            const MetacalFilters& filters, const MetacalOptions& options, RandomStream noise, std::span<double> out,
            double* image_variance, double fixnoise_sign = 1.0, std::vector<double>* noise_power = nullptr,
            std::span<const double> noise_field = {});

  // The variances of linear combinations of this stamp size's images' pixels.
  NoiseSpectrum& noise_spectrum() { return spectrum_; }

 private:
  int s_, period_;
  NoiseDraw draw_;
  std::unique_ptr<MetacalImager> imager_;
  std::unique_ptr<BasicMetacalImager<float>> single_imager_;
  NoiseSpectrum spectrum_;
  std::vector<double> data_, noise_, turned_;  // the masked stamp, the fixnoise field, it turned
};

}  // namespace stampede
