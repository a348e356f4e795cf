// Metrics of metadetection catalogues; see metadetect_metrics.hpp.
#include "app/metadetect_metrics.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "app/metadetect_option_keys.hpp"
#include "app/run_harness.hpp"
#include "engine/common/number_text.hpp"
#include "io/file_digest.hpp"
#include "io/fits_file.hpp"
#include "io/metadetect_reader.hpp"

namespace stampede::app {
namespace {

// The scene keys a run records of its inputs (app/metadetect_run), where every input agrees.
constexpr const char* kShearKeys[2] = {"SHEAR1", "SHEAR2"};

std::optional<double> real_key(const io::MetadetectTable& t, const char* key) {
  const std::optional<std::string> v = t.key(key);
  if (!v) return std::nullopt;
  char* end = nullptr;
  const double x = std::strtod(v->c_str(), &end);
  if (end == v->c_str() || *end != '\0') throw std::invalid_argument(t.path + ": header key " + key + " = '" + *v + "' is not a number");
  return x;
}

// The shear the table's inputs record, or nullopt.
std::optional<std::array<double, 2>> recorded_shear(const io::MetadetectTable& t) {
  const std::optional<double> g1 = real_key(t, kShearKeys[0]), g2 = real_key(t, kShearKeys[1]);
  if (!g1 || !g2) return std::nullopt;
  return std::array<double, 2>{*g1, *g2};
}

std::string shear_text(const std::array<double, 2>& g) {
  char b[64];
  std::snprintf(b, sizeof b, "(%g, %g)", g[0] + 0.0, g[1] + 0.0);  // + 0.0: -0 as 0
  return b;
}

// The inputs' digests, in order (DIGEST1, DIGEST2, ...).
std::vector<std::string> input_digests(const io::MetadetectTable& t) {
  std::vector<std::string> out;
  for (int k = 1;; ++k) {
    const std::optional<std::string> d = t.key("DIGEST" + std::to_string(k));
    if (!d) return out;
    out.push_back(*d);
  }
}

// `b`, given as `role` of `a`, must be measured alike (every option the run records, its bands and
// its kind of input) on other inputs; where both record their scene (app/metadetect_run), `b`'s
// shear is `a`'s times `shear_sign`, its seed `a`'s, and it is turned by 90 degrees exactly when
// `turned`. Throws std::invalid_argument naming both tables and what differs.
void check_pair(const io::MetadetectTable& a, const io::MetadetectTable& b, const std::string& role, double shear_sign,
                bool turned) {
  const std::string pair = b.path + " (" + role + ") and " + a.path;
  std::vector<std::string> keys = {"INPUTS", "BANDS", "DETBANDS", "SHRBANDS", "STARHDU", "STARMARG", "MCSTEP"};
  for (const auto& [key, value] : metadetect_header_keys(MetadetectOptions{})) keys.push_back(key);
  for (const std::string& key : keys) {
    const std::optional<std::string> x = a.key(key), y = b.key(key);
    if (x != y)
      throw std::invalid_argument(pair + " are not measured alike: " + key + " = " + (y ? "'" + *y + "'" : "(absent)") +
                                  " there, " + (x ? "'" + *x + "'" : "(absent)") + " here; a pair is two runs with "
                                  "the same options");
  }
  const std::vector<std::string> da = input_digests(a), db = input_digests(b);
  if (!da.empty() && da == db)
    throw std::invalid_argument(pair + " measured the same input files (their digests are equal): a pair is the "
                                "same scene under another shear or turned, in other files");
  const std::optional<std::array<double, 2>> ga = recorded_shear(a), gb = recorded_shear(b);
  if (ga && gb && !((*gb)[0] == shear_sign * (*ga)[0] && (*gb)[1] == shear_sign * (*ga)[1]))
    throw std::invalid_argument(pair + ": their inputs record the shears " + shear_text(*gb) + " and " + shear_text(*ga) +
                                (shear_sign < 0 ? ", not opposite ones" : ", not the same one"));
  const std::optional<std::string> ra = a.key("SCNROT"), rb = b.key("SCNROT");
  if (ra && rb && (*ra != *rb) != turned)
    throw std::invalid_argument(pair + ": " + (turned ? "the scene is not turned between them" :
                                "one scene is turned by 90 degrees and the other is not") + " (SCNROT " + *rb + " and " + *ra + ")");
  const std::optional<std::string> sa = a.key("SCNSEED"), sb = b.key("SCNSEED");
  if (sa && sb && *sa != *sb)
    throw std::invalid_argument(pair + ": their inputs are of other scenes (seeds " + *sb + " and " + *sa + ")");
}

// The true shear of `plus`: the one its inputs record; else (a table of an older run) its first
// input's G1, G2 keys, when that file is still the one it measured.
std::array<double, 2> true_shear_of(const io::MetadetectTable& plus) {
  if (const auto g = recorded_shear(plus)) return *g;
  const std::optional<std::string> first = plus.key("INPUT1");
  if (!first) throw std::invalid_argument("the true shear is needed: " + plus.path + " records no input; give --shear G1,G2");
  // The input's path as the run was given it: relative to where it ran, which may be the table's
  // directory.
  namespace fs = std::filesystem;
  std::string input = *first;
  if (!fs::exists(input) && fs::path(input).is_relative()) {
    const fs::path beside = fs::path(plus.path).parent_path() / input;
    if (fs::exists(beside)) input = beside.string();
  }
  if (!fs::exists(input))
    throw std::invalid_argument("the true shear: " + plus.path + "'s first input '" + *first +
                                "' is not found here: give it (--shear G1,G2)");
  const std::string digest = io::digest_file(input).text();
  if (const auto recorded = plus.key("DIGEST1"); recorded && *recorded != digest)
    throw std::invalid_argument("the true shear: '" + input + "' is not the file " + plus.path + " measured (its digest " +
                                digest + ", the table records " + *recorded + "): give --shear G1,G2");
  io::FitsFile in = io::FitsFile::open_read(input);
  const std::optional<double> g1 = in.read_key_double("G1"), g2 = in.read_key_double("G2");
  if (!g1 || !g2)
    throw std::invalid_argument("the true shear: " + plus.path + "'s first input '" + input + "' records no shear (G1, "
                                "G2 of its primary HDU, as `sim cells` images do; a cell tile does not): give --shear G1,G2");
  return {*g1, *g2};
}

// What the cuts leave, checked: a catalogue none of whose rows pass is an error that says why.
void check_kept(const MetadetectShear& s, const io::MetadetectTable& t, const MetadetectCuts& cuts) {
  if (s.kept_noshear > 0 && std::isfinite(s.r11) && std::isfinite(s.r22)) return;
  const std::string measured = t.key("MEASURE").value_or("?");
  char b[256];
  std::snprintf(b, sizeof b, "%s: %s of its %zu rows pass the cuts (flags 0, snr > %g, T_ratio > %g, mfrac <= %g)",
                t.path.c_str(), s.kept_noshear > 0 ? "too few (a sheared type keeps none)" : "none", t.cell.size(),
                cuts.min_snr, cuts.min_t_ratio, cuts.max_mfrac);
  throw std::invalid_argument(std::string(b) + "; R and g are undefined: " +
                              (t.cell.empty() ? "the table holds no detection" :
                               "loosen the cuts (--cut-snr, --cut-t-ratio, --cut-mfrac) for this " + measured + " table"));
}

}  // namespace

MetadetectCuts default_metadetect_cuts(const std::string& measurement) {
  MetadetectCuts cuts;
  if (measurement == "pgauss") cuts.min_t_ratio = 0.5;  // the pre-PSF size over the PSF's: DES Y6's cut
  return cuts;
}

MetadetectMetrics metadetect_metrics(const MetadetectMetricsOptions& o) {
  if (o.table.empty()) throw std::invalid_argument("no metadetect table given");
  if (o.rotated.empty() != o.rotated_minus.empty() && !o.minus.empty())
    throw std::invalid_argument("--rotated and --rotated-minus go together with --minus");
  for (const std::string* p : {&o.table, &o.minus, &o.rotated, &o.rotated_minus})
    if (!p->empty()) refuse_unfinished_table(*p, "metadetect table");
  const io::MetadetectTable plus = io::read_metadetect_table(o.table);
  MetadetectCuts cuts = default_metadetect_cuts(plus.key("MEASURE").value_or(""));
  if (o.cut_snr) cuts.min_snr = *o.cut_snr;
  if (o.cut_t_ratio) cuts.min_t_ratio = *o.cut_t_ratio;
  if (o.cut_mfrac) cuts.max_mfrac = *o.cut_mfrac;
  auto sums = [&](const io::MetadetectTable& t) {
    return sum_metadetect_cells(t.cell, t.shear_type, t.e1, t.e2, t.flags, t.snr, t.t_ratio, t.mfrac, cuts);
  };
  auto read = [&](const std::string& path, const io::MetadetectTable& of, const std::string& role, double sign,
                  bool turned) {
    io::MetadetectTable t = io::read_metadetect_table(path);
    check_pair(of, t, role, sign, turned);
    return t;
  };
  MetadetectCellSums ps = sums(plus);
  std::optional<io::MetadetectTable> rotated;
  if (!o.rotated.empty()) {
    rotated = read(o.rotated, plus, "--rotated", 1, true);
    add_cell_sums(sums(*rotated), &ps);
  }
  MetadetectMetrics out;
  out.cuts = cuts;
  out.shear = metadetect_shear(ps, plus.step, o.resamples, o.seed, o.estimator);
  check_kept(out.shear, plus, cuts);
  if (o.minus.empty()) return out;
  const io::MetadetectTable minus = read(o.minus, plus, "--minus", -1, false);
  MetadetectCellSums ms = sums(minus);
  if (!o.rotated_minus.empty()) {
    const io::MetadetectTable rm = read(o.rotated_minus, minus, "--rotated-minus", 1, true);
    check_pair(*rotated, rm, "--rotated-minus", -1, false);
    add_cell_sums(sums(rm), &ms);
  }
  check_kept(metadetect_shear(ms, minus.step, 2, o.seed, o.estimator), minus, cuts);
  const std::optional<std::array<double, 2>> recorded = recorded_shear(plus);
  if (o.shear) {
    if (recorded && *recorded != *o.shear)
      throw std::invalid_argument("--shear " + shear_text(*o.shear) + " but " + o.table + "'s inputs record the shear " +
                                  shear_text(*recorded));
    out.true_shear = *o.shear;
  } else {
    out.true_shear = true_shear_of(plus);
  }
  if (out.true_shear[0] == 0 && out.true_shear[1] == 0)
    throw std::invalid_argument("the true shear of " + o.table + " is (0, 0): m is undefined (give the pair's shear)");
  out.has_bias = true;
  out.bias = metadetect_pair_bias(ps, ms, out.true_shear[0], out.true_shear[1], plus.step, o.resamples, o.seed,
                                  o.estimator);
  for (int k = 0; k < 2; ++k)
    if (out.true_shear[static_cast<std::size_t>(k)] != 0 && !std::isfinite(k == 0 ? out.bias.m1 : out.bias.m2))
      throw std::invalid_argument("m" + std::to_string(k + 1) + " of " + o.table + " and " + o.minus +
                                  " is undefined: their cells share no kept row (cuts flags 0, snr > " +
                                  number_text(cuts.min_snr) + ", T_ratio > " + number_text(cuts.min_t_ratio) +
                                  ", mfrac <= " + number_text(cuts.max_mfrac) + ")");
  return out;
}

}  // namespace stampede::app
