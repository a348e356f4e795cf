// `stampede calibrate build | apply`; see calibrate_command.hpp.
#include "tools/calibrate_command.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <optional>
#include <set>
#include <stdexcept>
#include <memory>
#include <string>
#include <vector>

#include "app/calibration_build.hpp"
#include "tools/field_flags.hpp"
#include "engine/calibration/calibration_grid.hpp"
#include "engine/calibration/noise_bias.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "io/calibration_table.hpp"
#include "io/catalog_reader.hpp"
#include "io/fits_file.hpp"
#include "io/output_check.hpp"
#include "app/run_config.hpp"
#include "tools/arguments.hpp"
#include "tools/progress_printer.hpp"

namespace {

using namespace stampede;

// A configuration value in its canonical text, so that a header's number card ("3.0", "1E-06")
// and the calibration's text ("3", "1e-06") compare equal; text that does not parse stays as it is.
std::string canonical_option(const std::string& key, const std::string& text) {
  app::RunConfig c;
  try {
    app::set_option(c, key, text);
    return app::get_option(c, key);
  } catch (const io::ConfigError&) {
    return text;
  }
}

// A run option as a fit table's header records it (the key in upper case), or nullopt.
std::optional<std::string> header_option(io::FitsFile& table, const std::string& key) {
  std::string upper = key;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return table.read_key_string(upper);
}

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
      "  --quiet                  no progress or summary on stderr\n"
      "\n"
      "Choosing the grid for your own data (docs/calibration/README.md has the measured cases):\n"
      "  - Fit a deep sample of your population (the same objects at high S/N, as apply --deep\n"
      "    needs) and read its disc radii r_d and bulge fractions F. m changes fastest with r_d\n"
      "    (at S/N 20 it halves from r_d = 1.2 to 1.6 px): put nodes close enough that neighbours'\n"
      "    m differ by well under 2x where most of the deep r_d lie, and a node at each end; the\n"
      "    bias is interpolated between nodes (cubic splines) and held beyond them. On GREAT08's\n"
      "    fiducial branch 4 radii x 3 fractions left m 1.9e-3 over-corrected, 8 radii\n"
      "    (1.2..3.2) x 5 fractions (0,0.25,..,1) 0.2e-3. The default 1,2.5,5 suits a population\n"
      "    spread that widely.\n"
      "  - --snr: your survey's typical S/N; apply scales the bias as (S/N_ref / snr)^2 per row,\n"
      "    which holds only near S/N_ref: an S/N 20 table leaves m = -4e-3 at S/N 40 (one built\n"
      "    at 40: 1e-4), and at S/N 10 the bias turns over. Build a table at each S/N your data\n"
      "    span.\n"
      "  - --e-max above the population's |e| (0.8 covers e ~ N(0, 0.25) per component).\n"
      "  - --realisations from the precision you need: the table's error on m and c scales as\n"
      "    1/sqrt(N); measured at S/N 20 on 4 x 3 nodes: 32 pairs give m to 3e-3 and c to 1.2e-3,\n"
      "    320 pairs m to 9e-4 and c to 4e-4, 2000 pairs c to 1.6e-4.\n"
      "  - The cost is points x 2 x realisations fits (printed first), each about one science fit\n"
      "    at --snr: the default grid with 32 pairs is 19,584 fits (~0.03 CPU-hours at S/N 20).\n");
}

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
    else throw std::invalid_argument("unknown option " + tools::quoted_value(a) + " (see stampede calibrate build --help)");
  }
  if (output.empty()) throw std::invalid_argument("-o CAL.fits is required (see stampede calibrate build --help)");

  app::CalibrationBuildOptions o;
  o.grid = g;
  o.output = output;
  o.threads = threads;
  o.resume = resume;
  o.overwrite = overwrite;
  if (!config.empty()) app::load_ini(o.config, config);
  for (const auto& s : sets) app::apply_set(o.config, s);
  // The grid's rules name its fields: the command line's words are its flags.
  static const tools::FieldFlags kGridFlags = {{"radii", "--radii"},   {"bulge_fractions", "--bulge-fractions"},
                                               {"e_max", "--e-max"},   {"e_steps", "--e-steps"},
                                               {"snr", "--snr"},       {"realisations", "--realisations"}};
  std::unique_ptr<app::CalibrationBuild> built;
  try {
    built = std::make_unique<app::CalibrationBuild>(o);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(tools::with_flags(e.what(), kGridFlags));
  }
  app::CalibrationBuild& build = *built;
  if (!quiet) std::fprintf(stderr, "%s\n", build.PlanReport().c_str());
  tools::ProgressPrinter printer(stderr, isatty(fileno(stderr)));
  std::function<void(const app::CalibrationBuildProgress&)> progress;
  if (!quiet) progress = [&](const app::CalibrationBuildProgress& p) { printer.update(p.seconds, p.Line()); };
  const app::CalibrationBuildSummary summary = build.run(progress);
  printer.finish();
  if (summary.fitted && !quiet) std::fprintf(stderr, "%s\n", summary.BriefReport().c_str());
  if (!quiet) std::fputs(summary.FullReport().c_str(), stderr);
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

// Reads `fields` of a fit table in chunks and calls fn(first_row, columns), columns in that order.
template <typename Fn>
void for_chunks(io::CatalogReader& f, const std::vector<io::ResultField>& fields, Fn fn) {
  const long long rows = f.rows();
  std::vector<std::vector<double>> cols(fields.size());
  for (long long first = 0; first < rows; first += kChunk) {
    const long long n = std::min(kChunk, rows - first);
    for (std::size_t c = 0; c < fields.size(); ++c) {
      cols[c].resize(static_cast<std::size_t>(n));
      f.column_rows(fields[c], first, cols[c]);
    }
    fn(first, cols);
  }
}

// A noise-bias calibration holds for the estimator it measured: the renderer (renderer = auto as it
// resolved) and the solver (the exact fit's surrogate stage, the amplitudes' projection) that built
// it must be the science run's, else apply refuses, naming both. Tables or catalogues that do not
// record them are refused too: nothing says which estimator they hold.
void check_fit_method(const CalibrationTable& table, const std::string& calibration, io::FitsFile& science_file,
                      const std::string& science) {
  auto table_value = [&](const std::string& key) -> std::optional<std::string> {
    for (const auto& [k, v] : table.config)
      if (k == key) return canonical_option(key, v);
    return std::nullopt;
  };
  auto science_value = [&](const std::string& key) -> std::optional<std::string> {
    const auto v = header_option(science_file, key);
    return v ? std::optional<std::string>(canonical_option(key, *v)) : std::nullopt;
  };
  const std::string rebuild = "; rebuild the calibration with the science run's options (stampede calibrate build)";
  const auto renderer = table_value("renderer"), science_renderer = science_value("renderer");
  if (!renderer || *renderer == "auto")
    throw std::invalid_argument(calibration + " does not record the renderer it was built with (an older table)" + rebuild);
  if (!science_renderer || *science_renderer == "auto")
    throw std::invalid_argument(science + " does not record the renderer that fitted it (not a stampede fit table, or "
                                "a MEDS run's)");
  std::vector<std::string> keys = {"renderer", "project_amplitudes"};
  if (*renderer == "exact") keys.push_back("exact_surrogate");
  for (const std::string& key : keys) {
    const auto built = table_value(key), fitted = science_value(key);
    if (built != fitted)
      throw std::invalid_argument(calibration + " was built with " + key + " = " + built.value_or("(not recorded)") +
                                  ", " + science + " fitted with " + key + " = " + fitted.value_or("(not recorded)") +
                                  ": a calibration holds only for the renderer and solver that built it" + rebuild);
  }
}

// Below this fraction of the calibration's S/N the (S/N)^-2 scaling of its m and c is an
// extrapolation of more than a factor 4.
constexpr double kLowSnrFactor = 0.5;

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
    else if (!a.empty() && a[0] == '-') throw std::invalid_argument("unknown option " + tools::quoted_value(a) + " (see stampede calibrate apply --help)");
    else if (science.empty()) science = a;
    else throw std::invalid_argument("unexpected argument " + tools::quoted_value(a) + " (one SCIENCE catalogue only)");
  }
  if (science.empty() || calibration.empty() || output.empty())
    throw std::invalid_argument("SCIENCE.fits, --calibration and -o are required (see stampede calibrate apply --help)");
  if (per_object == !deep.empty())
    throw std::invalid_argument("give exactly one of --deep DEEP.fits (population mode) and --per-object");
  const std::vector<io::RunInput> inputs = {{"science catalogue", io::fits_root_name(science)},
                                            {"--calibration", io::fits_root_name(calibration)},
                                            {"--deep", io::fits_root_name(deep)}};
  const std::vector<io::RunOutput> outputs = {{"-o", output, {output + ".partial"}}};
  io::check_outputs(outputs, std::span(inputs.data(), deep.empty() ? 2 : 3), overwrite);

  const CalibrationTable table = io::read_calibration_table(calibration);
  const NoiseBiasModel model(table);

  using F = io::ResultField;
  std::vector<F> science_fields = {F::kE1, F::kE2, F::kSnr, F::kPsfE1, F::kPsfE2};
  if (per_object) science_fields.insert(science_fields.end(), {F::kRadius, F::kBulgeFlux, F::kDiscFlux});

  // The science run should have been fitted as the calibration was: warn about differences.
  io::CatalogReader in = io::CatalogReader::open(science, science_fields);
  check_fit_method(table, calibration, in.file(), science);
  static const std::set<std::string> kMayDiffer = {"renderer", "project_amplitudes", "exact_surrogate", "noise_sigma", "psf_e1", "psf_e2", "batch_size", "fft_wisdom",
                                                   "save_images", "psf_input", "psf_image", "psf_upsampling",
                                                   "psf_pixel_integrated"};
  int differing = 0;
  for (const auto& [key, value] : table.config) {
    if (kMayDiffer.count(key) || key.starts_with("catalog_")) continue;
    const auto v = header_option(in.file(), key);
    if (v && canonical_option(key, *v) != canonical_option(key, value)) {
      ++differing;
      if (!quiet)
        std::fprintf(stderr, "stampede calibrate apply: warning: %s has %s = %s, the calibration %s\n", science.c_str(),
                     key.c_str(), v->c_str(), value.c_str());
    }
  }

  Bias population{NAN, NAN, NAN}, population_error{NAN, NAN, NAN};
  long long deep_used = 0, deep_clamped = 0, deep_rows = 0;
  if (!per_object) {
    const std::vector<F> deep_fields = {F::kRadius, F::kBulgeFlux, F::kDiscFlux, F::kE1, F::kE2, F::kStatus, F::kFlags};
    io::CatalogReader d = io::CatalogReader::open(deep, deep_fields);
    PopulationBias pop(model);
    // A subsample (every stride-th row, at most ~20000) for the bootstrap of the calibration error.
    const long long stride = std::max(1LL, (d.rows() + 19999) / 20000);
    std::vector<GalaxyProperties> sample;
    for_chunks(d, deep_fields,
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
  long long rows = 0, nan_rows = 0, clamped = 0, low_snr = 0;
  double max_m = 0;
  {
    io::FitsFile out = io::FitsFile::create(partial, true);
    in.file().copy_all_hdus_to(out);
    in.file().move_to("RESULTS");  // the copy walks the input's HDUs
    out.move_to("RESULTS");
    out.add_column("e1_cal", "noise-bias calibrated e1: (e1 - nbc_c1) / (1 + nbc_m)");
    out.add_column("e2_cal", "noise-bias calibrated e2: (e2 - nbc_c2) / (1 + nbc_m)");
    out.add_column("nbc_m", "noise-bias m applied: m (SNRREF / snr)^2");
    out.add_column("nbc_c1", "noise-bias c1 applied, scaled and turned to the row's PSF");
    out.add_column("nbc_c2", "noise-bias c2 applied, scaled and turned to the row's PSF");
    std::vector<double> e1c, e2c, m, c1, c2;
    double sum_m = 0;
    for_chunks(in, science_fields, [&](long long first, const std::vector<std::vector<double>>& c) {
      const std::size_t n = c[0].size();
      for (auto* v : {&e1c, &e2c, &m, &c1, &c2}) v->assign(n, NAN);
      for (std::size_t i = 0; i < n; ++i) {
        Bias b = population;
        if (per_object) {
          const GalaxyProperties p = properties(c[5][i], c[6][i], c[7][i], c[0][i], c[1][i]);
          bool outside = false;
          b = finite(p) ? model.at(p, &outside) : Bias{NAN, NAN, NAN};
          clamped += outside;
        }
        const Bias k = object_correction(b, model.snr_ref(), model.psf_e0(), c[2][i], {c[3][i], c[4][i]});
        m[i] = k.m;
        c1[i] = k.c1;
        c2[i] = k.c2;
        calibrate_ellipticity(k, c[0][i], c[1][i], &e1c[i], &e2c[i]);
        ++rows;
        if (std::isfinite(e1c[i])) {
          sum_m += k.m;
          max_m = std::max(max_m, std::abs(k.m));
          low_snr += c[2][i] < kLowSnrFactor * model.snr_ref();
        } else {
          ++nan_rows;
        }
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
    out.write_key("NBCNLOW", low_snr, "rows below half NBCSNREF: m, c extrapolated (S/N)^-2");
    if (per_object) out.write_key("NBCNCLMP", clamped, "rows outside the grid, clamped to its edge");
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
  // Said even with --quiet: numbers a user would otherwise take as calibrated.
  if (low_snr > 0)
    std::fprintf(stderr,
                 "stampede calibrate apply: warning: %lld of %lld rows (%.1f%%) have S/N below %g, half the calibration's "
                 "%g: their m and c are the calibration's scaled by (S/N)^-2 beyond its reach (|m| up to %.3g); build "
                 "a calibration at their S/N (calibrate build --snr)\n",
                 low_snr, rows - nan_rows, 100.0 * low_snr / std::max(1LL, rows - nan_rows),
                 kLowSnrFactor * model.snr_ref(), model.snr_ref(), max_m);
  if (per_object && clamped > 0)
    std::fprintf(stderr,
                 "stampede calibrate apply: warning: %lld of %lld rows lie outside the calibration's grid (radius or "
                 "bulge fraction): their bias is the grid edge's (header NBCNCLMP)\n",
                 clamped, rows);
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
