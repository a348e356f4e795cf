// Multi-epoch metacalibration; see multi_epoch_metacal_fitter.hpp.
#include "engine/metacal/multi_epoch_metacal_fitter.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "engine/common/number_text.hpp"
#include "engine/metacal/metacal_fitter.hpp"

namespace stampede {

MultiEpochMetacalFitter::MultiEpochMetacalFitter(const FitterOptions& fit_options, const MetacalOptions& options)
    : fit_options_(metacal_fit_options(fit_options, options.model)), options_(options), fitter_(fit_options_) {}

MultiEpochMetacalFitter::~MultiEpochMetacalFitter() = default;

MetacalImageSet& MultiEpochMetacalFitter::set_for(int box_size) {
  auto it = sets_.find(box_size);
  if (it == sets_.end()) it = sets_.emplace(box_size, std::make_unique<MetacalImageSet>(box_size, FftPlanning::kEstimate)).first;
  return *it->second;
}

void MultiEpochMetacalFitter::fit(std::span<const MetacalEpoch> epochs, std::int64_t object_id, std::uint32_t failure_flag,
                                  FitResult* noshear, MetacalRecord* record, std::uint32_t* flags, std::string* problem,
                                  int n_bands, std::vector<BandFit>* bands) {
  *record = MetacalRecord();
  *noshear = FitResult();
  if (bands) bands->assign(static_cast<std::size_t>(std::max(n_bands, 0)), BandFit{});
  gamma_fwhm_ = NAN;
  epochs_used_ = 0;
  auto fail = [&](FitStatus status, const std::string& why) {
    noshear->status = status;
    *flags |= failure_flag;
    if (problem->empty()) *problem = why;
  };
  // The cutouts without masked pixels; all of them (masked pixels zeroed) when none is clean.
  used_.clear();
  bool any_data = false;
  for (const MetacalEpoch& e : epochs) {
    const bool clean = std::all_of(e.weight.begin(), e.weight.end(), [](double w) { return w > 0; });
    const bool data = std::any_of(e.weight.begin(), e.weight.end(), [](double w) { return w > 0; });
    any_data = any_data || data;
    if (clean) used_.push_back(&e);
  }
  if (!any_data) return fail(FitStatus::kNoData, "metacal: every pixel of every cutout is masked");
  const bool masked = used_.empty();
  if (masked) {
    for (const MetacalEpoch& e : epochs)
      if (std::any_of(e.weight.begin(), e.weight.end(), [](double w) { return w > 0; })) used_.push_back(&e);
    *flags |= failure_flag;
    if (problem->empty()) *problem = "metacal: every cutout has masked pixels (used zeroed; R not usable)";
  }
  // What the fitter refuses on the data is refused here too: a flat cutout set would give fixnoise
  // a galaxy of noise to fit.
  bool flat = true;
  for (const MetacalEpoch* e : used_) {
    double first = NAN;
    for (std::size_t i = 0; i < e->pixels.size() && flat; ++i) {
      if (e->weight[i] == 0) continue;
      if (std::isnan(first)) first = e->pixels[i];
      flat = e->pixels[i] == first;
    }
  }
  if (flat) return fail(FitStatus::kNoData, "metacal: the cutouts are flat");

  const std::size_t n = used_.size();
  psfs_.resize(n);
  for (std::size_t k = 0; k < n; ++k) psfs_[k] = {used_[k]->psf, used_[k]->frame, set_for(used_[k]->box_size).period()};
  std::string why;
  if (!sky_reconvolution(psfs_, options_, &gamma_, &why)) return fail(FitStatus::kPsfFailure, "metacal: " + why);
  gamma_fwhm_ = gamma_.fwhm;
  epochs_used_ = static_cast<int>(n);

  if (images_.size() < n) images_.resize(n), weights_.resize(n);
  prepared_.resize(n);
  variances_.resize(n);
  if (noise_powers_.size() < n) noise_powers_.resize(n);
  noises_.resize(n);
  const bool moments = options_.model == MetacalModel::kWeightedMoments;
  // A weight narrower than Γ, the images' PSF, samples their core in a pixel or two and R is not a
  // response (metacal_weight_fwhm = 0.1 arcsec on a MEDS tile: R11 = 16.6 with status ok); weights
  // from 1.5 Γ up are measured (docs/metacal.md).
  if (moments && weight_fwhm() < gamma_fwhm_)
    return fail(FitStatus::kModelFailure, "metacal: metacal_weight_fwhm = " + number_text(weight_fwhm()) +
                                              " is narrower than the reconvolution PSF's FWHM " + number_text(gamma_fwhm_));
  for (std::size_t k = 0; k < n; ++k) {
    const MetacalEpoch& e = *used_[k];
    const std::size_t npix = static_cast<std::size_t>(e.box_size) * e.box_size;
    images_[k].resize(kNumMetacalTypes * npix);
    weights_[k].resize(npix);
    // The first cutout's fixnoise stream is the single-stamp one (so that one cutout gives its row).
    const RandomStream noise = k == 0 ? RandomStream({options_.seed, static_cast<std::uint64_t>(object_id), kFixnoisePurpose})
                                      : RandomStream({options_.seed, static_cast<std::uint64_t>(object_id), kFixnoisePurpose, k});
    double variance = 0;
    MetacalImageSet& set = set_for(e.box_size);
    set.make(e.pixels, e.weight, WeightKind::kInverseVariance, 0.0, *gamma_.filters[k], options_, noise, images_[k],
             &variance, 1.0, &noise_powers_[k]);
    variances_[k] = variance;
    noises_[k] = MetacalNoise(&set.noise_spectrum(), noise_powers_[k]);
    if (moments) continue;  // nothing is fitted: no weight map, no Gamma to render
    // The images' noise is uniform: their weight is 1 / variance (unit for noise-free data).
    const double w = variance > 0 ? 1.0 / variance : 1.0;
    for (std::size_t i = 0; i < npix; ++i) weights_[k][i] = e.weight[i] > 0 ? w : 0.0;
    prepared_[k] = fitter_.renderer_for(e.box_size).prepare_psf(gamma_.filters[k]->reconvolution(), &why);
    if (!prepared_[k]) return fail(FitStatus::kPsfFailure, "metacal: Gamma: " + why);
  }
  auto fit_type = [&](MetacalType t) {
    if (moments) return measure_moments(t, n_bands, bands != nullptr && t == MetacalType::kNoshear);
    fit_epochs_.clear();
    for (std::size_t k = 0; k < n; ++k) {
      const MetacalEpoch& e = *used_[k];
      const std::size_t npix = static_cast<std::size_t>(e.box_size) * e.box_size;
      fit_epochs_.push_back({std::span<const double>(images_[k]).subspan(static_cast<int>(t) * npix, npix), weights_[k],
                             e.box_size, e.frame, prepared_[k], e.flux_scale, e.band});
    }
    // Each image set is fitted exactly as the noshear one, from its own moments (MetacalFitter).
    MultiBandFitResult r;
    r.bands.resize(static_cast<std::size_t>(n_bands));
    r.fit = fitter_.fit(fit_epochs_, n_bands, r.bands, 0);
    // The fit weighs the images' noise as white; its errors and S/N are made those of the noise
    // the images carry (metacal_noise.hpp); each band's S/N by the joint fit's factor.
    if (r.fit.status == FitStatus::kOk && std::all_of(variances_.begin(), variances_.begin() + n, [](double v) { return v > 0; })) {
      moment_stamps(t, -1, nullptr);
      const double white_snr = r.fit.snr;
      correct_fit_for_correlated_noise(stamps_, equivalent_weights(r.fit.params[index(Param::kRadius)], gamma_fwhm_),
                                       moments_scratch_, &r.fit);
      for (BandFit& b : r.bands) b.snr = r.bands.size() == 1 ? r.fit.snr : b.snr * (r.fit.snr / white_snr);
    }
    return r;
  };
  MultiBandFitResult noshear_bands = fit_type(MetacalType::kNoshear);
  *noshear = noshear_bands.fit;
  if (bands) *bands = std::move(noshear_bands.bands);
  std::string unusable;  // the first image set whose fit is not ok
  const std::string what = moments ? " image set's moments are " : " image set's fit is ";
  if (noshear->status != FitStatus::kOk) unusable = "noshear" + what + ToString(noshear->status);
  for (int t = 1; t < kNumMetacalTypes; ++t) {
    const FitResult r = fit_type(static_cast<MetacalType>(t)).fit;
    if (r.status != FitStatus::kOk && unusable.empty())
      unusable = std::string(metacal_type_name(static_cast<MetacalType>(t))) + what + ToString(r.status);
    record->set_sheared(t - 1, r);
  }
  if (!unusable.empty()) {
    *flags |= failure_flag;
    if (problem->empty()) *problem = "metacal: the " + unusable + " (R not usable)";
  }
  record->set_response(options_.step);
}

double MultiEpochMetacalFitter::weight_fwhm() const {
  return options_.moments_weight_fwhm(gamma_fwhm_);
}

void MultiEpochMetacalFitter::moment_stamps(MetacalType t, int band, bool* unweighted) {
  stamps_.clear();
  for (std::size_t k = 0; k < used_.size(); ++k) {
    const MetacalEpoch& e = *used_[k];
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

MultiBandFitResult MultiEpochMetacalFitter::measure_moments(MetacalType t, int n_bands, bool per_band) {
  // Noise-free images are measured in data units, as the single-stamp path does (and flagged so).
  bool unweighted = false;
  moment_stamps(t, -1, &unweighted);
  int n_pixels = 0;
  for (const kernels::MomentsStamp& st : stamps_) n_pixels += st.size * st.size;
  MultiBandFitResult out;
  const kernels::WeightedMoments m = kernels::weighted_moments(stamps_, weight_fwhm(), moments_scratch_);
  out.fit = weighted_moments_row(m, unweighted, n_pixels);
  out.bands.assign(static_cast<std::size_t>(std::max(n_bands, 0)), BandFit{});
  if (!per_band) return out;
  // Each band's weighted flux and S/N, under the same weight, about its own centroid.
  for (int b = 0; b < n_bands; ++b) {
    moment_stamps(t, b, nullptr);
    BandFit& bf = out.bands[static_cast<std::size_t>(b)];
    bf.n_epochs = static_cast<int>(stamps_.size());
    if (stamps_.empty()) continue;
    const kernels::WeightedMoments mb = kernels::weighted_moments(stamps_, weight_fwhm(), moments_scratch_);
    if (mb.valid) bf.flux = mb.flux, bf.snr = mb.snr;
  }
  return out;
}

}  // namespace stampede
