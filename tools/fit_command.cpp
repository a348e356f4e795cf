// `stampede fit`; see fit_command.hpp.
#include "tools/arguments.hpp"
#include "tools/fit_command.hpp"
#include "tools/psf_setup.hpp"
#include "tools/run_fingerprint.hpp"

#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "engine/pipeline/pipeline.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "engine/render/psf_cache.hpp"
#include "engine/render/renderer_factory.hpp"
#include "io/catalog_writer.hpp"
#include "io/catalogue_source.hpp"
#include "io/fits_error.hpp"
#include "io/grid_source.hpp"
#include "io/psf_keys.hpp"
#include "io/run_config.hpp"

namespace {

using namespace stampede;

constexpr const char* kUsage =
    "usage: stampede fit INPUT.fits -o OUT.fits [--config run.ini] [--set key=value ...]\n"
    "                    [--threads N] [--catalog CAT] [--weight W.fits] [--text OUT.txt]\n"
    "                    [--resume] [--quiet]\n";

void print_help() {
  std::printf(
      "%s\n"
      "Fits the im3shape bulge + disc model to every object and writes one row per object, in input\n"
      "order, to the FITS table OUT.fits (written as OUT.fits.partial and renamed when complete).\n"
      "\n"
      "INPUT.fits      a grid of square stamps (GREAT08 layout; stamp size from stamp_size or the\n"
      "                header key STAMPSZ; object id = iy * nx + ix), or with --catalog a large image\n"
      "  -o OUT.fits   output table (required)\n"
      "  --config F    im3shape-style ini file (key = value, # comments); see --help-config\n"
      "  --set K=V     override one option (repeatable); applied after --config\n"
      "  --threads N   worker threads (default: all cores); results are identical for any N\n"
      "  --catalog C   catalogue (FITS table or text 'id x y', FITS 1-based pixels) of objects to cut\n"
      "                from INPUT; stamps reaching past the image edge are fitted with the outside\n"
      "                masked and flagged (flag bit 65536)\n"
      "  --weight W    inverse-variance image of INPUT's shape (0 masks a pixel); else noise_sigma\n"
      "  --text T      also write the table as whitespace text\n"
      "  --resume      continue an interrupted run (same input and options) from its last batch\n"
      "  --quiet       no progress or summary on stderr\n"
      "  --help-config print every option with its default as an ini file\n",
      kUsage);
}

struct Args {
  std::string input, output, config, catalog, weight, text;
  std::vector<std::string> sets;
  int threads = 0;
  bool resume = false, quiet = false;
};


// The output sink: appends each batch to the catalogue writer, counts statuses, and saves the
// data, best-fit model and residual of the objects named by save_images (re-rendered here from the
// row's parameters, on the writer thread, with its own plans).
class WriterSink final : public BatchSink {
 public:
  WriterSink(io::CatalogWriter& writer, const io::RunConfig& cfg, std::shared_ptr<const PreparedPsf> shared_psf,
             PsfCache* psf_cache, const std::string& images_path)
      : writer_(writer), cfg_(cfg), shared_psf_(std::move(shared_psf)), psf_cache_(psf_cache) {
    for (std::int64_t id : io::save_image_ids(cfg)) wanted_.insert(id);
    if (!wanted_.empty()) images_ = std::make_unique<io::FitsFile>(io::FitsFile::create(images_path, true));
  }
  void write(const StampBatch& batch) override {
    writer_.append(std::span<const ObjectRecord>(batch.records.data(), batch.count));
    for (int k = 0; k < batch.count; ++k) {
      const ObjectRecord& r = batch.records[k];
      ++by_status[static_cast<int>(r.fit.status)];
      if (wanted_.count(r.id) && IsUsable(r.fit.status)) save(batch, k);
    }
  }
  std::array<long long, 7> by_status{};

 private:
  void save(const StampBatch& batch, int k) {
    const ObjectRecord& r = batch.records[k];
    if (!renderer_) renderer_ = make_renderer(cfg_.fitter.renderer, cfg_.fitter.render, cfg_.fitter.model, plans_);
    std::shared_ptr<const PreparedPsf> psf = shared_psf_;
    std::string error;
    if (psf_cache_) psf = psf_cache_->get(batch.psf[k], *renderer_, &error);
    if (!psf) return;
    renderer_->set_psf(psf);
    const std::size_t npix = batch.npix();
    std::vector<double> data(batch.stamp(k), batch.stamp(k) + npix), model(npix), resid(npix);
    if (renderer_->render(r.fit.params, model) != RenderStatus::kOk) return;
    for (std::size_t i = 0; i < npix; ++i) resid[i] = data[i] - model[i];
    const std::string id = std::to_string(r.id);
    images_->write_image(batch.stamp_size, batch.stamp_size, data, "DATA_" + id);
    images_->write_image(batch.stamp_size, batch.stamp_size, model, "MODEL_" + id);
    images_->write_image(batch.stamp_size, batch.stamp_size, resid, "RESID_" + id);
  }

  io::CatalogWriter& writer_;
  const io::RunConfig& cfg_;
  std::shared_ptr<const PreparedPsf> shared_psf_;
  PsfCache* psf_cache_;
  std::set<std::int64_t> wanted_;
  std::unique_ptr<io::FitsFile> images_;
  FftPlanCache plans_{FftPlanning::kEstimate};
  std::unique_ptr<Renderer> renderer_;
};

}  // namespace

int run_fit_command(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    if (s == "--help" || s == "-h") {
      print_help();
      return 0;
    } else if (s == "--help-config") {
      std::fputs(io::ini_template().c_str(), stdout);
      return 0;
    } else if (s == "-o" || s == "--output") {
      a.output = value();
    } else if (s == "--config") {
      a.config = value();
    } else if (s == "--set") {
      a.sets.push_back(value());
    } else if (s == "--threads") {
      a.threads = static_cast<int>(tools::integer_in(argc, argv, &i, 1, 4096));
    } else if (s == "--catalog") {
      a.catalog = value();
    } else if (s == "--weight") {
      a.weight = value();
    } else if (s == "--text") {
      a.text = value();
    } else if (s == "--resume") {
      a.resume = true;
    } else if (s == "--quiet") {
      a.quiet = true;
    } else if (!s.empty() && s[0] == '-') {
      throw std::invalid_argument("unknown option '" + s + "' (see stampede fit --help)");
    } else if (a.input.empty()) {
      a.input = s;
    } else {
      throw std::invalid_argument("unexpected argument '" + s + "' (one INPUT only)");
    }
  }
  if (a.input.empty() || a.output.empty()) {
    std::fputs(kUsage, stderr);
    return 2;
  }

  io::RunConfig cfg;
  if (!a.config.empty()) io::load_ini(cfg, a.config);
  for (const auto& s : a.sets) io::apply_set(cfg, s);

  // Input first: its header may fix the stamp size, and a bad file should fail before anything.
  std::unique_ptr<StampSource> source;
  std::optional<PsfModel> recorded_psf;  // the PSF the input's header records, if any
  std::string recorded_where;              // its file and HDU
  if (a.catalog.empty()) {
    auto grid = std::make_unique<io::GridStampSource>(a.input, a.weight,
                                                      cfg.explicitly_set.count("stamp_size") ? cfg.fitter.render.stamp_size : 0);
    cfg.fitter.render.stamp_size = grid->stamp_size();
    recorded_where = grid->header().describe();
    try {
      recorded_psf = io::read_psf_keys_if_present(grid->header());
    } catch (const io::FitsError& e) {  // the record only feeds a check: the fit does not need it
      std::fprintf(stderr, "stampede fit: warning: the PSF record is unreadable, not checked: %s\n", e.what());
    }
    source = std::move(grid);
  } else {
    io::CatalogueColumns cols;
    cols.id = cfg.catalog_id_column;
    cols.x = cfg.catalog_x_column;
    cols.y = cfg.catalog_y_column;
    cols.with_psf = cfg.psf_from_catalogue;
    cols.psf_beta = cfg.catalog_psf_beta_column;
    cols.psf_fwhm = cfg.catalog_psf_fwhm_column;
    cols.psf_e1 = cfg.catalog_psf_e1_column;
    cols.psf_e2 = cfg.catalog_psf_e2_column;
    source = std::make_unique<io::CatalogueStampSource>(a.input, a.weight, a.catalog, cfg.fitter.render.stamp_size, cols);
  }
  io::validate(cfg);
  if (cfg.psf_from_catalogue && a.catalog.empty())
    throw io::ConfigError("option 'psf_input' = 'moffat_catalog' needs --catalog");

  const FftPlanning planning = cfg.fft_wisdom.empty() ? FftPlanning::kEstimate : FftPlanning::kMeasure;
  if (!cfg.fft_wisdom.empty()) load_fftw_wisdom(cfg.fft_wisdom);  // a missing file is fine: it is made at the end
  FftPlanCache setup_plans(planning);
  std::shared_ptr<const PreparedPsf> shared_psf;
  std::unique_ptr<PsfCache> psf_cache;
  double psf_e1 = NAN, psf_e2 = NAN, psf_fwhm = NAN;
  if (cfg.psf_from_catalogue) {
    psf_cache = std::make_unique<PsfCache>(1024);
  } else {
    const tools::SharedPsf psf = tools::build_shared_psf(cfg, setup_plans);
    shared_psf = psf.prepared;
    psf_e1 = psf.e1, psf_e2 = psf.e2, psf_fwhm = psf.fwhm;
    // A set written by `stampede sim` or GalSim records its PSF; fitting it with another (e.g. the
    // default round Moffat) is almost always a forgotten option, and biases c by the difference.
    if (recorded_psf) {
      const std::vector<std::string> diff = tools::psf_differences(*recorded_psf, psf.model);
      if (!diff.empty()) {
        std::string list;
        for (const auto& d : diff) list += (list.empty() ? "" : ", ") + d;
        std::fprintf(stderr,
                     "stampede fit: warning: %s records a PSF other than the run's: %s. The fit uses the run's "
                     "PSF; set those options to fit with the recorded one.\n",
                     recorded_where.c_str(), list.c_str());
      }
    }
  }

  io::CatalogWriterOptions wo;
  wo.path = a.output;
  wo.text_path = a.text;
  wo.positions = a.catalog.empty() ? io::PositionColumns::kGrid : io::PositionColumns::kCatalogue;
  wo.header = io::effective_options(cfg);
  wo.header.emplace_back("INPUT", a.input);
  if (!a.catalog.empty()) wo.header.emplace_back("CATALOG", a.catalog);
  if (!a.weight.empty()) wo.header.emplace_back("WEIGHTS", a.weight);
  std::string identity = a.input + "\n" + a.catalog + "\n" + a.weight + "\n";
  for (const auto& [k, v] : wo.header) identity += k + "=" + v + "\n";
  wo.fingerprint = tools::run_fingerprint(identity);
  std::unique_ptr<io::CatalogWriter> writer;
  long long done_before = 0;
  if (a.resume) {
    writer = io::CatalogWriter::resume(wo, &done_before);
    source->skip_to(done_before);
  } else {
    writer = io::CatalogWriter::create(wo);
  }

  std::string images_path = a.output;
  if (images_path.size() > 5 && images_path.compare(images_path.size() - 5, 5, ".fits") == 0) images_path.resize(images_path.size() - 5);
  images_path += ".images.fits";
  WriterSink sink(*writer, cfg, shared_psf, psf_cache.get(), images_path);
  PipelineOptions po;
  po.threads = a.threads;
  po.batch_size = cfg.batch_size;
  po.per_object_psf = static_cast<bool>(psf_cache);
  po.stamp_size = cfg.fitter.render.stamp_size;
  const FitterOptions fitter_options = cfg.fitter;
  PsfCache* cache = psf_cache.get();
  auto make_fitter = [&]() -> std::unique_ptr<BatchFitter> {
    return std::make_unique<StampFitter>(fitter_options, shared_psf, cache, planning, psf_e1, psf_e2, psf_fwhm);
  };
  const bool show_progress = !a.quiet && isatty(fileno(stderr));
  double last_print = -1;
  const long long total = source->total_objects();
  auto progress = [&](const PipelineProgress& p) {
    if (!show_progress || p.seconds - last_print < 0.5) return;
    last_print = p.seconds;
    const double rate = p.objects_done / std::max(p.seconds, 1e-9);
    const long long left = total - done_before - p.objects_done;
    std::fprintf(stderr, "\r%lld/%lld objects (%.1f%%), %.1f objects/s, ETA %.0f s   ", done_before + p.objects_done,
                 total, 100.0 * (done_before + p.objects_done) / std::max(total, 1LL), rate, left / std::max(rate, 1e-9));
  };
  const PipelineSummary summary = run_pipeline(*source, sink, make_fitter, po, progress);
  writer->finish();
  if (!cfg.fft_wisdom.empty() && !save_fftw_wisdom(cfg.fft_wisdom) && !a.quiet)
    std::fprintf(stderr, "stampede fit: warning: could not write FFTW wisdom to '%s'\n", cfg.fft_wisdom.c_str());
  if (!a.quiet) {
    if (show_progress) std::fputc('\n', stderr);
    std::fprintf(stderr, "stampede fit: %lld objects (%lld resumed) in %.1f s, %.1f objects/s; status:", summary.objects + done_before,
                 done_before, summary.seconds, summary.objects / std::max(summary.seconds, 1e-9));
    for (int s = 0; s < 7; ++s)
      if (sink.by_status[s]) std::fprintf(stderr, " %s=%lld", ToString(static_cast<FitStatus>(s)), sink.by_status[s]);
    std::fprintf(stderr, "; wrote %s\n", a.output.c_str());
  }
  return 0;
}
