// Fitting stamps held in memory; see array_fit.hpp.
#include "app/array_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "app/fit_run.hpp"
#include "app/psf_setup.hpp"
#include "app/stamp_fitter_recipe.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "engine/render/psf_cache.hpp"

namespace stampede::app {

namespace {

// Copies the caller's stamps into the pipeline's batches, numbering them as a grid.
class ArraySource final : public StampSource {
 public:
  explicit ArraySource(const ArrayStamps& in) : in_(in), nx_(in.grid_nx > 0 ? in.grid_nx : std::max(in.count, 1)) {}
  long long total_objects() const override { return in_.count; }
  void skip_to(long long index) override { next_ = index; }
  bool fill(StampBatch& batch) override {
    const std::size_t npix = static_cast<std::size_t>(in_.stamp_size) * in_.stamp_size;
    batch.begin(next_);
    while (batch.count < batch.capacity() && next_ < in_.count) {
      const int k = batch.count++;
      const std::size_t at = static_cast<std::size_t>(next_) * npix;
      std::span<double> pixels, weights;
      ArenaObservation& o = batch.observations.add_stamp(in_.stamp_size, &pixels, &weights);
      o.weighted = !in_.weights.empty();
      std::copy_n(in_.pixels.data() + at, npix, pixels.begin());
      if (o.weighted) std::copy_n(in_.weights.data() + at, npix, weights.begin());
      if (in_.psfs.size() > 1) o.psf = in_.psfs[static_cast<std::size_t>(next_)];
      ObjectRecord& r = batch.records[k];
      r = ObjectRecord{};
      r.id = in_.first_id + next_;
      r.ix = static_cast<std::int32_t>(next_ % nx_);
      r.iy = static_cast<std::int32_t>(next_ / nx_);
      r.stamp_x0 = static_cast<double>(r.ix) * in_.stamp_size;
      r.stamp_y0 = static_cast<double>(r.iy) * in_.stamp_size;
      ++next_;
    }
    return batch.count > 0;
  }

 private:
  const ArrayStamps& in_;
  long long nx_;
  long long next_ = 0;
};

// Receives batches in input order and keeps their rows.
class RowsSink final : public BatchSink {
 public:
  explicit RowsSink(std::vector<ObjectRecord>* rows) : rows_(rows) {}
  void write(const StampBatch& batch) override {
    std::copy_n(batch.records.begin(), batch.count, rows_->begin() + batch.first_object);
  }

 private:
  std::vector<ObjectRecord>* rows_;
};

void check_arrays(const ArrayStamps& in) {
  if (in.count < 0) throw std::invalid_argument("stamp count " + std::to_string(in.count) + " is negative");
  if (in.stamp_size < 1) throw std::invalid_argument("stamp size " + std::to_string(in.stamp_size) + " is not positive");
  const std::size_t n = static_cast<std::size_t>(in.count) * in.stamp_size * in.stamp_size;
  if (in.pixels.size() != n)
    throw std::invalid_argument("stamps hold " + std::to_string(in.pixels.size()) + " values, not " +
                                std::to_string(in.count) + " x " + std::to_string(in.stamp_size) + "^2");
  if (!in.weights.empty() && in.weights.size() != n)
    throw std::invalid_argument("weights hold " + std::to_string(in.weights.size()) + " values, the stamps " +
                                std::to_string(n));
  // ids first_id .. first_id + count - 1 must all be int64: never wrapped to negative.
  if (in.count > 0 && in.first_id > std::numeric_limits<std::int64_t>::max() - (in.count - 1))
    throw std::invalid_argument("first_id = " + std::to_string(in.first_id) + ": the ids of " + std::to_string(in.count) +
                                " stamps would pass 2^63 - 1");
  if (in.psfs.size() > 1 && in.psfs.size() != static_cast<std::size_t>(in.count))
    throw std::invalid_argument(std::to_string(in.psfs.size()) + " PSFs for " + std::to_string(in.count) +
                                " stamps (give one, or one per stamp)");
  if (in.grid_nx < 0) throw std::invalid_argument("grid_nx " + std::to_string(in.grid_nx) + " is negative");
  for (std::size_t i = 0; i < in.psfs.size(); ++i) {
    std::string why;
    if (!in.psfs[i].IsValid(&why))
      throw std::invalid_argument((in.psfs.size() > 1 ? "PSF " + std::to_string(i) + ": " : "PSF: ") + why);
  }
}

// cfg with the arrays' stamp size (refused when stamp_size was set to another), validated.
app::RunConfig config_for(const app::RunConfig& config, int stamp_size, bool per_stamp_psf) {
  app::RunConfig cfg = config;
  if (cfg.explicitly_set.contains("stamp_size") && cfg.fitter.render.stamp_size != stamp_size)
    throw io::ConfigError("option 'stamp_size' = " + std::to_string(cfg.fitter.render.stamp_size) +
                          " but the stamps are " + std::to_string(stamp_size) + " pixels square");
  cfg.fitter.render.stamp_size = stamp_size;
  if (per_stamp_psf) {
    cfg.psf_from_catalogue = true;  // the pipeline's per-object path
  } else if (cfg.psf_from_catalogue) {
    throw io::ConfigError("option 'psf_input' = 'moffat_catalog' needs a PSF per stamp");
  }
  app::validate(cfg);
  return cfg;
}

// metacal deconvolves a PSF and widens it: the Airy disc (its transform vanishes beyond its
// cut-off) cannot be used.
void check_metacal_psfs(const app::RunConfig& cfg, const std::vector<PsfModel>& psfs) {
  if (!cfg.metacal.enabled) return;
  for (const PsfModel& p : psfs)
    if (p.kind == PsfKind::kAiry)
      throw io::ConfigError("metacal = true cannot use an Airy PSF (its transform vanishes beyond its cut-off)");
}

}  // namespace

SingleStampFitter::SingleStampFitter(const app::RunConfig& config, int stamp_size, std::optional<PsfModel> psf)
    : stamp_size_(stamp_size), batch_(1) {
  // The options first: a stamp size out of their range is their error, before the arrays' checks.
  config_for(config, std::max(stamp_size, 1), false);
  ArrayStamps shape;
  shape.stamp_size = stamp_size;
  if (psf) shape.psfs.push_back(*psf);
  check_arrays(shape);
  const app::RunConfig cfg = config_for(config, stamp_size, false);
  check_metacal_psfs(cfg, shape.psfs);
  FftPlanCache setup_plans(FftPlanning::kEstimate);
  fitter_ = stamp_fitter_recipe(cfg, setup_plans, false, psf, "the stamps' PSF").make(FftPlanning::kEstimate);
}

SingleStampFitter::~SingleStampFitter() = default;

ObjectRecord SingleStampFitter::fit(std::span<const double> pixels, std::span<const double> weights, std::int64_t id) {
  const std::size_t npix = static_cast<std::size_t>(stamp_size_) * stamp_size_;
  if (pixels.size() != npix || (!weights.empty() && weights.size() != npix))
    throw std::invalid_argument("a stamp of " + std::to_string(stamp_size_) + " x " + std::to_string(stamp_size_) +
                                " pixels was expected, not " +
                                std::to_string(weights.empty() || pixels.size() != npix ? pixels.size() : weights.size()) +
                                " values");
  batch_.begin(0);
  batch_.count = 1;
  std::span<double> into_pixels, into_weights;
  batch_.observations.add_stamp(stamp_size_, &into_pixels, &into_weights).weighted = !weights.empty();
  std::copy(pixels.begin(), pixels.end(), into_pixels.begin());
  std::copy(weights.begin(), weights.end(), into_weights.begin());
  ObjectRecord& r = batch_.records[0];
  r = ObjectRecord{};
  r.id = id;
  r.ix = 0;
  r.iy = 0;
  fitter_->fit(batch_);
  return r;
}

std::vector<ObjectRecord> fit_array_stamps(const app::RunConfig& config, const ArrayStamps& in, int threads) {
  check_threads(threads, "threads");
  check_arrays(in);
  const app::RunConfig cfg = config_for(config, in.stamp_size, in.psfs.size() > 1);
  check_metacal_psfs(cfg, in.psfs);

  std::vector<ObjectRecord> rows(static_cast<std::size_t>(in.count));
  if (in.count == 0) return rows;
  FftPlanCache setup_plans(FftPlanning::kEstimate);
  const std::optional<PsfModel> one_psf =
      in.psfs.size() == 1 ? std::optional<PsfModel>(in.psfs.front()) : std::nullopt;
  const StampFitterRecipe recipe = stamp_fitter_recipe(cfg, setup_plans, in.psfs.size() > 1, one_psf, "the stamps' PSF");

  ArraySource source(in);
  RowsSink sink(&rows);
  PipelineOptions pipeline_options;
  pipeline_options.threads = threads;
  pipeline_options.batch_size = cfg.batch_size;
  auto make_fitter = [&]() -> std::unique_ptr<BatchFitter> { return recipe.make(FftPlanning::kEstimate); };
  run_pipeline(source, sink, make_fitter, pipeline_options);
  return rows;
}

}  // namespace stampede::app
