// The fit run's sink, on the pipeline's serial output stage: appends each batch's rows to the
// catalogue (if any), hands them to the caller (FitRunOptions::on_rows), counts their statuses,
// reports survey objects' problems in input order (the first few in full, then a count: a tile
// with many masked objects must not flood the terminal), and saves the data, best-fit model and
// residual of the objects named by save_images (re-rendered from the row's parameters, with the
// sink's own FFT plans).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <set>
#include <string>

#include "app/fit_run.hpp"
#include "engine/render/fft_plans.hpp"
#include "engine/render/psf_cache.hpp"
#include "engine/render/renderer.hpp"
#include "io/catalog_writer.hpp"
#include "io/fits_file.hpp"

namespace stampede::app {

class FitTableSink final : public BatchSink {
 public:
  static constexpr int kProblemsShown = 10;
  // writer: null for a run without a table; shared_psf or psf_cache: the PSF of the saved images.
  FitTableSink(io::CatalogWriter* writer, const FitRunOptions& run, const RunConfig& config,
               std::shared_ptr<const PreparedPsf> shared_psf, PsfCache* psf_cache, const std::string& images_path);
  void write(const StampBatch& batch) override;
  // After the run: how many more objects had problems than were reported.
  void report_remaining_problems() const;
  std::array<long long, kFitStatusCount> by_status{};

 private:
  void save(const StampBatch& batch, int k);

  io::CatalogWriter* writer_;
  const FitRunOptions& run_;
  const RunConfig& config_;
  std::shared_ptr<const PreparedPsf> shared_psf_;
  PsfCache* psf_cache_;
  long long problems_ = 0;
  std::set<std::int64_t> wanted_;
  std::unique_ptr<io::FitsFile> images_;
  FftPlanCache plans_{FftPlanning::kEstimate};
  std::unique_ptr<Renderer> renderer_;
};

}  // namespace stampede::app
