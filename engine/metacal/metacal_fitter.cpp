// One object's metacalibration; see metacal_fitter.hpp.
#include "engine/metacal/metacal_fitter.hpp"

#include <algorithm>
#include <cmath>

#include "engine/common/number_text.hpp"
#include "engine/common/random_stream.hpp"
#include "engine/metacal/reconvolution_psf.hpp"

namespace stampede {
namespace {

// 90 degrees counter-clockwise about the stamp's centre: in(x, y) lands at (S-1-y, x).
void rotate(std::span<const double> in, std::span<double> out, int s) {
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x) out[static_cast<std::size_t>(x) * s + (s - 1 - y)] = in[static_cast<std::size_t>(y) * s + x];
}
// The inverse of rotate(), added to `out`.
void add_rotated_back(std::span<const double> in, std::span<double> out, int s) {
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x) out[static_cast<std::size_t>(y) * s + x] += in[static_cast<std::size_t>(x) * s + (s - 1 - y)];
}

// The fit options of the chosen metacal model: one component, the other's amplitude held at 0.
FitterOptions with_model(FitterOptions o, MetacalModel model) {
  auto only = [&](Param keep, Param zero) {
    o.params[zero].free = false;
    o.params[zero].start = 0;
    o.params[keep].free = true;
  };
  switch (model) {
    case MetacalModel::kBulgeDisc: break;
    case MetacalModel::kExponential: only(Param::kDiscA, Param::kBulgeA); break;
    case MetacalModel::kGaussian:
      only(Param::kBulgeA, Param::kDiscA);
      o.params[Param::kBulgeIndex].free = false;
      o.params[Param::kBulgeIndex].start = 0.5;
      break;
  }
  return o;
}

constexpr std::uint64_t kFixnoisePurpose = 0x6669786e6f697365ull;  // "fixnoise"

}  // namespace

bool MetacalOptions::IsValid(std::string* why) const {
  if (!(step > 0 && step <= 0.1)) {
    if (why) *why = "metacal_step = " + number_text(step) + ": must be in (0, 0.1]";
    return false;
  }
  if (!(psf_dilation == 0 || (psf_dilation >= 1 && psf_dilation <= 3))) {
    if (why) *why = "metacal_psf_dilation = " + number_text(psf_dilation) + ": must be 0 (automatic) or in [1, 3]";
    return false;
  }
  return true;
}

MetacalFitter::MetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options, int stamp_size,
                             FftPlanCache& plans, FftPlanning planning)
    : fit_options_(with_model(fit_options, options.model)),
      options_(options),
      s_(stamp_size),
      imager_(stamp_size, MetacalImager::padded_size(stamp_size), planning) {
  fitter_ = std::make_unique<Fitter>(fit_options_, nullptr, plans);
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  images_.resize(kNumMetacalTypes * npix);
  noise_images_.resize(kNumMetacalTypes * npix);
  noise_.resize(npix);
  rotated_.resize(npix);
  weight_.resize(npix);
}

bool MetacalFitter::set_psf(const PsfModel& psf, std::string* error) {
  if (have_psf_ && psf == psf_) return filters_ != nullptr;
  have_psf_ = true;
  psf_ = psf;
  filters_.reset();
  fitter_->set_psf(nullptr);
  filters_ = reconvolution_filters(psf, options_, imager_.period(), error);
  if (!filters_) return false;
  gamma_ = filters_->reconvolution();
  auto prepared = fitter_->renderer().prepare_psf(gamma_, error);
  if (!prepared) {
    filters_.reset();
    return false;
  }
  fitter_->set_psf(prepared);
  return true;
}

bool MetacalFitter::make_images(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                                std::int64_t object_id, double* image_variance) {
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  // The data's per-pixel noise: the weight map's, or noise_sigma's. A masked pixel has none to
  // deconvolve: it is zeroed in the data (and the caller flags the row).
  const double sigma = fit_options_.noise_sigma;
  double variance_sum = 0;
  bool masked = false;
  for (std::size_t i = 0; i < npix; ++i) {
    double var = sigma * sigma;
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
  std::copy(pixels.begin(), pixels.end(), rotated_.begin());
  if (masked)
    for (std::size_t i = 0; i < npix; ++i)
      if (weight[i] == 0) rotated_[i] = 0;
  const double centre = 0.5 * (s_ - 1);
  imager_.make_images(rotated_, *filters_, centre, centre, images_);
  const double mean_variance = variance_sum / static_cast<double>(npix);
  const bool fixnoise = options_.fixnoise && mean_variance > 0;
  if (fixnoise) {
    RandomStream rng({options_.seed, static_cast<std::uint64_t>(object_id), kFixnoisePurpose});
    for (std::size_t i = 0; i < npix; ++i) noise_[i] *= rng.normal();
    rotate(noise_, rotated_, s_);
    imager_.make_images(rotated_, *filters_, centre, centre, noise_images_);
    for (int t = 0; t < kNumMetacalTypes; ++t)
      add_rotated_back(std::span<const double>(noise_images_).subspan(t * npix, npix),
                       std::span<double>(images_).subspan(t * npix, npix), s_);
  }
  // The images' noise: the data's through the noshear filter, twice that with fixnoise.
  *image_variance = mean_variance * filters_->noise_gain() * (fixnoise ? 2.0 : 1.0);
  return !masked;
}

void MetacalFitter::fit(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                        std::int64_t object_id, std::uint32_t failure_flag, FitResult* noshear, MetacalRecord* record,
                        std::uint32_t* flags) {
  *record = MetacalRecord();
  *noshear = FitResult();
  if (!filters_) {
    noshear->status = FitStatus::kPsfFailure;
    *flags |= failure_flag;
    return;
  }
  // What the fitter refuses on the data must be refused here too: the operations would spread a
  // NaN over every pixel, and fixnoise would give a flat stamp a galaxy of noise to fit.
  bool any = false, flat = true, finite = true;
  double first = 0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    if (!weight.empty() && weight[i] == 0) continue;
    if (!std::isfinite(pixels[i]) || (!weight.empty() && !(weight[i] > 0 && std::isfinite(weight[i])))) finite = false;
    if (!any) first = pixels[i];
    flat = flat && pixels[i] == first;
    any = true;
  }
  if (!finite || !any || flat) {
    noshear->status = !finite ? FitStatus::kBadPixels : FitStatus::kNoData;
    *flags |= failure_flag;
    return;
  }
  double variance = 0;
  if (!make_images(pixels, weight, kind, object_id, &variance)) *flags |= failure_flag;
  std::span<const double> w;
  if (variance > 0) {
    std::fill(weight_.begin(), weight_.end(), 1.0 / variance);
    w = weight_;
  }
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  auto image = [&](MetacalType t) { return std::span<const double>(images_).subspan(static_cast<int>(t) * npix, npix); };
  *noshear = fitter_->fit(image(MetacalType::kNoshear), w, WeightKind::kInverseVariance);
  std::array<double, kNumMetacalTypes> e1{}, e2{};
  bool usable = true;
  for (int t = 1; t < kNumMetacalTypes; ++t) {
    const MetacalType type = static_cast<MetacalType>(t);
    // Each image is fitted exactly as the noshear one, from its own moments: R must be the
    // response of the estimator that measured e. Starting from the noshear solution instead keeps
    // every fit in the noshear fit's basin, so R misses the basin changes that a real shear causes
    // in noisy data: at S/N 20 it read <R> 0.99 where the true response was 1.09 (docs/metacal.md).
    const FitResult r = fitter_->fit(image(type), w, WeightKind::kInverseVariance);
    usable = usable && r.status == FitStatus::kOk;
    e1[t] = r.params[index(Param::kE1)];
    e2[t] = r.params[index(Param::kE2)];
    record->e1[t - 1] = e1[t];
    record->e2[t - 1] = e2[t];
    record->snr[t - 1] = r.snr;
    record->radius[t - 1] = r.params[index(Param::kRadius)];
  }
  if (!usable || noshear->status != FitStatus::kOk) *flags |= failure_flag;
  const double two_step = 2 * options_.step;
  record->r11 = (e1[1] - e1[2]) / two_step;
  record->r21 = (e2[1] - e2[2]) / two_step;
  record->r12 = (e1[3] - e1[4]) / two_step;
  record->r22 = (e2[3] - e2[4]) / two_step;
}

}  // namespace stampede
