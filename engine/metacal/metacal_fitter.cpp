// One object's metacalibration; see metacal_fitter.hpp.
#include "engine/metacal/metacal_fitter.hpp"

#include <algorithm>
#include <cmath>

#include "engine/common/number_text.hpp"
#include "engine/common/random_stream.hpp"
#include "engine/metacal/metacal_noise.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
#include "kernels/weighted_moments.hpp"

namespace stampede {

FitterOptions metacal_fit_options(FitterOptions o, MetacalModel model) {
  auto only = [&](Param keep, Param zero) {
    o.params[zero].free = false;
    o.params[zero].start = 0;
    o.params[keep].free = true;
  };
  switch (model) {
    case MetacalModel::kBulgeDisc:
    case MetacalModel::kWeightedMoments: break;
    case MetacalModel::kExponential: only(Param::kDiscA, Param::kBulgeA); break;
    case MetacalModel::kGaussian:
      only(Param::kBulgeA, Param::kDiscA);
      o.params[Param::kBulgeIndex].free = false;
      o.params[Param::kBulgeIndex].start = 0.5;
      break;
  }
  return o;
}

bool MetacalOptions::IsValid(std::string* why) const {
  if (!(step >= kMinStep && step <= 0.1)) {
    if (why)
      *why = "metacal_step = " + number_text(step) + ": must be in [" + number_text(kMinStep) + ", 0.1]" +
             (step > 0 && step < kMinStep ? " (below it, errors in e of the image operations and fits, over 2 "
                                            "metacal_step, swamp R: docs/metacal.md, \"The step's floor\")"
                                          : "");
    return false;
  }
  if (!(psf_dilation == 0 || (psf_dilation >= 1 && psf_dilation <= 3))) {
    if (why) *why = "metacal_psf_dilation = " + number_text(psf_dilation) + ": must be 0 (automatic) or in [1, 3]";
    return false;
  }
  if (!(weight_fwhm == 0 || (weight_fwhm >= 0.1 && weight_fwhm <= 1000))) {
    if (why) *why = "metacal_weight_fwhm = " + number_text(weight_fwhm) + ": must be 0 (automatic) or in [0.1, 1000] (pixels; arcsec for MEDS tiles)";
    return false;
  }
  return true;
}

MetacalFitter::MetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options, int stamp_size,
                             FftPlanning planning)
    : fit_options_(metacal_fit_options(fit_options, options.model)),
      options_(options),
      s_(stamp_size),
      images_set_(stamp_size, planning),
      fitter_(fit_options_, planning) {
  image_.box_size = s_;
  const std::size_t npix = static_cast<std::size_t>(s_) * s_;
  images_.resize(kNumMetacalTypes * npix);
  weight_.resize(npix);
}

double MetacalFitter::weight_fwhm() const {
  return options_.moments_weight_fwhm(filters_ ? gamma_.fwhm() : NAN);
}

bool MetacalFitter::set_psf(const PsfModel& psf, std::string* error) {
  if (have_psf_ && psf == psf_) return filters_ != nullptr;
  have_psf_ = true;
  psf_ = psf;
  filters_.reset();
  image_.psf = nullptr;
  filters_ = reconvolution_filters(psf, options_, images_set_.period(), error);
  if (!filters_) return false;
  gamma_ = filters_->reconvolution();
  image_.psf = fitter_.renderer_for(s_).prepare_psf(gamma_, error);
  if (!image_.psf) {
    filters_.reset();
    return false;
  }
  return true;
}

bool MetacalFitter::make_images(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                                std::int64_t object_id, double* image_variance) {
  // A simulated noise pair's members (4q + r and 4q + 2 + r) share one field, negated for the second.
  const bool negated = options_.noise_pairs && object_id >= 0 && (object_id & 2);
  const std::int64_t key = negated ? object_id - 2 : object_id;
  return images_set_.make(pixels, weight, kind, fit_options_.noise_sigma, *filters_, options_,
                          RandomStream({options_.seed, static_cast<std::uint64_t>(key), kFixnoisePurpose}), images_,
                          image_variance, negated ? -1.0 : 1.0, &noise_power_);
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
  // The estimator of every image: a fit of metacal's model, or the weighted moments.
  auto measure = [&](MetacalType t) {
    if (options_.model == MetacalModel::kWeightedMoments) return moments_result(image(t), variance);
    image_.pixels = image(t), image_.weight = w;
    FitResult r = fitter_.fit({&image_, 1});
    // The fit weighs the images' noise as white; its errors and S/N are made those of the noise
    // the images carry (metacal_noise.hpp).
    if (variance > 0 && r.status == FitStatus::kOk) {
      MetacalNoise noise(&images_set_.noise_spectrum(), noise_power_);
      kernels::MomentsStamp stamp;
      stamp.image = image(t);
      stamp.size = s_;
      stamp.variance = variance;
      stamp.covariance = &noise;
      correct_fit_for_correlated_noise({&stamp, 1}, equivalent_weights(r.params[index(Param::kRadius)], gamma_.fwhm()),
                                       scratch_, &r);
    }
    return r;
  };
  *noshear = measure(MetacalType::kNoshear);
  bool usable = true;
  for (int t = 1; t < kNumMetacalTypes; ++t) {
    const MetacalType type = static_cast<MetacalType>(t);
    // Each image is fitted exactly as the noshear one, from its own moments: R must be the
    // response of the estimator that measured e. Starting from the noshear solution instead keeps
    // every fit in the noshear fit's basin, so R misses the basin changes that a real shear causes
    // in noisy data (docs/metacal.md).
    const FitResult r = measure(type);
    usable = usable && r.status == FitStatus::kOk;
    record->set_sheared(t - 1, r);
  }
  if (!usable || noshear->status != FitStatus::kOk) *flags |= failure_flag;
  record->set_response(options_.step);
}

FitResult weighted_moments_row(const kernels::WeightedMoments& m, bool unweighted, int n_pixels) {
  FitResult r;
  if (unweighted) r.flags |= kFlagUnweighted;
  r.n_pixels = n_pixels;
  if (!m.valid) {
    r.status = FitStatus::kModelFailure;
    return r;
  }
  r.status = FitStatus::kOk;
  r.params[index(Param::kX0)] = m.x;
  r.params[index(Param::kY0)] = m.y;
  r.params[index(Param::kE1)] = m.e1;
  r.params[index(Param::kE2)] = m.e2;
  // The half-light radius of the Gaussian whose weighted T this is (T = 2 sigma^2).
  r.params[index(Param::kRadius)] = 1.1774100225154747 * std::sqrt(0.5 * m.t);
  r.errors[index(Param::kE1)] = r.e1_err = m.e1_err;
  r.errors[index(Param::kE2)] = r.e2_err = m.e2_err;
  r.flux = m.flux;
  // Noise-free images have no S/N (docs/usage.md: unweighted rows' snr is NaN).
  r.snr = unweighted ? NAN : m.snr;
  return r;
}

FitResult MetacalFitter::moments_result(std::span<const double> image, double variance) {
  // Noise-free images are measured in data units, as an unweighted fit is (and flagged so).
  const bool unweighted = !(variance > 0);
  // The stamp in its own pixels (the multi-stamp form of one stamp is the same measurement), its
  // errors for the images' correlated noise.
  MetacalNoise noise(&images_set_.noise_spectrum(), noise_power_);
  kernels::MomentsStamp stamp;
  stamp.image = image;
  stamp.size = s_;
  stamp.variance = unweighted ? 1.0 : variance;
  stamp.covariance = unweighted ? nullptr : &noise;
  const kernels::WeightedMoments m = kernels::weighted_moments({&stamp, 1}, weight_fwhm(), scratch_);
  return weighted_moments_row(m, unweighted, static_cast<int>(image.size()));
}

}  // namespace stampede
