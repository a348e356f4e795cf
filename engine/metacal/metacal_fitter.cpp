// One object's metacalibration, on a stamp or on its cutouts; see metacal_fitter.hpp.
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

MetacalFitter::MetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options, FftPlanning planning,
                             ImageWeight image_weight)
    : fit_options_(metacal_fit_options(fit_options, options.model)),
      options_(options),
      planning_(planning),
      image_weight_(image_weight),
      fitter_(fit_options_, planning) {}

MetacalFitter::~MetacalFitter() = default;

MetacalImageSet& MetacalFitter::set_for(int box_size) {
  auto it = sets_.find(box_size);
  if (it == sets_.end()) it = sets_.emplace(box_size, std::make_unique<MetacalImageSet>(box_size, planning_)).first;
  return *it->second;
}

double MetacalFitter::weight_fwhm() const {
  return options_.moments_weight_fwhm(gamma_fwhm_);
}

bool MetacalFitter::reconvolve(std::string* error) {
  const std::size_t n = used_.size();
  bool same = have_gamma_ && gamma_psfs_.size() == n;
  for (std::size_t k = 0; k < n && same; ++k) {
    const Observation& e = *used_[k];
    const PixelFrame& f = psfs_[k].frame;
    same = *e.psf_model == gamma_psfs_[k] && e.frame.dudx == f.dudx && e.frame.dudy == f.dudy && e.frame.dvdx == f.dvdx &&
           e.frame.dvdy == f.dvdy && e.frame.x_ref == f.x_ref && e.frame.y_ref == f.y_ref &&
           set_for(e.box_size).period() == psfs_[k].period;
  }
  if (!same) {
    have_gamma_ = true;
    gamma_psfs_.resize(n);
    psfs_.resize(n);
    prepared_.assign(n, nullptr);
    gamma_error_.clear();
    for (std::size_t k = 0; k < n; ++k) {
      gamma_psfs_[k] = *used_[k]->psf_model;
      psfs_[k] = {&gamma_psfs_[k], used_[k]->frame, set_for(used_[k]->box_size).period()};
    }
    gamma_served_ = sky_reconvolution(psfs_, options_, &gamma_, &gamma_error_);
    // Model fits render Gamma in every epoch's pixels; weighted moments need no model.
    for (std::size_t k = 0; k < n && gamma_served_ && options_.model != MetacalModel::kWeightedMoments; ++k) {
      std::string why;
      prepared_[k] = fitter_.renderer_for(used_[k]->box_size).prepare_psf(gamma_.filters[k]->reconvolution(), &why);
      if (!prepared_[k]) gamma_served_ = false, gamma_error_ = "Gamma: " + why;
    }
  }
  if (!gamma_served_ && error) *error = gamma_error_;
  return gamma_served_;
}

void MetacalFitter::size_for_used() {
  const std::size_t n = used_.size();
  if (images_.size() < n) images_.resize(n), weights_.resize(n), noise_powers_.resize(n);
  variances_.resize(n);
  noises_.resize(n);
  fit_weights_.resize(n);
}

void MetacalFitter::make_epoch_images(std::size_t k, std::int64_t object_id) {
  const Observation& e = *used_[k];
  const std::size_t npix = static_cast<std::size_t>(e.box_size) * e.box_size;
  images_[k].resize(kNumMetacalTypes * npix);
  // A simulated noise pair's members (4q + r and 4q + 2 + r) share one field, negated for the
  // second. The first epoch's stream is the stamp's (so that one epoch is a stamp), the others
  // are keyed by their place too.
  const bool negated = options_.noise_pairs && object_id >= 0 && (object_id & 2);
  const auto key = static_cast<std::uint64_t>(negated ? object_id - 2 : object_id);
  const RandomStream noise = k == 0 ? RandomStream({options_.seed, key, kFixnoisePurpose})
                                    : RandomStream({options_.seed, key, kFixnoisePurpose, k});
  MetacalImageSet& set = set_for(e.box_size);
  set.make(e.pixels, e.weight, e.weight_kind, fit_options_.noise_sigma, *gamma_.filters[k], options_, noise, images_[k],
           &variances_[k], negated ? -1.0 : 1.0, &noise_powers_[k]);
  noises_[k] = MetacalNoise(&set.noise_spectrum(), noise_powers_[k]);
}

void MetacalFitter::set_fit_weight(std::size_t k) {
  const Observation& e = *used_[k];
  const std::size_t npix = static_cast<std::size_t>(e.box_size) * e.box_size;
  const double variance = variances_[k];
  weights_[k].resize(npix);
  if (image_weight_ == ImageWeight::kUniform) {
    fit_weights_[k] = {};
    if (variance > 0) {
      std::fill(weights_[k].begin(), weights_[k].end(), 1.0 / variance);
      fit_weights_[k] = weights_[k];
    }
    return;
  }
  // The images' noise is uniform: their weight is 1 / variance (unit for noise-free data).
  const double w = variance > 0 ? 1.0 / variance : 1.0;
  for (std::size_t i = 0; i < npix; ++i) weights_[k][i] = e.weight.empty() || e.weight[i] > 0 ? w : 0.0;
  fit_weights_[k] = weights_[k];
}

bool MetacalFitter::make_images(const Observation& epoch, std::int64_t object_id, double* image_variance,
                                std::string* error) {
  used_.assign(1, &epoch);
  if (!reconvolve(error)) return false;
  size_for_used();
  make_epoch_images(0, object_id);
  *image_variance = variances_[0];
  return true;
}

void MetacalFitter::fit(std::span<const Observation> epochs, std::int64_t object_id, std::uint32_t failure_flag,
                        FitResult* noshear, MetacalRecord* record, std::uint32_t* flags, std::string* problem,
                        int n_bands, std::vector<BandFit>* bands) {
  *record = MetacalRecord();
  *noshear = FitResult();
  if (bands) bands->assign(static_cast<std::size_t>(std::max(n_bands, 0)), BandFit{});
  gamma_fwhm_ = NAN;
  epochs_used_ = 0;
  auto fail = [&](FitStatus status, const char* why, const std::string& detail = {}) {
    noshear->status = status;
    *flags |= failure_flag;
    if (problem->empty()) *problem = why + detail;
  };
  // What the fitter refuses on the data is refused here too: the image operations would spread a
  // NaN over every pixel.
  for (const Observation& e : epochs)
    for (std::size_t i = 0; i < e.pixels.size(); ++i) {
      const double w = e.weight.empty() ? 1.0 : e.weight[i];
      if (w != 0 && !(std::isfinite(e.pixels[i]) && w > 0 && std::isfinite(w)))
        return fail(FitStatus::kBadPixels, "metacal: a pixel or its weight is not finite, or a weight is negative");
    }
  // The epochs without masked pixels; all of them (masked pixels zeroed) when none is clean.
  auto clean = [](const Observation& e) { return std::all_of(e.weight.begin(), e.weight.end(), [](double w) { return w > 0; }); };
  auto has_data = [](const Observation& e) {
    return e.weight.empty() || std::any_of(e.weight.begin(), e.weight.end(), [](double w) { return w > 0; });
  };
  used_.clear();
  bool any_data = false;
  for (const Observation& e : epochs) {
    any_data = any_data || has_data(e);
    if (clean(e)) used_.push_back(&e);
  }
  if (!any_data) return fail(FitStatus::kNoData, "metacal: every pixel of every cutout is masked");
  if (used_.empty()) {
    for (const Observation& e : epochs)
      if (has_data(e)) used_.push_back(&e);
    *flags |= failure_flag;
    if (problem->empty()) *problem = "metacal: every cutout has masked pixels (used zeroed; R not usable)";
  }
  // A flat epoch set would give fixnoise a galaxy of noise to fit.
  bool flat = true;
  for (const Observation* e : used_) {
    double first = NAN;
    for (std::size_t i = 0; i < e->pixels.size() && flat; ++i) {
      if (!e->weight.empty() && e->weight[i] == 0) continue;
      if (std::isnan(first)) first = e->pixels[i];
      flat = e->pixels[i] == first;
    }
  }
  if (flat) return fail(FitStatus::kNoData, "metacal: the cutouts are flat");

  std::string why;
  if (!reconvolve(&why)) return fail(FitStatus::kPsfFailure, "metacal: ", why);
  const std::size_t n = used_.size();
  gamma_fwhm_ = gamma_.fwhm;
  epochs_used_ = static_cast<int>(n);
  const bool moments = options_.model == MetacalModel::kWeightedMoments;
  // A weight narrower than Γ, the images' PSF, samples their core in a pixel or two and R is not a
  // response (metacal_weight_fwhm = 0.1 arcsec on a MEDS tile: R11 = 16.6 with status ok); weights
  // from 1.5 Γ up are measured (docs/metacal.md).
  if (moments && weight_fwhm() < gamma_fwhm_)
    return fail(FitStatus::kModelFailure, "metacal: metacal_weight_fwhm = ",
                number_text(weight_fwhm()) + " is narrower than the reconvolution PSF's FWHM " + number_text(gamma_fwhm_));
  size_for_used();
  for (std::size_t k = 0; k < n; ++k) {
    make_epoch_images(k, object_id);
    if (!moments) set_fit_weight(k);  // nothing is fitted: no weight map
  }
  const MultiBandFitResult& first = measure(MetacalType::kNoshear, n_bands, bands != nullptr);
  *noshear = first.fit;
  if (bands) bands->assign(first.bands.begin(), first.bands.end());
  const char* what = moments ? " image set's moments are " : " image set's fit is ";
  const char* unusable = nullptr;  // the first image set whose fit is not ok
  FitStatus unusable_status = FitStatus::kOk;
  if (noshear->status != FitStatus::kOk) unusable = "noshear", unusable_status = noshear->status;
  for (int t = 1; t < kNumMetacalTypes; ++t) {
    // Each image set is fitted exactly as the noshear one, from its own moments: R must be the
    // response of the estimator that measured e. Starting from the noshear solution instead keeps
    // every fit in the noshear fit's basin, so R misses the basin changes that a real shear causes
    // in noisy data (docs/metacal.md).
    const FitResult& r = measure(static_cast<MetacalType>(t), n_bands, false).fit;
    if (r.status != FitStatus::kOk && !unusable)
      unusable = metacal_type_name(static_cast<MetacalType>(t)), unusable_status = r.status;
    record->set_sheared(t - 1, r);
  }
  if (unusable) {
    *flags |= failure_flag;
    if (problem->empty())
      *problem = std::string("metacal: the ") + unusable + what + ToString(unusable_status) + " (R not usable)";
  }
  record->set_response(options_.step);
}

const MultiBandFitResult& MetacalFitter::measure(MetacalType t, int n_bands, bool per_band) {
  if (options_.model == MetacalModel::kWeightedMoments) {
    measure_moments(t, n_bands, per_band);
    return measured_;
  }
  fit_epochs_.clear();
  for (std::size_t k = 0; k < used_.size(); ++k) {
    const Observation& e = *used_[k];
    const std::size_t npix = static_cast<std::size_t>(e.box_size) * e.box_size;
    fit_epochs_.push_back({std::span<const double>(images_[k]).subspan(static_cast<int>(t) * npix, npix),
                           fit_weights_[k], e.box_size, e.frame, prepared_[k], e.flux_scale, e.band});
  }
  MultiBandFitResult& r = measured_;
  r.bands.assign(static_cast<std::size_t>(n_bands), BandFit{});
  r.fit = fitter_.fit(fit_epochs_, n_bands, r.bands, 0);
  // The fit weighs the images' noise as white; its errors and S/N are made those of the noise
  // the images carry (metacal_noise.hpp); each band's S/N by the joint fit's factor.
  if (r.fit.status == FitStatus::kOk &&
      std::all_of(variances_.begin(), variances_.begin() + static_cast<std::ptrdiff_t>(used_.size()),
                  [](double v) { return v > 0; })) {
    moment_stamps(t, -1, nullptr);
    const double white_snr = r.fit.snr;
    correct_fit_for_correlated_noise(stamps_, equivalent_weights(r.fit.params[index(Param::kRadius)], gamma_fwhm_),
                                     moments_scratch_, &r.fit);
    for (BandFit& b : r.bands) b.snr = r.bands.size() == 1 ? r.fit.snr : b.snr * (r.fit.snr / white_snr);
  }
  return r;
}

void MetacalFitter::moment_stamps(MetacalType t, int band, bool* unweighted) {
  stamps_.clear();
  for (std::size_t k = 0; k < used_.size(); ++k) {
    const Observation& e = *used_[k];
    if (band >= 0 && e.band != band) continue;
    const std::size_t npix = static_cast<std::size_t>(e.box_size) * e.box_size;
    kernels::MomentsStamp s;
    s.image = std::span<const double>(images_[k]).subspan(static_cast<int>(t) * npix, npix);
    s.size = e.box_size;
    s.dudx = e.frame.dudx, s.dudy = e.frame.dudy, s.dvdx = e.frame.dvdx, s.dvdy = e.frame.dvdy;
    s.x_ref = e.frame.x_ref, s.y_ref = e.frame.y_ref;
    s.flux_scale = e.flux_scale;
    s.variance = variances_[k] > 0 ? variances_[k] : 1.0;
    s.covariance = variances_[k] > 0 ? &noises_[k] : nullptr;
    if (unweighted) *unweighted = *unweighted || !(variances_[k] > 0);
    stamps_.push_back(s);
  }
}

void MetacalFitter::measure_moments(MetacalType t, int n_bands, bool per_band) {
  // Noise-free images are measured in data units, as an unweighted fit is (and flagged so).
  bool unweighted = false;
  moment_stamps(t, -1, &unweighted);
  int n_pixels = 0;
  for (const kernels::MomentsStamp& st : stamps_) n_pixels += st.size * st.size;
  MultiBandFitResult& out = measured_;
  const kernels::WeightedMoments m = kernels::weighted_moments(stamps_, weight_fwhm(), moments_scratch_);
  out.fit = weighted_moments_row(m, unweighted, n_pixels);
  out.bands.assign(static_cast<std::size_t>(std::max(n_bands, 0)), BandFit{});
  if (!per_band) return;
  // Each band's weighted flux and S/N, under the same weight, about its own centroid.
  for (int b = 0; b < n_bands; ++b) {
    moment_stamps(t, b, nullptr);
    BandFit& bf = out.bands[static_cast<std::size_t>(b)];
    bf.n_epochs = static_cast<int>(stamps_.size());
    if (stamps_.empty()) continue;
    const kernels::WeightedMoments mb = kernels::weighted_moments(stamps_, weight_fwhm(), moments_scratch_);
    if (mb.valid) bf.flux = mb.flux, bf.snr = mb.snr;
  }
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

}  // namespace stampede
