// `stampede metrics --metadetect PLUS.fits [--minus MINUS.fits]`; see print_help.
#include "tools/metadetect_metrics_command.hpp"

#include <cmath>
#include <cstdio>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>

#include "app/metadetect_metrics.hpp"
#include "engine/analysis/metadetect_shear.hpp"
#include "tools/arguments.hpp"
#include "tools/json_output.hpp"

namespace {

using namespace stampede;

void print_help() {
  const MetadetectCuts d = app::default_metadetect_cuts("wmom"), pgauss = app::default_metadetect_cuts("pgauss");
  std::printf(
      "usage: stampede metrics --metadetect TABLE.fits [--minus MINUS.fits] [--shear G1,G2] [options]\n"
      "\n"
      "The response and shear of a `stampede metadetect` catalogue: each shear type's catalogue is cut\n"
      "on its own quantities (so that the selection is inside R), R11 = (<e1>_1p - <e1>_1m) / (2 step),\n"
      "R22 likewise, g = <e>_noshear / R. With --minus, the catalogue of the same cells under the\n"
      "opposite shear (`sim cells --pair`): m = (<e1>+ - <e1>-) / 2 / <R11> / g1 - 1 and c = (<e2>+ +\n"
      "<e2>-) / 2 / <R22> (and m2, c1 for a shear along g2). Errors: bootstrap over cells (a pair's two\n"
      "cells together). The shear is read with metacal's step composed with the image's shear (its\n"
      "response R / (1 - |g|^2); the package's estimator reads |g| high by |g|^2).\n"
      "\n"
      "options:\n"
      "  --minus PATH          the shear pair's other catalogue\n"
      "  --rotated PATH        the catalogue of the same cells' scenes turned by 90 degrees (`sim\n"
      "                        cells --rotate`), and --rotated-minus PATH its pair: each joins its cell\n"
      "                        (intrinsic shapes cancel, as in ring pairs)\n"
      "  --shear G1,G2         the true shear of TABLE (default: the one its inputs record, as `sim\n"
      "                        cells` writes it)\n"
      "  --cut-snr X           keep rows with snr > X (%g)\n"
      "  --cut-t-ratio Q       keep rows with T_ratio > Q (%g; a pgauss table's: %g)\n"
      "  --cut-mfrac F         keep rows with mfrac <= F, the masked share about them (%g)\n"
      "  --estimator E         composed: g = <e> (1 - |g|^2) / R (default); package: <e> / R, the\n"
      "                        reference metadetect package's\n"
      "  --bootstrap N         bootstrap resamples (200)\n"
      "  --seed N              bootstrap seed (1)\n"
      "  --json PATH           also write the figures as JSON\n"
      "\n"
      "The tables of a pair must be measured alike on other files; where their inputs record their\n"
      "scene (sim cells' do), opposite shears of one scene, turned exactly where given as --rotated.\n"
      "Cuts that keep no row are an error.\n",
      d.min_snr, d.min_t_ratio, pgauss.min_t_ratio, d.max_mfrac);
}

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.6e", v);
  return b;
}

}  // namespace

int run_metadetect_metrics_command(int argc, char** argv) {
  std::string plus_path, minus_path, rotated_path, rotated_minus_path, json;
  std::optional<std::array<double, 2>> shear;
  std::optional<double> cut_snr, cut_t_ratio, cut_mfrac;
  MetadetectEstimator estimator = MetadetectEstimator::kComposed;
  int resamples = 200;
  std::uint64_t seed = 1;
  std::set<std::string> seen;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    if (a.starts_with("--") && a != "--help" && !seen.insert(a).second)
      throw std::invalid_argument(a + " is given twice (see stampede metrics --help)");
    if (a == "--help" || a == "-h") {
      print_help();
      return 0;
    } else if (a == "--metadetect") {
      plus_path = value();
    } else if (a == "--minus") {
      minus_path = value();
    } else if (a == "--rotated") {
      rotated_path = value();
    } else if (a == "--rotated-minus") {
      rotated_minus_path = value();
    } else if (a == "--shear") {
      shear = tools::number_pair(a, value(), "two numbers G1,G2");
    } else if (a == "--cut-snr") {
      cut_snr = tools::number_value(argc, argv, &i);
    } else if (a == "--cut-t-ratio") {
      cut_t_ratio = tools::number_value(argc, argv, &i);
    } else if (a == "--cut-mfrac") {
      cut_mfrac = tools::number_value(argc, argv, &i);
    } else if (a == "--estimator") {
      const std::string v = value();
      if (!parse_metadetect_estimator(v, &estimator))
        throw std::invalid_argument("option --estimator " + tools::quoted_value(v) + ": must be composed or package");
    } else if (a == "--bootstrap") {
      resamples = static_cast<int>(tools::integer_in(argc, argv, &i, 2, 100000));
    } else if (a == "--seed") {
      seed = static_cast<std::uint64_t>(tools::integer_in(argc, argv, &i, 0, 1LL << 62));
    } else if (a == "--json") {
      json = value();
    } else {
      throw std::invalid_argument("option " + tools::quoted_value(a) + " is not one of metrics --metadetect's");
    }
  }
  if (!json.empty())
    tools::check_json_output(json, {{"--metadetect", plus_path}, {"--minus", minus_path}, {"--rotated", rotated_path},
                                    {"--rotated-minus", rotated_minus_path}});
  app::MetadetectMetricsOptions mo;
  mo.table = plus_path, mo.minus = minus_path, mo.rotated = rotated_path, mo.rotated_minus = rotated_minus_path;
  mo.shear = shear, mo.cut_snr = cut_snr, mo.cut_t_ratio = cut_t_ratio, mo.cut_mfrac = cut_mfrac, mo.resamples = resamples, mo.seed = seed, mo.estimator = estimator;
  const app::MetadetectMetrics r = app::metadetect_metrics(mo);
  const MetadetectShear& s = r.shear;
  const MetadetectCuts& cuts = r.cuts;
  std::printf("%s: %lld cells, %.0f noshear rows kept (snr > %g, T_ratio > %g, mfrac <= %g, flags 0)\n",
              plus_path.c_str(), s.cells, s.kept_noshear, cuts.min_snr, cuts.min_t_ratio, cuts.max_mfrac);
  std::printf("  R11 = %.5f +- %.5f   R22 = %.5f +- %.5f\n", s.r11, s.r11_err, s.r22, s.r22_err);
  std::printf("  g1  = %+.3e +- %.1e   g2 = %+.3e +- %.1e\n", s.g1, s.g1_err, s.g2, s.g2_err);
  if (s.cells < 2) std::printf("  (one cell: no errors; they are a bootstrap over cells, which needs two)\n");
  std::string out = "{\"table\": " + tools::json_string(plus_path) + ", \"cells\": " + std::to_string(s.cells) +
                    ", \"cut_snr\": " + number(cuts.min_snr) + ", \"cut_t_ratio\": " + number(cuts.min_t_ratio) +
                    ", \"cut_mfrac\": " + number(cuts.max_mfrac) +
                    ", \"R11\": " + number(s.r11) +
                    ", \"R11_err\": " + number(s.r11_err) + ", \"R22\": " + number(s.r22) + ", \"R22_err\": " +
                    number(s.r22_err) + ", \"g1\": " + number(s.g1) + ", \"g1_err\": " + number(s.g1_err) +
                    ", \"g2\": " + number(s.g2) + ", \"g2_err\": " + number(s.g2_err);
  if (r.has_bias) {
    const MetadetectBias& b = r.bias;
    std::printf("shear pair with %s, g = (%g, %g), %lld pairs of cells, estimator %s:\n", minus_path.c_str(),
                r.true_shear[0], r.true_shear[1], b.pairs, metadetect_estimator_name(estimator));
    if (std::isfinite(b.m1)) std::printf("  m1 = %+.3e +- %.1e   c2 = %+.3e +- %.1e\n", b.m1, b.m1_err, b.c2, b.c2_err);
    if (std::isfinite(b.m2)) std::printf("  m2 = %+.3e +- %.1e   c1 = %+.3e +- %.1e\n", b.m2, b.m2_err, b.c1, b.c1_err);
    out += ", \"minus\": " + tools::json_string(minus_path) + ", \"shear\": [" + number(r.true_shear[0]) + ", " +
           number(r.true_shear[1]) +
           "], \"pairs\": " + std::to_string(b.pairs) + ", \"estimator\": \"" + metadetect_estimator_name(estimator) +
           "\", \"m1\": " + number(b.m1) + ", \"m1_err\": " + number(b.m1_err) +
           ", \"c2\": " + number(b.c2) + ", \"c2_err\": " + number(b.c2_err) + ", \"m2\": " + number(b.m2) +
           ", \"m2_err\": " + number(b.m2_err) + ", \"c1\": " + number(b.c1) + ", \"c1_err\": " + number(b.c1_err);
  }
  out += "}\n";
  if (!json.empty()) tools::write_json(json, out);
  return 0;
}
