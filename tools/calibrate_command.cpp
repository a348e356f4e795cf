// `stampede calibrate build | apply`; see calibrate_command.hpp.
#include "tools/calibrate_command.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/calibration/calibration_grid.hpp"
#include "engine/calibration/noise_bias.hpp"
#include "engine/model/parameters.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "engine/pipeline/stamp_fitter.hpp"
#include "io/calibration_table.hpp"
#include "io/fits_file.hpp"
#include "io/run_config.hpp"
#include "tools/arguments.hpp"
#include "tools/psf_setup.hpp"
#include "tools/run_fingerprint.hpp"

namespace {

using namespace stampede;

// ---- build ----------------------------------------------------------------------------------------

void print_build_help() {
  std::printf(
      "usage: stampede calibrate build -o CAL.fits [--config run.ini] [--set key=value ...] [options]\n"
      "\n"
      "Measures the noise bias of the fitter (im3shape section 5.3) on simulated bulge + disc\n"
      "galaxies: a grid of disc half-light radius r_d x bulge flux fraction F x true e along e1 and\n"
      "along e2, each drawn at the reference S/N with the run's PSF and fitted with the run's\n"
      "configuration under noise pairs (n, -n). At each grid point the mean of e_fit - e_true is\n"
      "measured; at each (r_d, F) a cubic in e_true is fitted per axis and component. Writes the\n"
      "points, the curves and the configuration to CAL.fits for `stampede calibrate apply`.\n"
      "\n"
      "The configuration (--config/--set, as `stampede fit`) must be the science run's: it sets the\n"
      "PSF (psf_input = moffat or airy), the stamp size, the fitter, and noise_sigma (> 0: the fits\n"
      "are weighted; fluxes follow from --snr).\n"
      "\n"
      "  -o CAL.fits              output (required); progress is kept in CAL.fits.partial\n"
      "  --snr X                  reference S/N = sqrt(sum I^2) / noise_sigma (20)\n"
      "  --radii A,B,..           disc half-light radii r_d, pixels (1,2.5,5: the paper's; radii\n"
      "                           spanning the population more finely calibrate better, see\n"
      "                           docs/calibration/README.md)\n"
      "  --bulge-fractions A,..   bulge flux fractions F (0,0.5,1)\n"
      "  --e-max E --e-steps N    e_true from -E to E in N steps, along e1 and e2 (0.8, 17)\n"
      "  --realisations N         noise pairs per grid point (16); the bias of a point is measured to\n"
      "                           ~0.045 / sqrt(N) in e at S/N 20 (mean error printed at the end)\n"
      "  --seed S                 noise seed (11)\n"
      "  --threads N              worker threads (default: all cores); results identical for any N\n"
      "  --resume                 continue an interrupted build from its last completed grid point\n"
      "  --overwrite              replace an existing CAL.fits\n"
      "  --quiet                  no progress or summary on stderr\n");
}

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
      fd_ = ::open(path_.c_str(), O_WRONLY);
      if (fd_ < 0 || ::ftruncate(fd_, valid_bytes) != 0 || ::lseek(fd_, 0, SEEK_END) < 0)
        throw std::runtime_error("cannot reopen '" + path_ + "' for writing");
    } else {
      fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd_ < 0) throw std::runtime_error("cannot create '" + path_ + "' (is the directory writable?)");
      append(header_ + "\n");
    }
  }
  ~BuildCheckpoint() {
    if (fd_ >= 0) ::close(fd_);
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
    ::close(fd_);
    fd_ = -1;
    std::remove(path_.c_str());
  }

 private:
  void append(const std::string& text) {
    if (::write(fd_, text.data(), text.size()) != static_cast<ssize_t>(text.size()) || ::fsync(fd_) != 0)
      throw std::runtime_error("cannot write '" + path_ + "'");
  }
  std::string path_, header_;
  int fd_ = -1;
  std::vector<PointBias> done_;
};

class AccumulatingSink final : public BatchSink {
 public:
  explicit AccumulatingSink(PointBiasAccumulator& acc) : acc_(acc) {}
  void write(const StampBatch& batch) override {
    acc_.add(std::span<const ObjectRecord>(batch.records.data(), static_cast<std::size_t>(batch.count)));
  }

 private:
  PointBiasAccumulator& acc_;
};

int run_build(int argc, char** argv) {
  CalibrationGridOptions g;
  std::string output, config;
  std::vector<std::string> sets;
  int threads = 0;
  bool resume = false, overwrite = false, quiet = false;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      print_build_help();
      return 0;
    } else if (a == "-o" || a == "--output") output = tools::option_value(argc, argv, &i);
    else if (a == "--config") config = tools::option_value(argc, argv, &i);
    else if (a == "--set") sets.push_back(tools::option_value(argc, argv, &i));
    else if (a == "--snr") g.snr = tools::number_value(argc, argv, &i);
    else if (a == "--radii") g.radii = tools::number_list(a, tools::option_value(argc, argv, &i));
    else if (a == "--bulge-fractions") g.bulge_fractions = tools::number_list(a, tools::option_value(argc, argv, &i));
    else if (a == "--e-max") g.e_max = tools::number_value(argc, argv, &i);
    else if (a == "--e-steps") g.e_steps = static_cast<int>(tools::integer_in(argc, argv, &i, 4, 201));
    else if (a == "--realisations") g.realisations = static_cast<int>(tools::integer_in(argc, argv, &i, 2, 1000000));
    else if (a == "--seed") g.seed = static_cast<std::uint64_t>(tools::integer_in(argc, argv, &i, 0, 1LL << 62));
    else if (a == "--threads") threads = static_cast<int>(tools::integer_in(argc, argv, &i, 1, 4096));
    else if (a == "--resume") resume = true;
    else if (a == "--overwrite") overwrite = true;
    else if (a == "--quiet") quiet = true;
    else throw std::invalid_argument("unknown option '" + a + "' (see stampede calibrate build --help)");
  }
  if (output.empty()) throw std::invalid_argument("-o CAL.fits is required (see stampede calibrate build --help)");
  if (!overwrite && !resume && std::filesystem::exists(output))
    throw std::invalid_argument("'" + output + "' exists (use --overwrite to replace it)");

  io::RunConfig cfg;
  if (!config.empty()) io::load_ini(cfg, config);
  for (const auto& s : sets) io::apply_set(cfg, s);
  io::validate(cfg);
  if (cfg.psf_from_catalogue || cfg.psf_kind == PsfKind::kImage)
    throw io::ConfigError("option 'psf_input' = '" + io::psf_input_value(cfg) +
                          "': calibrate build simulates analytic PSFs only (moffat or airy)");
  if (!(cfg.fitter.noise_sigma > 0))
    throw io::ConfigError("option 'noise_sigma' = 0: the calibration fits (and the science run's) must be weighted; "
                          "set noise_sigma > 0 (the data's noise)");
  g.noise_sigma = cfg.fitter.noise_sigma;
  g.stamp_size = cfg.fitter.render.stamp_size;
  g.bulge_radius_ratio = cfg.fitter.params.spec[index(Param::kRadiusRatio)].start;

  FftPlanCache setup_plans(FftPlanning::kEstimate);
  const tools::SharedPsf psf = tools::build_shared_psf(cfg, setup_plans);
  g.psf = psf.model;
  const CalibrationGrid grid(g);  // validates the grid options

  CalibrationTable table;
  table.grid = g;
  table.points = grid.points();
  table.config = io::effective_options(cfg);
  std::string identity;
  char buf[64];
  for (const auto* list : {&g.radii, &g.bulge_fractions})
    for (double v : *list) {
      std::snprintf(buf, sizeof buf, "%.17g,", v);
      identity += buf;
    }
  std::snprintf(buf, sizeof buf, "|%.17g|%.17g|%d|%d|%llu|", g.snr, g.e_max, g.e_steps, g.realisations,
                static_cast<unsigned long long>(g.seed));
  identity += buf;
  for (const auto& [k, v] : table.config) identity += k + "=" + v + "\n";

  const int n_points = static_cast<int>(grid.points().size());
  BuildCheckpoint checkpoint(output + ".partial", tools::run_fingerprint(identity), resume, n_points);
  const int first_point = static_cast<int>(checkpoint.done().size());
  const bool show_progress = !quiet && isatty(fileno(stderr));
  if (!quiet)
    std::fprintf(stderr,
                 "stampede calibrate build: %d grid points (%zu radii x %zu bulge fractions x 2 axes x %d e) x %d noise "
                 "pairs = %lld fits at S/N %g%s\n",
                 n_points, g.radii.size(), g.bulge_fractions.size(), g.e_steps, g.realisations, grid.objects(), g.snr,
                 first_point ? (", resuming at point " + std::to_string(first_point)).c_str() : "");

  if (first_point < n_points) {
    PointBiasAccumulator acc(grid, [&](int point, const PointBias& b) { checkpoint.add(point, b); });
    AccumulatingSink sink(acc);
    CalibrationSource source(grid);
    source.skip_to(static_cast<long long>(first_point) * grid.objects_per_point());
    PipelineOptions po;
    po.threads = threads;
    po.batch_size = cfg.batch_size;
    po.stamp_size = g.stamp_size;
    const FitterOptions fitter_options = cfg.fitter;
    std::shared_ptr<const PreparedPsf> kernel = psf.prepared;
    auto make_fitter = [&]() -> std::unique_ptr<BatchFitter> {
      return std::make_unique<StampFitter>(fitter_options, kernel, nullptr, FftPlanning::kEstimate, psf.e1, psf.e2,
                                           psf.fwhm);
    };
    const long long total = grid.objects(), before = static_cast<long long>(first_point) * grid.objects_per_point();
    double last_print = -1;
    auto progress = [&](const PipelineProgress& p) {
      if (!show_progress || p.seconds - last_print < 0.5) return;
      last_print = p.seconds;
      const double rate = p.objects_done / std::max(p.seconds, 1e-9);
      const long long done = before + p.objects_done;
      std::fprintf(stderr, "\r%lld/%lld fits (%.1f%%), point %lld/%d, %.1f fits/s, ETA %.0f s   ", done, total,
                   100.0 * done / total, done / grid.objects_per_point(), n_points, rate, (total - done) / std::max(rate, 1e-9));
    };
    const PipelineSummary summary = run_pipeline(source, sink, make_fitter, po, progress);
    if (show_progress) std::fputc('\n', stderr);
    if (!quiet)
      std::fprintf(stderr, "stampede calibrate build: %lld fits in %.1f s, %.1f fits/s\n", summary.objects,
                   summary.seconds, summary.objects / std::max(summary.seconds, 1e-9));
  }
  if (static_cast<int>(checkpoint.done().size()) != n_points)
    throw std::runtime_error("calibrate build: only " + std::to_string(checkpoint.done().size()) + " of " +
                             std::to_string(n_points) + " grid points were measured");
  table.biases = checkpoint.done();
  table.curves = fit_bias_curves(g, table.points, table.biases);
  const std::string tmp = output + ".tmp";
  io::write_calibration_table(tmp, table, true);
  std::filesystem::rename(tmp, output);
  checkpoint.remove();

  if (!quiet) {
    long long used = 0, failed = 0;
    double err = 0;
    for (const PointBias& b : table.biases) {
      used += b.pairs_used;
      failed += b.pairs_failed;
      if (std::isfinite(b.error[0])) err += b.error[0];
    }
    std::fprintf(stderr, "noise pairs used %lld, lost to a flagged fit %lld; mean error of a point's bias %.2e\n", used,
                 failed, err / n_points);
    std::fprintf(stderr, "%8s %6s %11s %11s %11s %11s\n", "r_d", "F", "m(e=0) e1", "m(e=0) e2", "c1(e=0)", "c2(e=0)");
    for (std::size_t k = 0; k + 3 < table.curves.size(); k += 4) {
      const BiasCurve* c = &table.curves[k];  // (e1, 0), (e1, 1), (e2, 0), (e2, 1)
      std::fprintf(stderr, "%8.3g %6.3g %+11.3e %+11.3e %+11.3e %+11.3e\n", c[0].radius, c[0].bulge_fraction,
                   c[0].coefficients[1], c[3].coefficients[1], 0.5 * (c[0].coefficients[0] + c[2].coefficients[0]),
                   0.5 * (c[1].coefficients[0] + c[3].coefficients[0]));
    }
    std::fprintf(stderr, "wrote %s\n", output.c_str());
  }
  return 0;
}

// ---- apply ----------------------------------------------------------------------------------------

void print_apply_help() {
  std::printf(
      "usage: stampede calibrate apply SCIENCE.fits --calibration CAL.fits (--deep DEEP.fits | --per-object)\n"
      "                                -o OUT.fits [--overwrite] [--quiet]\n"
      "\n"
      "Corrects the noise bias of a `stampede fit` catalogue (im3shape appendix C). OUT.fits is\n"
      "SCIENCE.fits with five columns added to its RESULTS table:\n"
      "  e1_cal, e2_cal   (e - c) / (1 + m)\n"
      "  nbc_m            m applied to the row: m_hat (S/N_ref / snr)^2\n"
      "  nbc_c1, nbc_c2   c applied: c_hat (S/N_ref / snr)^2, turned to the row's PSF: c_hat e_psf / e_psf0\n"
      "and the calibration recorded in its header (NBC* keys). Rows with a non-finite snr or e get NaN.\n"
      "\n"
      "  --calibration CAL  the output of `stampede calibrate build` (same fit configuration)\n"
      "  --deep DEEP.fits   population mode (default): a `stampede fit` catalogue of a deep (high S/N)\n"
      "                     sample of the same population; m_hat and c_hat are the means of the\n"
      "                     calibration's m(r_d, F, |e|) and c over its usable rows, with their\n"
      "                     errors from the calibration's point errors (parametric bootstrap)\n"
      "  --per-object       m and c from each row's own noisy r_d, F and |e| (Kacprzak et al. 2012).\n"
      "                     Biased: the noisy properties carry noise bias themselves (bias on bias;\n"
      "                     im3shape section 5.3 found m = 3e-2 left on GREAT08). For comparison only.\n"
      "  -o OUT.fits        output (written as OUT.fits.partial and renamed when complete)\n");
}

constexpr long long kChunk = 65536;

GalaxyProperties properties(double radius, double bulge_flux, double disc_flux, double e1, double e2) {
  GalaxyProperties p;
  p.radius = radius;
  const double total = bulge_flux + disc_flux;
  p.bulge_fraction = total > 0 ? std::clamp(bulge_flux / total, 0.0, 1.0) : NAN;
  p.e = std::hypot(e1, e2);
  return p;
}

bool finite(const GalaxyProperties& p) {
  return std::isfinite(p.radius) && p.radius > 0 && std::isfinite(p.bulge_fraction) && std::isfinite(p.e);
}

// Reads the columns of the RESULTS table of `f` in chunks and calls fn(first_row, columns).
template <typename Fn>
void for_chunks(io::FitsFile& f, const std::vector<std::string>& names, Fn fn) {
  const long long rows = f.table_rows();
  std::vector<std::vector<double>> cols(names.size());
  for (long long first = 0; first < rows; first += kChunk) {
    const long long n = std::min(kChunk, rows - first);
    for (std::size_t c = 0; c < names.size(); ++c) {
      cols[c].resize(static_cast<std::size_t>(n));
      f.read_column_rows(names[c], first, cols[c]);
    }
    fn(first, cols);
  }
}

int run_apply(int argc, char** argv) {
  std::string science, calibration, deep, output;
  bool per_object = false, overwrite = false, quiet = false;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      print_apply_help();
      return 0;
    } else if (a == "--calibration") calibration = tools::option_value(argc, argv, &i);
    else if (a == "--deep") deep = tools::option_value(argc, argv, &i);
    else if (a == "--per-object") per_object = true;
    else if (a == "-o" || a == "--output") output = tools::option_value(argc, argv, &i);
    else if (a == "--overwrite") overwrite = true;
    else if (a == "--quiet") quiet = true;
    else if (!a.empty() && a[0] == '-') throw std::invalid_argument("unknown option '" + a + "' (see stampede calibrate apply --help)");
    else if (science.empty()) science = a;
    else throw std::invalid_argument("unexpected argument '" + a + "' (one SCIENCE catalogue only)");
  }
  if (science.empty() || calibration.empty() || output.empty())
    throw std::invalid_argument("SCIENCE.fits, --calibration and -o are required (see stampede calibrate apply --help)");
  if (per_object == !deep.empty())
    throw std::invalid_argument("give exactly one of --deep DEEP.fits (population mode) and --per-object");
  if (!overwrite && std::filesystem::exists(output))
    throw std::invalid_argument("'" + output + "' exists (use --overwrite to replace it)");

  const CalibrationTable table = io::read_calibration_table(calibration);
  const NoiseBiasModel model(table);

  // The science run should have been fitted as the calibration was: warn about differences.
  io::FitsFile in = io::FitsFile::open_read(science);
  in.move_to("RESULTS");
  static const std::set<std::string> kMayDiffer = {"noise_sigma", "psf_e1", "psf_e2", "batch_size", "fft_wisdom",
                                                   "save_images", "psf_input", "psf_image", "psf_upsampling",
                                                   "psf_pixel_integrated"};
  int differing = 0;
  for (const auto& [key, value] : table.config) {
    if (kMayDiffer.count(key) || key.starts_with("catalog_")) continue;
    std::string upper = key;
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const auto v = in.read_key_string(upper);
    if (v && *v != value) {
      ++differing;
      if (!quiet)
        std::fprintf(stderr, "stampede calibrate apply: warning: %s has %s = %s, the calibration %s\n", science.c_str(),
                     key.c_str(), v->c_str(), value.c_str());
    }
  }

  Bias population{NAN, NAN, NAN}, population_error{NAN, NAN, NAN};
  long long deep_used = 0, deep_clamped = 0, deep_rows = 0;
  if (!per_object) {
    io::FitsFile d = io::FitsFile::open_read(deep);
    d.move_to("RESULTS");
    PopulationBias pop(model);
    // A subsample (every stride-th row, at most ~20000) for the bootstrap of the calibration error.
    const long long stride = std::max(1LL, (d.table_rows() + 19999) / 20000);
    std::vector<GalaxyProperties> sample;
    for_chunks(d, {"radius", "bulge_flux", "disc_flux", "e1", "e2", "status", "flags"},
               [&](long long, const std::vector<std::vector<double>>& c) {
                 for (std::size_t i = 0; i < c[0].size(); ++i) {
                   ++deep_rows;
                   if (!usable_for_shear(static_cast<FitStatus>(static_cast<int>(c[5][i])),
                                         static_cast<std::uint32_t>(c[6][i])))
                     continue;
                   const GalaxyProperties p = properties(c[0][i], c[1][i], c[2][i], c[3][i], c[4][i]);
                   if (!finite(p)) continue;
                   if (pop.count() % stride == 0) sample.push_back(p);
                   pop.add(p);
                 }
               });
    if (pop.count() == 0) throw std::runtime_error(d.describe() + ": no usable rows for the population");
    population = pop.mean();
    population_error = population_bias_error(table, sample, 200, 1);
    deep_used = pop.count();
    deep_clamped = pop.clamped();
  }

  const std::string partial = output + ".partial";
  {
    io::FitsFile out = io::FitsFile::create(partial, true);
    in.copy_all_hdus_to(out);
    in.move_to("RESULTS");  // the copy walks the input's HDUs
    out.move_to("RESULTS");
    out.add_column("e1_cal", "noise-bias calibrated e1: (e1 - nbc_c1) / (1 + nbc_m)");
    out.add_column("e2_cal", "noise-bias calibrated e2: (e2 - nbc_c2) / (1 + nbc_m)");
    out.add_column("nbc_m", "noise-bias m applied: m (SNRREF / snr)^2");
    out.add_column("nbc_c1", "noise-bias c1 applied, scaled and turned to the row's PSF");
    out.add_column("nbc_c2", "noise-bias c2 applied, scaled and turned to the row's PSF");
    std::vector<std::string> names = {"e1", "e2", "snr", "psf_e1", "psf_e2"};
    if (per_object) names.insert(names.end(), {"radius", "bulge_flux", "disc_flux"});
    std::vector<double> e1c, e2c, m, c1, c2;
    long long rows = 0, nan_rows = 0;
    double sum_m = 0;
    for_chunks(in, names, [&](long long first, const std::vector<std::vector<double>>& c) {
      const std::size_t n = c[0].size();
      for (auto* v : {&e1c, &e2c, &m, &c1, &c2}) v->assign(n, NAN);
      for (std::size_t i = 0; i < n; ++i) {
        Bias b = population;
        if (per_object) {
          const GalaxyProperties p = properties(c[5][i], c[6][i], c[7][i], c[0][i], c[1][i]);
          b = finite(p) ? model.at(p) : Bias{NAN, NAN, NAN};
        }
        const Bias k = object_correction(b, model.snr_ref(), model.psf_e0(), c[2][i], {c[3][i], c[4][i]});
        m[i] = k.m;
        c1[i] = k.c1;
        c2[i] = k.c2;
        calibrate_ellipticity(k, c[0][i], c[1][i], &e1c[i], &e2c[i]);
        ++rows;
        if (std::isfinite(e1c[i])) sum_m += k.m;
        else ++nan_rows;
      }
      out.write_column_rows("e1_cal", first, e1c);
      out.write_column_rows("e2_cal", first, e2c);
      out.write_column_rows("nbc_m", first, m);
      out.write_column_rows("nbc_c1", first, c1);
      out.write_column_rows("nbc_c2", first, c2);
    });
    out.write_key("NBCMODE", std::string(per_object ? "per-object" : "population"), "noise-bias calibration mode");
    out.write_key("NBCCAL", calibration, "calibration table (stampede calibrate build)");
    out.write_key("NBCSNREF", model.snr_ref(), "S/N of the calibration; m, c scale as (NBCSNREF/snr)^2");
    out.write_key("NBCPSFE1", model.psf_e0().real(), "PSF e1 of the calibration (c turned from it)");
    out.write_key("NBCPSFE2", model.psf_e0().imag(), "PSF e2 of the calibration");
    out.write_key("NBCDIFF", static_cast<long long>(differing), "configuration keys differing from the calibration's");
    if (!per_object) {
      out.write_key("NBCDEEP", deep, "deep catalogue giving the population");
      out.write_key("NBCNDEEP", deep_used, "usable deep rows averaged");
      out.write_key("NBCNCLMP", deep_clamped, "deep rows outside the grid, clamped to its edge");
      out.write_key("NBCM", population.m, "population m at NBCSNREF");
      out.write_key("NBCC1", population.c1, "population c1 at NBCSNREF, calibration PSF frame");
      out.write_key("NBCC2", population.c2, "population c2 at NBCSNREF, calibration PSF frame");
      out.write_key("NBCMERR", population_error.m, "error of NBCM from the calibration's point errors");
      out.write_key("NBCC1ERR", population_error.c1, "error of NBCC1 from the calibration's point errors");
      out.write_key("NBCC2ERR", population_error.c2, "error of NBCC2 from the calibration's point errors");
    }
    out.close();
    if (!quiet) {
      if (!per_object)
        std::fprintf(stderr,
                     "stampede calibrate apply: population from %lld of %lld deep rows (%lld clamped to the grid): "
                     "m = %+.4e +- %.1e, c = (%+.3e +- %.1e, %+.3e +- %.1e) at S/N %g\n",
                     deep_used, deep_rows, deep_clamped, population.m, population_error.m, population.c1,
                     population_error.c1, population.c2, population_error.c2, model.snr_ref());
      std::fprintf(stderr, "stampede calibrate apply: %lld rows, %lld without a calibrated e; mean m applied %+.4e; wrote %s\n",
                   rows, nan_rows, sum_m / std::max(1LL, rows - nan_rows), output.c_str());
    }
  }
  std::filesystem::rename(partial, output);
  return 0;
}

}  // namespace

int run_calibrate_command(int argc, char** argv) {
  const std::string sub = argc > 1 ? argv[1] : "";
  if (sub == "build") return run_build(argc, argv);
  if (sub == "apply") return run_apply(argc, argv);
  if (sub == "--help" || sub == "-h") {
    std::printf(
        "usage: stampede calibrate build|apply [options]\n\n"
        "  build   measure the fitter's noise bias on a simulated grid; write a calibration table\n"
        "  apply   correct a fit catalogue with a calibration table and a deep catalogue\n\n"
        "Run 'stampede calibrate build --help' or 'stampede calibrate apply --help' for options.\n");
    return 0;
  }
  throw std::invalid_argument(sub.empty() ? "calibrate needs a sub-command: build or apply"
                                          : "unknown sub-command '" + sub + "' (build or apply)");
}
