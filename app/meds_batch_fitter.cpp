// A MEDS tile's batches; see meds_batch_fitter.hpp.
#include "app/meds_batch_fitter.hpp"

#include <chrono>

namespace stampede::app {

MedsBatchFitter::MedsBatchFitter(const std::string& path, const MedsFitOptions& options,
                                 std::function<void(long long, const std::string&)> on_problem)
    : on_problem_(std::move(on_problem)) {
  tiles_.push_back(io::MedsFile::open(path));
  fitter_ = std::make_unique<MedsObjectFitter>(tiles_.front(), options);
}

MedsBatchFitter::MedsBatchFitter(const std::vector<std::string>& paths, const std::vector<std::string>& bands,
                                 const MedsFitOptions& options,
                                 std::function<void(long long, const std::string&)> on_problem)
    : on_problem_(std::move(on_problem)) {
  std::vector<io::MedsFile*> tiles;
  for (const std::string& p : paths) tiles.push_back(&tiles_.emplace_back(io::MedsFile::open(p)));
  band_fitter_ = std::make_unique<MultiBandObjectFitter>(tiles, bands, options);
}

MedsBatchFitter::~MedsBatchFitter() = default;

void MedsBatchFitter::fit(StampBatch& batch) {
  using Clock = std::chrono::steady_clock;
  for (int k = 0; k < batch.count; ++k) {
    ObjectRecord& record = batch.records[static_cast<std::size_t>(k)];
    const long long row = record.id;
    const Clock::time_point start = Clock::now();
    const MedsObjectResult result = fitter_ ? fitter_->fit(row) : band_fitter_->fit(row);
    fill_survey_record(result, &record);
    record.time_us = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    if (on_problem_ && !result.problem.empty()) on_problem_(row, result.problem);
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
