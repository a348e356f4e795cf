// `stampede metrics`; see metrics_command.hpp.
#include "tools/arguments.hpp"
#include "tools/metrics_command.hpp"
#include "tools/json_output.hpp"
#include "tools/metadetect_metrics_command.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/run_harness.hpp"
#include "engine/common/number_text.hpp"
#include "engine/fit/fit_result.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/analysis/metacal_shear.hpp"
#include "engine/analysis/shear_pairs.hpp"
#include "engine/analysis/shear_metrics.hpp"
#include "io/catalog_reader.hpp"
#include "io/fits_file.hpp"
#include "io/simulation_identity.hpp"

namespace {

using namespace stampede;

void print_help() {
  std::printf(
      "usage: stampede metrics --fit FIT.fits --truth TRUTH.fits [--fit ... --truth ...]\n"
      "                        [--json OUT.json] [--bootstrap N] [--seed S] [--e-columns E1,E2]\n"
      "                        [--metacal [--no-selection-response]] [--cut-snr X] [--cut-radius R]\n"
      "                        [--cut-size-ratio Q] [--shear-pairs]\n"
      "       stampede metrics --metadetect TABLE.fits [--minus MINUS.fits] ...  (metadetection catalogues:\n"
      "                        `stampede metrics --metadetect X --help` for its options)\n"
      "\n"
      "Per set (a `stampede fit` table and the truth file of the same set, in the GREAT08-mini\n"
      "layout: SHEAR1 SHEAR2 in the primary header, a TRUTH table with `index` and `pair`):\n"
      "the mean fitted e over usable objects estimates the set's shear, ring pairs averaged first,\n"
      "errors by bootstrap over pairs (default 200 resamples). Excluded: status != ok or flags\n"
      "4/16/32/65536/131072/262144 (at bound, no errors, not converged, edge, PSF failure, metacal\n"
      "failure), with the\n"
      "partner of an excluded ring member. Across sets: a weighted fit g_est = (1 + m) g + c per\n"
      "component, c rotated into the PSF frame (c+ along the PSF), and the GREAT08 quality factor\n"
      "  Q = 1e-4 / mean over sets and both components of (g_est - g_true)^2.\n"
      "\n"
      "  --e-columns E1,E2   the ellipticity columns to use (default e1,e2; e.g. e1_cal,e2_cal from\n"
      "                      `stampede calibrate apply`); rows where they are not finite are excluded\n"
      "  --metacal           tables of a `metacal = true` run: per set g = (<R> + R_S)^-1 <e>, with R_S\n"
      "                      the selection response of the cuts below made on each sheared image's\n"
      "                      quantities (Sheldon & Huff 2017); flag 262144 (metacal failure) excludes\n"
      "  --no-selection-response\n"
      "                      metacal: cut on the noshear quantities alone and leave R_S out, to\n"
      "                      measure the bias a cut causes when its selection response is ignored\n"
      "  --cut-snr X         keep objects with snr >= X (metacal: on every image's own snr)\n"
      "  --cut-radius R      keep objects with radius >= R (likewise; pixels, arcsec for MEDS tables)\n"
      "  --cut-size-ratio Q  metacal: keep objects with radius >= Q x the FWHM of the reconvolution\n"
      "                      PSF Gamma (every image's own radius; Gamma: the header key\n"
      "                      metacal_gamma_fwhm, or a MEDS table's gamma_fwhm column per object)\n"
      "  --shear-pairs       the sets come in pairs from `sim great08 --shear-pairs` (each +g set's\n"
      "                      --fit/--truth followed by its -g partner's): also m from half the pair\n"
      "                      differences and c from half the sums, where the galaxies and noise the\n"
      "                      two share cancel; errors by a bootstrap resampling both sets alike\n");
}

struct Cuts {
  bool metacal = false;
  double min_snr = -INFINITY, min_radius = -INFINITY;
  double min_size_ratio = -INFINITY;  // metacal: radius / Gamma's FWHM
  bool selection_response = true;     // metacal: false leaves R_S out (to measure the bias it removes)

  // The cuts as given on the command line, e.g. "--cut-snr 25 --cut-radius 1"; "no cut" without.
  std::string text() const {
    std::string out;
    auto add = [&](const char* option, double v) {
      if (!std::isfinite(v)) return;
      char buf[64];
      std::snprintf(buf, sizeof buf, "%s%s %.17g", out.empty() ? "" : " ", option, v);
      out += buf;
    };
    add("--cut-snr", min_snr);
    add("--cut-radius", min_radius);
    add("--cut-size-ratio", min_size_ratio);
    return out.empty() ? "no cut" : out;
  }
};

// A number as printf's `format` prints it, or "n/a" (width kept) when it is not finite: an error
// that could not be computed is shown as missing, never as a number.
std::string number_or_na(const char* format, double v, int width = 0) {
  char buf[64];
  if (std::isfinite(v))
    std::snprintf(buf, sizeof buf, format, v);
  else
    std::snprintf(buf, sizeof buf, "%*s", width, "n/a");
  return buf;
}

// JSON has no NaN or infinity: a value not computed is null.
std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);  // reads back bitwise; c ~ 1e-4 keeps its digits
  return buf;
}

// A set's estimate, and what pairing it with its shear-pair partner needs.
struct SetData {
  SetShear shear;
  std::unique_ptr<UnitShearEstimator> units;  // --shear-pairs only: a copy of the set's rows
  long long index = -1, partner = -1;  // SETIDX and SHEARPR of the truth (-1: none)
};

// A table's integer as the fit or simulation wrote it: a value none writes (NaN, 2.5, a status past
// the last) is a damaged or foreign file, named rather than cast (NaN to an integer is undefined).
void check_integer(const std::string& where, const char* column, std::size_t row, double v, double lo, double hi) {
  if (!(v >= lo && v <= hi && v == std::floor(v)))
    throw std::runtime_error(where + ": column '" + column + "' row " + std::to_string(row) + " = " + number_text(v) +
                             " is not an integer in [" + number_text(lo) + ", " + number_text(hi) + "]");
}

SetData read_set(const std::string& fit_path, const std::string& truth_path, const std::string& e1_column,
                 const std::string& e2_column, int bootstrap, std::uint64_t seed, const Cuts& cuts, double* psf_e1,
                 double* psf_e2, bool units) {
  using F = io::ResultField;
  app::refuse_unfinished_table(io::fits_root_name(fit_path), "fit catalogue");  // a .partial holds a run in progress
  io::CatalogReader fit = io::CatalogReader::open(fit_path, {F::kId, F::kStatus, F::kFlags, F::kPsfE1, F::kPsfE2});
  const auto id = fit.column(F::kId), e1 = fit.column(e1_column), e2 = fit.column(e2_column),
             status = fit.column(F::kStatus), flags = fit.column(F::kFlags), pe1 = fit.column(F::kPsfE1),
             pe2 = fit.column(F::kPsfE2);
  io::FitsFile truth = io::FitsFile::open_read(truth_path);
  const double g1 = truth.key_double("SHEAR1"), g2 = truth.key_double("SHEAR2");
  if (!(std::abs(g1) < 1 && std::abs(g2) < 1))
    throw std::runtime_error(truth.describe() + ": SHEAR1, SHEAR2 = " + number_text(g1) + ", " + number_text(g2) +
                             " is not a shear (|g| < 1)");
  SetData out;
  out.index = truth.read_key_long("SETIDX").value_or(-1);
  out.partner = truth.read_key_long("SHEARPR").value_or(-1);
  // The set the fit was of (its input's SEED SETIDX NOISESD) must be the truth's: row-by-row ids
  // cannot tell two sets of one grid apart.
  const std::string fitted_set = fit.file().read_key_string(io::kInputSetKey).value_or("");
  const std::string truth_set = io::simulation_identity(truth);
  if (!fitted_set.empty() && fitted_set != truth_set)
    throw std::runtime_error(fit.describe() + " is a fit of set '" + fitted_set + "' (" + io::kInputSetKey + "), but " +
                             truth_path + " is the truth of set '" + truth_set + "': pair each fit with its own set's truth");
  truth.move_to("TRUTH");
  const auto index = truth.read_column("index");
  std::vector<double> pair_col;
  if (truth.has_column("pair")) pair_col = truth.read_column("pair");
  if (index.size() != id.size())
    throw std::runtime_error(fit.describe() + " has " + std::to_string(id.size()) + " rows, " + truth.describe() +
                             " has " + std::to_string(index.size()));
  std::vector<int> usable(id.size());
  std::vector<long long> pair(pair_col.empty() ? 0 : id.size());
  for (std::size_t i = 0; i < id.size(); ++i) {
    if (id[i] != index[i])
      throw std::runtime_error(fit.describe() + ": row " + std::to_string(i) + " is object " + std::to_string(id[i]) +
                               " but the truth row is object " + std::to_string(index[i]));
    check_integer(fit.describe(), "status", i, status[i], 0, kFitStatusCount - 1);
    check_integer(fit.describe(), "flags", i, flags[i], 0, 4294967295.0);
    usable[i] = usable_for_shear(static_cast<FitStatus>(static_cast<int>(status[i])), static_cast<std::uint32_t>(flags[i])) &&
                std::isfinite(e1[i]) && std::isfinite(e2[i]);
    // A fit's |e| is below 1 (calibrated columns a little beyond): 1e308 is a damaged table, whose
    // mean would overflow to an infinite shear.
    for (const auto& [column, e] : {std::pair{&e1_column, &e1}, std::pair{&e2_column, &e2}})
      if (usable[i] && !(std::abs((*e)[i]) <= 10))
        throw std::runtime_error(fit.describe() + ": column '" + *column + "' row " + std::to_string(i) + " = " +
                                 number_text((*e)[i]) + " is not an ellipticity (|e| <= 10)");
    if (!pair.empty()) {
      check_integer(truth.describe(), "pair", i, pair_col[i], -9007199254740992.0, 9007199254740992.0);
      pair[i] = static_cast<long long>(pair_col[i]);
    }
  }
  // The frame c is rotated into: the PSF's e (both components finite and |e| < 1; a damaged row 0
  // printed "e = 0.000, -inf").
  if (!pe1.empty() && std::abs(pe1[0]) < 1 && std::abs(pe2[0]) < 1) {
    *psf_e1 = pe1[0];
    *psf_e2 = pe2[0];
  }
  const bool cut = std::isfinite(cuts.min_snr) || std::isfinite(cuts.min_radius);
  auto passes = [&](double snr, double radius) {  // an unset cut keeps everything, NaN included
    return (!std::isfinite(cuts.min_snr) || snr >= cuts.min_snr) && (!std::isfinite(cuts.min_radius) || radius >= cuts.min_radius);
  };
  SetShear& set = out.shear;
  if (cuts.metacal) {
    if (!fit.has(F::kR11))
      throw std::runtime_error(fit.describe() + " has no metacal columns (R11 ...): fit with metacal = true, or drop --metacal");
    const std::optional<double> recorded_step = fit.file().read_key_double("metacal_step");
    if (!recorded_step) throw std::runtime_error(fit.describe() + ": no metacal_step key (R is measured over it)");
    const double step = *recorded_step;
    if (!(step > 0 && step <= 0.1))
      throw std::runtime_error(fit.describe() + ": metacal_step = " + number_text(step) + " is not a metacal step in (0, 0.1]");
    const auto snr = fit.column(F::kSnr), radius = fit.column(F::kRadius);
    // The size-ratio cut is a radius cut at Q x Gamma, the PSF of all five images: per object in a
    // survey table, one for a grid's run.
    std::vector<double> gamma;
    if (std::isfinite(cuts.min_size_ratio)) {
      if (fit.has(F::kGammaFwhm)) {
        gamma = fit.column(F::kGammaFwhm);
      } else {
        const double g = fit.file().read_key_double("metacal_gamma_fwhm").value_or(NAN);
        if (!(g > 0)) throw std::runtime_error(fit.describe() + ": --cut-size-ratio needs a metacal_gamma_fwhm key or gamma_fwhm column");
        gamma.assign(id.size(), g);
      }
    }
    auto sized = [&](std::size_t i, double r) { return gamma.empty() || r >= cuts.min_size_ratio * gamma[i]; };
    const auto r11 = fit.column(F::kR11), r12 = fit.column(F::kR12), r21 = fit.column(F::kR21), r22 = fit.column(F::kR22);
    const F sheared[4][2] = {{F::kSnr_1p, F::kRadius_1p}, {F::kSnr_1m, F::kRadius_1m}, {F::kSnr_2p, F::kRadius_2p},
                             {F::kSnr_2m, F::kRadius_2m}};
    std::vector<std::vector<double>> snr_t(4), radius_t(4);
    for (int t = 0; t < 4; ++t) snr_t[t] = fit.column(sheared[t][0]), radius_t[t] = fit.column(sheared[t][1]);
    std::vector<std::uint8_t> selected(id.size());
    for (std::size_t i = 0; i < id.size(); ++i) {
      if (!usable[i]) continue;
      std::uint8_t bits = passes(snr[i], radius[i]) && sized(i, radius[i]) ? 1 : 0;
      for (int t = 0; t < 4; ++t) {
        // Without R_S each sheared image's selection is the noshear one, so R_S is exactly 0.
        const bool kept = cuts.selection_response ? passes(snr_t[t][i], radius_t[t][i]) && sized(i, radius_t[t][i]) : bits;
        bits |= (kept ? 1 : 0) << (t + 1);
      }
      selected[i] = bits;
    }
    const MetacalRows rows{e1, e2, {r11, r12, r21, r22}, selected, pair, step};
    const MetacalSetShear m = estimate_metacal_set_shear(rows, g1, g2, bootstrap, seed);
    if (const int empty = m.empty_selection(); empty >= 0 && m.selected_units[0] > 0) {
      std::string names;
      for (int t = 1; t < 5; ++t)
        if (m.selected_units[t] == 0) names += std::string(names.empty() ? "" : ", ") + kMetacalSelectionNames[t];
      throw std::runtime_error(fit.describe() + ": " + cuts.text() + " keeps " + std::to_string(m.selected_units[0]) +
                               " ring pairs (or lone objects) on the noshear image but none on the " + names +
                               " image's quantities, so <e> over that selection and R_S are undefined: loosen the cut "
                               "(or measure without R_S: --no-selection-response)");
    }
    if (units) out.units = make_metacal_units(rows);
    std::printf("%s: <R> = [[%+.4f %+.4f] [%+.4f %+.4f]]  R_S = [[%+.4f %+.4f] [%+.4f %+.4f]]  <e> = (%+.6f, %+.6f)\n",
                fit_path.c_str(), m.r[0], m.r[1], m.r[2], m.r[3], m.r_sel[0], m.r_sel[1], m.r_sel[2], m.r_sel[3],
                m.g1_raw, m.g2_raw);
    set = m.shear;
  } else {
    if (cut) {
      const auto snr = fit.column(F::kSnr), radius = fit.column(F::kRadius);
      for (std::size_t i = 0; i < id.size(); ++i) usable[i] = usable[i] && passes(snr[i], radius[i]);
    }
    set = estimate_set_shear(e1, e2, usable, pair, g1, g2, bootstrap, seed);
    if (units) out.units = make_shear_units(e1, e2, usable, pair);
  }
  if (set.used == 0)
    throw std::runtime_error(fit.describe() + ": all " + std::to_string(id.size()) +
                             " rows are excluded (status not ok, flags 4/16/32/65536/131072/262144, e not finite, or "
                             "cut: " + cuts.text() + "), so the set has no shear estimate");
  return out;
}

// Consecutive --fit sets as shear pairs: each odd one the SHEARPR partner of the one before, under
// the opposite shear.
ShearPairMetrics pair_sets(const std::vector<SetData>& sets, const std::vector<std::string>& truths, int bootstrap,
                           std::uint64_t seed, double psf_e1, double psf_e2, std::vector<ShearPairEstimate>* pairs) {
  if (sets.size() % 2 != 0)
    throw std::invalid_argument("--shear-pairs: " + std::to_string(sets.size()) +
                                " sets given; give each +g set followed by its -g partner");
  for (std::size_t k = 0; k < sets.size(); k += 2) {
    const SetData &plus = sets[k], &minus = sets[k + 1];
    if (plus.partner < 0 || plus.partner != minus.index || minus.partner != plus.index)
      throw std::invalid_argument("--shear-pairs: " + truths[k] + " (SETIDX " + std::to_string(plus.index) + ", SHEARPR " +
                                  std::to_string(plus.partner) + ") and " + truths[k + 1] + " (SETIDX " +
                                  std::to_string(minus.index) + ", SHEARPR " + std::to_string(minus.partner) +
                                  ") are not a shear pair: simulate with `sim great08 --shear-pairs` and give each "
                                  "pair's sets one after the other");
    if (minus.shear.g1_true != -plus.shear.g1_true || minus.shear.g2_true != -plus.shear.g2_true)
      throw std::invalid_argument("--shear-pairs: " + truths[k + 1] + " does not hold the opposite shear of " + truths[k]);
    pairs->push_back(estimate_shear_pair(*plus.units, *minus.units, plus.shear.g1_true, plus.shear.g2_true, bootstrap,
                                         seed + k));
  }
  return combine_shear_pairs(*pairs, psf_e1, psf_e2);
}

}  // namespace

int run_metrics_command(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--metadetect") return run_metadetect_metrics_command(argc, argv);
  std::vector<std::string> fits, truths;
  std::string json, e1_column = io::column_name(io::ResultField::kE1),
                    e2_column = io::column_name(io::ResultField::kE2);
  int bootstrap = 200;
  std::uint64_t seed = 1;
  Cuts cuts;
  bool shear_pairs = false;
  std::set<std::string> given_once;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    // An option that takes one value, given twice: the last would silently win over the first.
    if ((a == "--json" || a == "--e-columns" || a == "--cut-snr" || a == "--cut-radius" || a == "--cut-size-ratio" ||
         a == "--bootstrap" || a == "--seed") &&
        !given_once.insert(a).second)
      throw std::invalid_argument(a + " is given twice: give it once (see stampede metrics --help)");
    if (a == "--help" || a == "-h") {
      print_help();
      return 0;
    } else if (a == "--fit") {
      fits.push_back(value());
      // The same table twice would count its sets twice (and its errors as independent).
      for (std::size_t k = 0; k + 1 < fits.size(); ++k) {
        std::error_code ec;
        if (fits[k] == fits.back() || std::filesystem::equivalent(fits[k], fits.back(), ec))
          throw std::invalid_argument("--fit " + tools::quoted_value(fits.back(), kQuotedPathMaxBytes) +
                                      " is given twice (as --fit " + tools::quoted_value(fits[k], kQuotedPathMaxBytes) +
                                      " too): give each set's table once");
      }
    } else if (a == "--truth") {
      truths.push_back(value());
    } else if (a == "--json") {
      json = value();
    } else if (a == "--e-columns") {
      const std::string v = value();
      const auto comma = v.find(',');
      if (comma == std::string::npos || comma == 0 || comma + 1 == v.size() || v.find(',', comma + 1) != std::string::npos)
        throw std::invalid_argument("option --e-columns: " + tools::quoted_value(v) + " is not two column names 'E1,E2'");
      e1_column = v.substr(0, comma);
      e2_column = v.substr(comma + 1);
    } else if (a == "--shear-pairs") {
      shear_pairs = true;
    } else if (a == "--metacal") {
      cuts.metacal = true;
    } else if (a == "--no-selection-response") {
      cuts.selection_response = false;
    } else if (a == "--cut-snr") {
      cuts.min_snr = tools::number_value(argc, argv, &i);
    } else if (a == "--cut-radius") {
      cuts.min_radius = tools::number_value(argc, argv, &i);
    } else if (a == "--cut-size-ratio") {
      cuts.min_size_ratio = tools::number_value(argc, argv, &i);
    } else if (a == "--bootstrap") {
      bootstrap = static_cast<int>(tools::integer_in(argc, argv, &i, 0, 1000000));
    } else if (a == "--seed") {
      seed = static_cast<std::uint64_t>(tools::integer_in(argc, argv, &i, 0, std::numeric_limits<long long>::max()));
    } else {
      throw std::invalid_argument("unknown option " + tools::quoted_value(a) + " (see stampede metrics --help)");
    }
  }
  if (std::isfinite(cuts.min_size_ratio) && !cuts.metacal)
    throw std::invalid_argument("--cut-size-ratio is a metacal cut (the images' PSF is Gamma): add --metacal");
  // R is the response of the noshear e (e1, e2) to shear: applied to other columns (calibrate
  // apply's e1_cal, e2_cal, already corrected for noise bias) it would calibrate twice.
  auto lower = [](std::string t) {
    for (char& ch : t) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return t;
  };  // FITS column names match without case
  if (cuts.metacal && (lower(e1_column) != io::column_name(io::ResultField::kE1) ||
                       lower(e2_column) != io::column_name(io::ResultField::kE2)))
    throw std::invalid_argument("--metacal with --e-columns " + tools::quoted_value(e1_column + "," + e2_column) +
                                ": metacal's R is the response of the noshear e (e1, e2) and calibrates them; applied to "
                                "other columns (calibrate apply's e1_cal, e2_cal are calibrated already) it would "
                                "calibrate twice. Drop --e-columns, or --metacal to measure calibrated columns as they are");
  if (!cuts.selection_response && !cuts.metacal)
    throw std::invalid_argument("--no-selection-response leaves metacal's R_S out: add --metacal");
  if (fits.empty() || fits.size() != truths.size())
    throw std::invalid_argument("give one --truth for each --fit (got " + std::to_string(fits.size()) + " and " +
                                std::to_string(truths.size()) + ")");
  if (!json.empty()) {
    std::vector<std::pair<std::string, std::string>> inputs;
    for (std::size_t k = 0; k < fits.size(); ++k) inputs.insert(inputs.end(), {{"--fit", fits[k]}, {"--truth", truths[k]}});
    tools::check_json_output(json, inputs);
  }
  double psf_e1 = 0, psf_e2 = 0;
  std::vector<SetData> data;
  std::vector<SetShear> sets;
  for (std::size_t k = 0; k < fits.size(); ++k) {
    data.push_back(read_set(fits[k], truths[k], e1_column, e2_column, bootstrap, seed + k, cuts, &psf_e1, &psf_e2,
                            shear_pairs));
    sets.push_back(data.back().shear);
  }
  std::vector<ShearPairEstimate> pair_estimates;
  ShearPairMetrics paired;
  if (shear_pairs) paired = pair_sets(data, truths, bootstrap, seed, psf_e1, psf_e2, &pair_estimates);
  data.clear();  // the units hold copies of every row
  const ShearMetrics m = combine_sets(sets, psf_e1, psf_e2);
  std::printf("%-4s %10s %10s %10s %9s %10s %10s %9s %6s %8s\n", "set", "g1_true", "g1", "g1-g1_t", "err1", "g2_true", "g2",
              "err2", "used", "excluded");
  std::vector<std::string> without_errors;  // sets whose bootstrap gave no error, and why
  for (std::size_t k = 0; k < m.sets.size(); ++k) {
    const SetShear& s = m.sets[k];
    std::printf("%-4zu %+10.6f %+10.6f %+10.2e %s %+10.6f %+10.6f %s %6lld %8lld\n", k, s.g1_true, s.g1,
                s.g1 - s.g1_true, number_or_na("%9.2e", s.err1, 9).c_str(), s.g2_true, s.g2,
                number_or_na("%9.2e", s.err2, 9).c_str(), s.used, s.excluded);
    if (!std::isfinite(s.err1) || !std::isfinite(s.err2))
      without_errors.push_back("set " + std::to_string(k) + ": " +
                               (bootstrap < 2 ? "--bootstrap " + std::to_string(bootstrap) + " (errors need 2 or more)"
                                              : std::to_string(s.units) + " usable ring pair" + (s.units == 1 ? "" : "s") +
                                                    " (a bootstrap error needs 2 or more)"));
  }
  for (const std::string& why : without_errors) std::printf("err n/a: %s\n", why.c_str());
  if (std::isfinite(m.component[0].m) && std::isfinite(m.component[1].m)) {
    for (int c = 0; c < 2; ++c)
      std::printf("m%d = %+.3e +- %s   c%d = %+.3e +- %s\n", c + 1, m.component[c].m,
                  number_or_na("%.1e", m.component[c].m_err).c_str(), c + 1, m.component[c].c,
                  number_or_na("%.1e", m.component[c].c_err).c_str());
    if (!std::isfinite(m.component[0].m_err) || !std::isfinite(m.component[1].m_err))
      std::printf("m, c errors n/a: %s\n",
                  without_errors.empty()
                      ? "the sets' errors are not finite"
                      : (std::to_string(m.sets.size()) + " sets, not all with a bootstrap error (err n/a above): "
                         "the fit is then unweighted, its errors from the scatter about the line, which needs 3 "
                         "sets or more")
                            .c_str());
    std::printf("PSF frame (e = %.3f, %.3f): c+ = %+.3e  cx = %+.3e\n", psf_e1, psf_e2, m.c_plus, m.c_cross);
  } else {
    std::printf("m, c: need at least two sets with different shears\n");
  }
  std::printf("Q = %.1f  (1e-4 / mean over sets and components of (g_est - g_true)^2)\n", m.q);
  if (shear_pairs) {
    std::printf("shear pairs: m from (g_+ - g_-) / 2 = (1 + m) g, c from (g_+ + g_-) / 2, joint bootstrap\n");
    std::printf("%-4s %10s %12s %9s %12s %9s %10s %12s %9s %12s %9s\n", "pair", "g1_true", "(g+-g-)/2", "err", "(g++g-)/2",
                "err", "g2_true", "(g+-g-)/2", "err", "(g++g-)/2", "err");
    for (std::size_t j = 0; j < pair_estimates.size(); ++j) {
      const ShearPairEstimate& p = pair_estimates[j];
      auto err = [](double v) { return number_or_na("%9.2e", v, 9); };
      std::printf("%-4zu %+10.6f %+12.6f %s %+12.2e %s %+10.6f %+12.6f %s %+12.2e %s\n", j, p.g1_true,
                  p.half_difference[0], err(p.half_difference_err[0]).c_str(), p.half_sum[0],
                  err(p.half_sum_err[0]).c_str(), p.g2_true, p.half_difference[1], err(p.half_difference_err[1]).c_str(),
                  p.half_sum[1], err(p.half_sum_err[1]).c_str());
    }
    for (int c = 0; c < 2; ++c)
      std::printf("paired m%d = %+.3e +- %s   c%d = %+.3e +- %s\n", c + 1, paired.component[c].m,
                  number_or_na("%.1e", paired.component[c].m_err).c_str(), c + 1, paired.component[c].c,
                  number_or_na("%.1e", paired.component[c].c_err).c_str());
    std::printf("paired PSF frame: c+ = %+.3e  cx = %+.3e\n", paired.c_plus, paired.c_cross);
  }
  if (!json.empty()) {
    std::ostringstream out;
    out << "{\n  \"sets\": [\n";
    for (std::size_t k = 0; k < m.sets.size(); ++k) {
      const SetShear& s = m.sets[k];
      out << "    {\"fit\": " << tools::json_string(fits[k]) << ", \"g1_true\": " << json_number(s.g1_true)
          << ", \"g2_true\": " << json_number(s.g2_true) << ", \"g1\": " << json_number(s.g1) << ", \"g2\": "
          << json_number(s.g2) << ", \"err1\": " << json_number(s.err1) << ", \"err2\": " << json_number(s.err2)
          << ", \"used\": " << s.used << ", \"excluded\": " << s.excluded << ", \"units\": " << s.units << "}"
          << (k + 1 < m.sets.size() ? "," : "") << "\n";
    }
    auto num = [](double v) {
      if (!std::isfinite(v)) return std::string("null");
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.9g", v);  // c ~ 1e-4: fixed-point to_string would lose it
      return std::string(buf);
    };
    out << "  ],\n  \"m1\": " << num(m.component[0].m) << ", \"m1_err\": " << num(m.component[0].m_err)
        << ", \"c1\": " << num(m.component[0].c) << ", \"c1_err\": " << num(m.component[0].c_err) << ",\n  \"m2\": "
        << num(m.component[1].m) << ", \"m2_err\": " << num(m.component[1].m_err) << ", \"c2\": " << num(m.component[1].c)
        << ", \"c2_err\": " << num(m.component[1].c_err) << ",\n  \"c_plus\": " << num(m.c_plus)
        << ", \"c_cross\": " << num(m.c_cross) << ", \"q\": " << num(m.q);
    if (shear_pairs) {
      const BiasFit &a = paired.component[0], &b = paired.component[1];
      out << ",\n  \"paired\": {\"pairs\": " << pair_estimates.size() << ", \"m1\": " << num(a.m) << ", \"m1_err\": "
          << num(a.m_err) << ", \"c1\": " << num(a.c) << ", \"c1_err\": " << num(a.c_err) << ", \"m2\": " << num(b.m)
          << ", \"m2_err\": " << num(b.m_err) << ", \"c2\": " << num(b.c) << ", \"c2_err\": " << num(b.c_err)
          << ", \"c_plus\": " << num(paired.c_plus) << ", \"c_cross\": " << num(paired.c_cross) << "}";
    }
    out << "\n}\n";
    tools::write_json(json, out.str());
  }
  return 0;
}
