// The calibration build; see calibration_build.hpp.
#include "app/calibration_build.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "app/run_fingerprint.hpp"
#include "engine/model/parameters.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "io/calibration_table.hpp"
#include "io/durable_file.hpp"
#include "io/output_check.hpp"

namespace stampede::app {

// The build's progress file: a header line naming the run, then one line per completed point.
// Appended and fsync'd point by point, so a build killed at any moment resumes after its last line.
class BuildCheckpoint {
 public:
  BuildCheckpoint(const std::string& path, const std::string& fingerprint, bool resume, int n_points)
      : path_(path), header_("# stampede calibrate build " + fingerprint) {
    if (resume) {
      std::ifstream in(path_);
      if (!in) throw std::runtime_error("--resume: no progress file '" + path_ + "' to resume from");
      std::string line;
      if (!std::getline(in, line) || line != header_)
        throw std::runtime_error("--resume: '" + path_ + "' belongs to a different build (options or configuration differ)");
      long long valid_bytes = static_cast<long long>(line.size()) + 1;
      while (std::getline(in, line)) {
        if (in.eof()) break;  // a last line without its newline was cut by the interruption
        std::istringstream ls(line);
        int point = -1;
        PointBias b;
        if (!(ls >> point >> b.bias[0] >> b.error[0] >> b.bias[1] >> b.error[1] >> b.pairs_used >> b.pairs_failed) ||
            point != static_cast<int>(done_.size()) || point >= n_points)
          throw std::runtime_error("--resume: '" + path_ + "' is damaged at grid point " + std::to_string(done_.size()));
        done_.push_back(b);
        valid_bytes += static_cast<long long>(line.size()) + 1;
      }
      file_ = io::DurableFile::open(path_, io::DurableFile::Mode::kReadWrite);
      file_.truncate(valid_bytes);
      file_.seek_to_end();
    } else {
      file_ = io::DurableFile::create(path_, "calibration progress file");
      io::sync_directory_of(path_);  // the new file's name must survive a crash too
      append(header_ + "\n");
    }
  }
  const std::vector<PointBias>& done() const { return done_; }
  void add(int point, const PointBias& b) {
    char line[256];
    std::snprintf(line, sizeof line, "%d %.17g %.17g %.17g %.17g %d %d\n", point, b.bias[0], b.error[0], b.bias[1],
                  b.error[1], b.pairs_used, b.pairs_failed);
    append(line);
    done_.push_back(b);
  }
  void remove() {
    file_.close();
    io::remove_if_present(path_);
  }

 private:
  // One record per fsync (io/durable_file.hpp's append-only log): a kill leaves whole records
  // and at most one cut line, which resume drops.
  void append(const std::string& text) {
    file_.write_all(text);
    file_.sync();
  }
  std::string path_, header_;
  io::DurableFile file_;
  std::vector<PointBias> done_;
};

namespace {

class AccumulatingSink final : public BatchSink {
 public:
  explicit AccumulatingSink(PointBiasAccumulator& acc) : acc_(acc) {}
  void write(const StampBatch& batch) override {
    acc_.add(std::span<const ObjectRecord>(batch.records.data(), static_cast<std::size_t>(batch.count)));
  }

 private:
  PointBiasAccumulator& acc_;
};

}  // namespace

std::string CalibrationBuildProgress::Line() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%lld/%lld fits (%.1f%%), point %lld/%d, %.1f fits/s, ETA %.0f s   ", fits_done,
                fits_total, 100.0 * fits_done / fits_total, point, points, fits_per_second, eta_seconds);
  return buf;
}

std::string CalibrationBuildSummary::BriefReport() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "stampede calibrate build: %lld fits in %.1f s, %.1f fits/s", fits, fit_seconds,
                fits / std::max(fit_seconds, 1e-9));
  return buf;
}

std::string CalibrationBuildSummary::FullReport() const {
  long long used = 0, failed = 0;
  double err = 0;
  for (const PointBias& b : table.biases) {
    used += b.pairs_used;
    failed += b.pairs_failed;
    if (std::isfinite(b.error[0])) err += b.error[0];
  }
  char buf[256];
  std::snprintf(buf, sizeof buf, "noise pairs used %lld, lost to a flagged fit %lld; mean error of a point's bias %.2e\n",
                used, failed, err / static_cast<double>(table.biases.size()));
  std::string out = buf;
  std::snprintf(buf, sizeof buf, "%8s %6s %11s %11s %11s %11s\n", "r_d", "F", "m(e=0) e1", "m(e=0) e2", "c1(e=0)",
                "c2(e=0)");
  out += buf;
  for (std::size_t k = 0; k + 3 < table.curves.size(); k += 4) {
    const BiasCurve* c = &table.curves[k];  // (e1, 0), (e1, 1), (e2, 0), (e2, 1)
    std::snprintf(buf, sizeof buf, "%8.3g %6.3g %+11.3e %+11.3e %+11.3e %+11.3e\n", c[0].radius, c[0].bulge_fraction,
                  c[0].coefficients[1], c[3].coefficients[1], 0.5 * (c[0].coefficients[0] + c[2].coefficients[0]),
                  0.5 * (c[1].coefficients[0] + c[3].coefficients[0]));
    out += buf;
  }
  return out + "wrote " + output + "\n";
}

CalibrationBuild::CalibrationBuild(CalibrationBuildOptions options) : options_(std::move(options)) {
  const app::RunConfig& config = options_.config;
  CalibrationGridOptions& g = options_.grid;
  const io::RunOutput output{"-o", options_.output,
                             {options_.output + ".partial", options_.output + ".tmp", io::OutputLock::path_for(options_.output)}};
  io::check_outputs(std::span(&output, 1), {}, options_.overwrite || options_.resume);
  lock_ = io::OutputLock::acquire(options_.output);
  app::validate(config);
  if (config.metacal.enabled)
    throw io::ConfigError("option 'metacal' = true: calibrate build simulates the plain fit's noise bias; a metacal run "
                          "measures its response from its own images and needs no calibration table");
  if (config.psf_from_catalogue || config.psf_kind == PsfKind::kImage)
    throw io::ConfigError("option 'psf_input' = '" + app::psf_input_value(config) +
                          "': calibrate build simulates analytic PSFs only (moffat or airy)");
  if (!(config.fitter.noise_sigma > 0))
    throw io::ConfigError("option 'noise_sigma' = 0: the calibration fits (and the science run's) must be weighted; "
                          "set noise_sigma > 0 (the data's noise)");
  g.noise_sigma = config.fitter.noise_sigma;
  g.stamp_size = config.fitter.render.stamp_size;
  g.bulge_radius_ratio = config.fitter.params.spec[index(Param::kRadiusRatio)].start;

  FftPlanCache setup_plans(FftPlanning::kEstimate);
  psf_ = app::build_shared_psf(config, setup_plans);
  g.psf = psf_.model;
  grid_ = std::make_unique<CalibrationGrid>(g);  // validates the grid options
  checkpoint_ = std::make_unique<BuildCheckpoint>(options_.output + ".partial",
                                                  calibration_build_fingerprint(g, app::effective_options(config)),
                                                  options_.resume, points());
}

CalibrationBuild::~CalibrationBuild() = default;

int CalibrationBuild::points() const { return static_cast<int>(grid_->points().size()); }

int CalibrationBuild::first_point() const { return static_cast<int>(checkpoint_->done().size()); }

std::string CalibrationBuild::PlanReport() const {
  const CalibrationGridOptions& g = options_.grid;
  const std::string resuming = first_point() ? ", resuming at point " + std::to_string(first_point()) : "";
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "stampede calibrate build: %d grid points (%zu radii x %zu bulge fractions x 2 axes x %d e) x %d noise "
                "pairs = %lld fits at S/N %g%s",
                points(), g.radii.size(), g.bulge_fractions.size(), g.e_steps, g.realisations, grid_->objects(), g.snr,
                resuming.c_str());
  return buf;
}

CalibrationBuildSummary CalibrationBuild::run(const std::function<void(const CalibrationBuildProgress&)>& progress) {
  const app::RunConfig& config = options_.config;
  const CalibrationGrid& grid = *grid_;
  const int n_points = points(), first = first_point();
  CalibrationBuildSummary summary;
  summary.output = options_.output;
  if (first < n_points) {
    PointBiasAccumulator acc(grid, [&](int point, const PointBias& b) { checkpoint_->add(point, b); });
    AccumulatingSink sink(acc);
    CalibrationSource source(grid);
    const long long total = grid.objects(), before = static_cast<long long>(first) * grid.objects_per_point();
    source.skip_to(before);
    PipelineOptions pipeline_options;
    pipeline_options.threads = options_.threads;
    pipeline_options.batch_size = config.batch_size;
    FitterOptions fitter_options = config.fitter;
    fitter_options.renderer = psf_.kind;
    const app::SharedPsf& psf = psf_;
    auto make_fitter = [&]() -> std::unique_ptr<BatchFitter> {
      return std::make_unique<StampFitter>(fitter_options, psf.prepared, nullptr, FftPlanning::kEstimate, psf.e1, psf.e2,
                                           psf.fwhm);
    };
    double last_report = -1;
    auto on_batch = [&](const PipelineProgress& p) {
      if (!progress || p.seconds - last_report < 0.5) return;
      last_report = p.seconds;
      CalibrationBuildProgress r;
      r.fits_done = before + p.objects_done;
      r.fits_total = total;
      r.point = r.fits_done / grid.objects_per_point();
      r.points = n_points;
      r.seconds = p.seconds;
      r.fits_per_second = p.objects_done / std::max(p.seconds, 1e-9);
      r.eta_seconds = (total - r.fits_done) / std::max(r.fits_per_second, 1e-9);
      progress(r);
    };
    const PipelineSummary fitted = run_pipeline(source, sink, make_fitter, pipeline_options, on_batch);
    summary.fitted = true;
    summary.fits = fitted.objects;
    summary.fit_seconds = fitted.seconds;
  }
  if (static_cast<int>(checkpoint_->done().size()) != n_points)
    throw std::runtime_error("calibrate build: only " + std::to_string(checkpoint_->done().size()) + " of " +
                             std::to_string(n_points) + " grid points were measured");
  CalibrationTable& table = summary.table;
  table.grid = options_.grid;
  table.points = grid.points();
  // The renderer as renderer = auto resolved for this PSF: apply compares it with the science
  // table's, which records its run's resolution alike.
  app::RunConfig recorded = config;
  recorded.fitter.renderer = psf_.kind;
  table.config = app::effective_options(recorded);
  table.biases = checkpoint_->done();
  table.curves = fit_bias_curves(table.grid, table.points, table.biases);
  const std::string tmp = options_.output + ".tmp";
  io::write_calibration_table(tmp, table, true);
  std::filesystem::rename(tmp, options_.output);
  checkpoint_->remove();
  return summary;
}

}  // namespace stampede::app
