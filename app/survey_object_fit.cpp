// One survey object's fit on its observations; see survey_object_fit.hpp.
#include "app/survey_object_fit.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace stampede::app {

FitterOptions single_component(FitterOptions o, Param zero) {
  o.params[zero].free = false;
  o.params[zero].start = 0;
  return o;
}

SurveyObjectFitter::SurveyObjectFitter(const MedsFitOptions& options, std::vector<std::string> tiles,
                                       std::vector<std::string> bands)
    : options_(options),
      tiles_(std::move(tiles)),
      bands_(std::move(bands)),
      fitter_(options.model == MedsModel::kBulgeOrDisc ? single_component(options.fitter, Param::kBulgeA) : options.fitter) {
  if (options.model == MedsModel::kBulgeOrDisc && options.metacal.enabled)
    throw std::invalid_argument("option 'meds_model' = 'bord' with metacal = true: metacal fits metacal_model (wmom, bd, "
                                "exp or gauss)");
  if (tiles_.empty() || tiles_.size() > static_cast<std::size_t>(kMaxBands) ||
      (bands_.size() != tiles_.size() && !(bands_.empty() && tiles_.size() == 1)))
    throw std::invalid_argument("SurveyObjectFitter: " + std::to_string(tiles_.size()) + " tiles for " +
                                std::to_string(bands_.size()) + " bands (1.." + std::to_string(kMaxBands) + ")");
  if (options.model == MedsModel::kBulgeOrDisc)
    bulge_fitter_ = std::make_unique<ObjectFitter>(single_component(options.fitter, Param::kDiscA));
  if (options.metacal.enabled) metacal_ = std::make_unique<MetacalFitter>(options.fitter, options.metacal);
}

SurveyObjectFitter::~SurveyObjectFitter() = default;

std::shared_ptr<const PreparedPsf> SurveyObjectFitter::prepare(const ArenaObservation& o, std::string* why) {
  if (o.psf_from_image) return fitter_.renderer_for(o.box_size).prepare_psf(o.psf, why);
  // The run's analytic PSF: the same for every cutout of a box size.
  std::shared_ptr<const PreparedPsf>& p = options_psf_[o.box_size];
  if (!p) p = fitter_.renderer_for(o.box_size).prepare_psf(o.psf, why);
  return p;
}

bool SurveyObjectFitter::collect(const ObservationArena& arena, int object, int band, long long row,
                                 MedsObjectResult* result) {
  MedsObjectResult& out = *result;
  const BandReading& reading = arena.reading(object, band);
  out.flags |= reading.flags;
  out.problem = reading.problem;
  if (!reading.readable) return false;
  const std::size_t first_epoch = epochs_.size();
  double psf_e1 = 0, psf_e2 = 0, psf_size = 0;
  for (int k = reading.first; k < reading.first + reading.count; ++k) {
    const ArenaObservation& o = arena[k];
    std::string why;
    const std::shared_ptr<const PreparedPsf> prepared = prepare(o, &why);
    if (!prepared) {
      if (out.problem.empty())
        out.problem = tiles_[static_cast<std::size_t>(band)] + ": object " + std::to_string(row) + ", cutout " +
                      std::to_string(o.cutout) + ": PSF: " + why;
      out.flags |= kFlagPsfCutoutDropped;  // the object is fitted on its other cutouts
      continue;
    }
    epochs_.push_back(arena.observation(o));
    epochs_.back().psf = prepared;
    const double xx = prepared->xx(), xy = prepared->xy(), yy = prepared->yy();
    psf_e1 += (xx - yy) / (xx + yy), psf_e2 += 2 * xy / (xx + yy), psf_size += std::sqrt(0.5 * (xx + yy));
  }
  out.n_epochs = static_cast<int>(epochs_.size() - first_epoch);
  out.masked_fraction = reading.pixels_total > 0
                            ? 1.0 - static_cast<double>(reading.pixels_unmasked) / reading.pixels_total
                            : NAN;
  if (out.n_epochs == 0) {
    out.flags |= kFlagNoUsableEpoch;
    if (out.flags & kFlagPsfCutoutDropped) {
      out.flags |= kFlagPsfFailure;
      out.fit.status = FitStatus::kPsfFailure;
    }
    return false;
  }
  if (reading.pixels_unmasked < reading.pixels_total) out.flags |= kFlagMaskedPixels;
  out.psf_e1 = psf_e1 / out.n_epochs, out.psf_e2 = psf_e2 / out.n_epochs, out.psf_size = psf_size / out.n_epochs;
  out.pixels_total = reading.pixels_total, out.pixels_unmasked = reading.pixels_unmasked;
  if (1.0 - out.masked_fraction < options_.min_unmasked_fraction) {
    out.flags |= kFlagTooMasked;
    return false;
  }
  return true;
}

MedsObjectResult SurveyObjectFitter::fit(const ObservationArena& arena, int object, long long row,
                                         const ObjectRecord& identity) {
  epochs_.clear();
  MedsObjectResult out;
  out.id = identity.id, out.number = identity.survey.number, out.ra = identity.survey.ra, out.dec = identity.survey.dec;
  out.bulge_or_disc = options_.model == MedsModel::kBulgeOrDisc;
  if (tiles_.size() == 1)
    fit_one_band(arena, object, row, &out);
  else
    fit_bands(arena, object, row, &out);
  if (!bands_.empty() && tiles_.size() == 1) {
    BandFit& b = out.bands.emplace_back();
    b.n_epochs = out.n_epochs;
    b.bulge_a = out.fit.params[index(Param::kBulgeA)], b.disc_a = out.fit.params[index(Param::kDiscA)];
    b.bulge_flux = out.fit.bulge_flux, b.disc_flux = out.fit.disc_flux, b.flux = out.fit.flux, b.snr = out.fit.snr;
  }
  return out;
}

void SurveyObjectFitter::fit_one_band(const ObservationArena& arena, int object, long long row, MedsObjectResult* result) {
  MedsObjectResult& out = *result;
  if (!collect(arena, object, 0, row, &out)) return;
  if (metacal_) {
    metacal_->fit(epochs_, out.id, kFlagMetacalFailure, &out.fit, &out.metacal, &out.flags,
                  &out.problem);
    out.gamma_fwhm = metacal_->gamma_fwhm();
    if (metacal_->epochs_used() > 0) out.n_epochs = metacal_->epochs_used();
    out.flags |= out.fit.flags;
    return;
  }
  out.fit = fitter_.fit(epochs_);
  if (bulge_fitter_) {
    // The PSFs were prepared by fitter_'s renderers: the same kind, options and box size.
    FitResult bulge = bulge_fitter_->fit(epochs_);
    const bool disc_ok = IsUsable(out.fit.status), bulge_ok = IsUsable(bulge.status);
    const bool take_bulge = bulge_ok && (!disc_ok || bulge.likelihood > out.fit.likelihood);
    if (take_bulge) std::swap(out.fit, bulge);
    out.is_bulge = take_bulge;
    out.other_likelihood = bulge.likelihood;  // the loser's, after the swap
  }
  out.flags |= out.fit.flags;
}

void SurveyObjectFitter::fit_bands(const ObservationArena& arena, int object, long long row, MedsObjectResult* result) {
  MedsObjectResult& out = *result;
  const int n = static_cast<int>(tiles_.size());
  out.bands.resize(static_cast<std::size_t>(n));
  std::uint32_t unusable = 0;  // why bands were left out
  long long pixels_total = 0, pixels_unmasked = 0;
  double psf_e1 = 0, psf_e2 = 0, psf_size = 0;
  for (int b = 0; b < n; ++b) {
    MedsObjectResult band;
    const std::size_t first = epochs_.size();
    const bool usable = collect(arena, object, b, row, &band);
    if (!band.problem.empty() && out.problem.empty()) out.problem = "band " + bands_[static_cast<std::size_t>(b)] + ": " + band.problem;
    if (!usable) {
      epochs_.resize(first);  // a band left out contributes no cutout
      // Why the band was left out excludes the row only when no band is left (below); a band
      // without PSFs keeps kFlagPsfCutoutDropped, which the shear estimates do not cut on.
      constexpr std::uint32_t kWhyLeftOut = kFlagNoUsableEpoch | kFlagTooMasked | kFlagPsfFailure;
      unusable |= band.flags & kWhyLeftOut;
      // Said in the row: a band masked in every cutout otherwise left it reading ok, its flux NaN.
      out.flags |= (band.flags & ~kWhyLeftOut) | kFlagBandLeftOut;
      continue;
    }
    out.flags |= band.flags;
    pixels_total += band.pixels_total, pixels_unmasked += band.pixels_unmasked;
    psf_e1 += band.psf_e1 * band.n_epochs, psf_e2 += band.psf_e2 * band.n_epochs, psf_size += band.psf_size * band.n_epochs;
  }
  out.n_epochs = static_cast<int>(epochs_.size());
  out.pixels_total = pixels_total, out.pixels_unmasked = pixels_unmasked;
  if (epochs_.empty()) {
    out.flags |= unusable ? unusable : kFlagNoUsableEpoch;
    if (out.flags & kFlagPsfFailure) out.fit.status = FitStatus::kPsfFailure;
    return;
  }
  out.masked_fraction = 1.0 - static_cast<double>(pixels_unmasked) / static_cast<double>(pixels_total);
  out.psf_e1 = psf_e1 / out.n_epochs, out.psf_e2 = psf_e2 / out.n_epochs, out.psf_size = psf_size / out.n_epochs;
  if (metacal_) {
    metacal_->fit(epochs_, out.id, kFlagMetacalFailure, &out.fit, &out.metacal, &out.flags, &out.problem, n,
                  &out.bands);
    out.gamma_fwhm = metacal_->gamma_fwhm();
    if (metacal_->epochs_used() > 0) out.n_epochs = metacal_->epochs_used();
    out.flags |= out.fit.flags;
    return;
  }
  out.fit = fitter_.fit(epochs_, n, out.bands);
  if (bulge_fitter_) {
    // The PSFs were prepared by fitter_'s renderers: the same kind, options and box sizes.
    bulge_bands_.resize(static_cast<std::size_t>(n));
    FitResult bulge = bulge_fitter_->fit(epochs_, n, bulge_bands_);
    const bool disc_ok = IsUsable(out.fit.status), bulge_ok = IsUsable(bulge.status);
    const bool take_bulge = bulge_ok && (!disc_ok || bulge.likelihood > out.fit.likelihood);
    if (take_bulge) std::swap(out.fit, bulge), std::swap(out.bands, bulge_bands_);
    out.is_bulge = take_bulge;
    out.other_likelihood = bulge.likelihood;  // the loser's, after the swap
  }
  out.flags |= out.fit.flags;
}

SurveyBatchFitter::SurveyBatchFitter(const MedsFitOptions& options, std::vector<std::string> tiles,
                                     std::vector<std::string> bands)
    : fitter_(options, std::move(tiles), std::move(bands)) {}

void SurveyBatchFitter::fit(StampBatch& batch) {
  using Clock = std::chrono::steady_clock;
  for (int k = 0; k < batch.count; ++k) {
    ObjectRecord& record = batch.records[static_cast<std::size_t>(k)];
    const long long row = batch.first_object + k;
    const Clock::time_point start = Clock::now();
    const MedsObjectResult result = fitter_.fit(batch.observations, k, row, record);
    fill_survey_record(result, &record);
    record.time_us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    batch.problems[static_cast<std::size_t>(k)] = result.problem;
  }
}

void fill_survey_record(const MedsObjectResult& r, ObjectRecord* out) {
  out->id = r.id;
  out->fit = r.fit;
  out->flags = r.flags;  // the fit's own flags included
  out->psf_e1 = r.psf_e1;
  out->psf_e2 = r.psf_e2;
  out->survey.number = r.number;
  out->survey.ra = r.ra;
  out->survey.dec = r.dec;
  out->survey.n_epochs = r.n_epochs;
  out->survey.masked_fraction = r.masked_fraction;
  out->survey.psf_size = r.psf_size;
  out->survey.is_bulge = r.bulge_or_disc ? (r.is_bulge ? 1 : 0) : -1;
  out->survey.other_likelihood = r.bulge_or_disc ? r.other_likelihood : NAN;
  out->metacal = r.metacal;
  out->survey.gamma_fwhm = r.gamma_fwhm;
  for (std::size_t b = 0; b < r.bands.size() && b < out->survey.bands.size(); ++b) out->survey.bands[b] = r.bands[b];
}

}  // namespace stampede::app
