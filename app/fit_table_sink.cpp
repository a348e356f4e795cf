// The fit run's sink; see fit_table_sink.hpp.
#include "app/fit_table_sink.hpp"

#include <vector>

#include "engine/render/renderer_factory.hpp"

namespace stampede::app {

FitTableSink::FitTableSink(io::CatalogWriter* writer, const FitRunOptions& run, const RunConfig& config,
                           std::shared_ptr<const PreparedPsf> shared_psf, PsfCache* psf_cache,
                           const std::string& images_path)
    : writer_(writer), run_(run), config_(config), shared_psf_(std::move(shared_psf)), psf_cache_(psf_cache) {
  for (std::int64_t id : save_image_ids(config)) wanted_.insert(id);
  if (!wanted_.empty()) images_ = std::make_unique<io::FitsFile>(io::FitsFile::create(images_path, true));
}

void FitTableSink::write(const StampBatch& batch) {
  const std::span<const ObjectRecord> rows(batch.records.data(), batch.count);
  if (writer_) writer_->append(rows);
  if (run_.on_rows) run_.on_rows(rows);
  for (int k = 0; k < batch.count; ++k) {
    const ObjectRecord& r = batch.records[k];
    ++by_status[static_cast<int>(r.fit.status)];
    if (wanted_.count(r.id) && IsUsable(r.fit.status)) save(batch, k);
    const std::string& problem = batch.problems[static_cast<std::size_t>(k)];
    if (!problem.empty() && ++problems_ <= kProblemsShown && run_.on_warning)
      run_.on_warning("object_data row " + std::to_string(batch.first_object + k) + ": " + problem);
  }
}

void FitTableSink::report_remaining_problems() const {
  if (problems_ > kProblemsShown && run_.on_warning)
    run_.on_warning(std::to_string(problems_ - kProblemsShown) + " more objects had problems (their rows' flags say which)");
}

void FitTableSink::save(const StampBatch& batch, int k) {
  const ObjectRecord& r = batch.records[k];
  if (!renderer_) renderer_ = make_renderer(config_.fitter.renderer, config_.fitter.render, config_.fitter.model, plans_);
  const ArenaObservation& stamp = batch.observations.first_of(k);
  std::shared_ptr<const PreparedPsf> psf = shared_psf_;
  std::string error;
  if (psf_cache_) psf = psf_cache_->get(stamp.psf, *renderer_, &error);
  if (!psf) return;
  renderer_->set_psf(psf);
  const std::span<const double> pixels = batch.observations.pixels(stamp);
  const std::size_t npix = pixels.size();
  std::vector<double> data(pixels.begin(), pixels.end()), model(npix), resid(npix);
  if (renderer_->render(r.fit.params, model) != RenderStatus::kOk) return;
  for (std::size_t i = 0; i < npix; ++i) resid[i] = data[i] - model[i];
  const std::string id = std::to_string(r.id);
  const int s = stamp.box_size;
  images_->write_image(s, s, data, "DATA_" + id);
  images_->write_image(s, s, model, "MODEL_" + id);
  images_->write_image(s, s, resid, "RESID_" + id);
}

}  // namespace stampede::app
