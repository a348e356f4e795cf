// `stampede metadetect IMAGE.fits ... -o OUT.fits`; see print_help.
#include "tools/metadetect_command.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "app/fit_run.hpp"
#include "app/metadetect_option_keys.hpp"
#include "app/metadetect_run.hpp"
#include "io/config_error.hpp"
#include "tools/arguments.hpp"
#include "tools/progress_printer.hpp"

namespace {

using namespace stampede;

// The table's options as help lines: "  --flag METAVAR" padded to 29 columns, the help's lines
// after it, the default's recorded text for its "%s".
std::string option_lines(const MetadetectOptions& d) {
  std::string out;
  for (const app::MetadetectOptionKey& k : app::metadetect_option_keys()) {
    if (k.flag.empty()) continue;
    std::string head = "  " + k.flag + (k.metavar.empty() ? "" : " " + k.metavar);
    head.resize(std::max<std::size_t>(head.size() + 1, 29), ' ');
    std::string help = k.help;
    if (const std::size_t at = help.find("%s"); at != std::string::npos) help.replace(at, 2, k.recorded(d));
    for (std::size_t begin = 0; begin < help.size();) {
      const std::size_t end = std::min(help.find('\n', begin), help.size());
      out += (begin == 0 ? head : std::string(29, ' ')) + help.substr(begin, end - begin) + "\n";
      begin = end + 1;
    }
  }
  return out;
}

void print_help() {
  const MetadetectOptions d;
  std::printf(
      "usage: stampede metadetect IMAGE.fits [IMAGE.fits ...] -o OUT.fits [options]\n"
      "       stampede metadetect --input-list LIST -o OUT.fits [options]\n"
      "       stampede metadetect SCENE_{band}.fits ... --bands g,r,... -o OUT.fits [options]\n"
      "       stampede metadetect --meds CELLS_MEDS.fits -o OUT.fits [options]\n"
      "       stampede metadetect --meds G.fits --meds R.fits ... [--bands g,r,...] -o OUT.fits [options]\n"
      "\n"
      "Metadetection (Sheldon et al. 2020, 2023): each cell's five metacal images (noshear, 1p, 1m,\n"
      "2p, 2m, with fixnoise) are made, objects are detected anew on each (Source Extractor's\n"
      "algorithm), and each detection is measured on the image it was found on (--measurement):\n"
      "weighted moments under a round Gaussian weight (wmom), pre-PSF Gaussian moments (pgauss) or a\n"
      "model fit (exp, bd). An image larger than a cell is cut into cells overlapping by twice the\n"
      "buffer; a detection is kept by the one cell whose inner region holds it. `stampede metrics\n"
      "--metadetect` turns the table into a response and a shear.\n"
      "\n"
      "input: IMAGE.fits holds the image in HDU 0 with its pixel scale (keyword SCALE, arcsec/px, or\n"
      "a WCS), and extensions WEIGHT (inverse variance, required), BMASK (optional, non-zero masks),\n"
      "ORMASK (optional, bits reported per detection) and\n"
      "PSF (a centred PSF image at the image's pixel scale, required unless --psfex). `stampede sim\n"
      "cells` writes such files. LIST: one image path per line (# comments). --meds: a cell tile (DES\n"
      "Y6's \"pizza slices\": a MEDS file whose object_data rows are cells, cutout 0 each cell's coadd\n"
      "with weight, bmask and psf cutouts; `sim cells --tile` writes one); x, y are then the tile's\n"
      "pixels. A NOISE HDU or noise cutouts (a realisation of the image's noise) are fixnoise's field;\n"
      "without, one is drawn from the weight.\n"
      "\n"
      "several bands: --meds once per band, the tiles holding the same cells (same rows, boxes and\n"
      "places), --bands naming them in that order (default b0, b1, ...; at most 8, distinct in more\n"
      "than case). Or image files: --bands names the bands and each image path (and --input-list\n"
      "line, and --psfex) is a template whose {band} is the band's name: scene_{band}.fits --bands g,r\n"
      "reads scene_g.fits and scene_r.fits, a scene's bands of one size and pixel scale, each with its\n"
      "own WEIGHT, BMASK, NOISE and PSF (`sim cells --bands g,r` writes DIR/{band}/cell_KKKK.fits).\n"
      "Each band's metacal images (one reconvolution PSF for all), detection on their sum weighted by\n"
      "each band's inverse noise variance, the measurement over every band's stamp together (weighted\n"
      "by the same), and columns flux_B snr_B per band (its stamp alone under the same weight).\n"
      "Band roles (DES Y6: --detect-bands r,i,z --shear-bands r,i,z): detection on the named bands'\n"
      "sum, the shape from the named bands' stamps (their own reconvolution PSF, the widest they\n"
      "need; the other bands' the widest every band needs); flux_B snr_B still for every band.\n"
      "\n"
      "output: OUT.fits, table METADETECT, a row per (cell, shear type, detection): cell shear_type id\n"
      "x y (0-based pixels of the input image) u v (arcsec) e1 e2 e1_err e2_err T (arcsec^2) T_ratio\n"
      "psf_T flux snr mfrac box_size isophotal_area sep_flags flags psf_orig_e1 psf_orig_e2 psf_orig_T\n"
      "psf_rec_e1 psf_rec_e2 x_noshear y_noshear bmask ormask; a cell that cannot be measured is\n"
      "one row with id -1 and flags 8. The options and the inputs' digests are in the header; each\n"
      "image once (the same bytes twice are refused). Written through OUT.fits.partial and a\n"
      "checkpoint: a killed run continues with --resume. Exit status 3: no cell could be measured.\n"
      "\n"
      "options:\n"
      "  -o, --output PATH          output table (required)\n"
      "  --package-output PATH      also, once the table is complete, its rows in the reference metadetect\n"
      "                             package's layout: an HDU per shear type (noshear 1p 1m 2p 2m), its\n"
      "                             column names ({m}_g, {m}_g_cov, {m}_s2n, {m}_T_ratio, sx_row, mfrac,\n"
      "                             bmask, psfrec_g, ...; docs/survey_metadetect.md)\n"
      "  --input-list LIST          read the image paths from LIST (after any given as arguments)\n"
      "  --bands B1,B2,...          the bands' names (see above)\n"
      "  --detect-bands B1,...      detect on these bands only (default: every band)\n"
      "  --shear-bands B1,...       shapes (e, T, flux, snr) from these bands only (default: every band)\n"
      "  --geometry G               survey cells: des-y6 (DES Y6's pizza slices, 200 px with 50 px\n"
      "                             buffers, at 0.263\"/px) or rubin (Rubin's cell coadds: 150 px\n"
      "                             inner cells with 50 px borders, 250 px, at 0.2\"/px); sets\n"
      "                             --cell-size and --cell-buffer\n"
      "  --star-mask STARS.fits     bright stars to mask: a table with x, y (FITS 1-based pixels of the\n"
      "                             inputs) and radius (pixels), or ra, dec (degrees) and radius_arcsec\n"
      "                             placed by each image's TAN WCS; their pixels are filled as masked ones,\n"
      "                             and no detection inside is kept (recorded: STARCAT, STARCATD)\n"
      "  --star-mask-hdu NAME       image files: each file's own star table, its HDU NAME (`sim cells\n"
      "                             --stars` writes STARS)\n"
      "  --star-margin PX           widen every star's radius by PX pixels (0)\n"
      "  --psfex MODEL.psf          image files: each cell's PSF is this PSFEx model at the cell's centre\n"
      "                             (X_IMAGE, Y_IMAGE of the image's pixels), not the PSF HDU (which may\n"
      "                             be absent); one model for every image; PSF_SAMP 1/integer\n"
      "%s"
      "  --threads N                worker threads (default: all cores)\n"
      "  --shard I/N                only shard I of N (0 <= I < N): a contiguous 1/N of the cells,\n"
      "                             numbered as in the whole run; `stampede merge` joins the shards\n"
      "  --resume                   continue an interrupted run of the same inputs and options\n"
      "  --overwrite                replace an existing OUT.fits\n"
      "  --quiet                    no progress line\n",
      option_lines(d).c_str());
}

std::vector<std::string> read_list(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("option --input-list: cannot read " + tools::quoted_value(path));
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) {
    const std::size_t a = line.find_first_not_of(" \t\r");
    if (a == std::string::npos || line[a] == '#') continue;
    const std::size_t b = line.find_last_not_of(" \t\r");
    out.push_back(line.substr(a, b - a + 1));
  }
  if (out.empty()) throw std::invalid_argument("option --input-list: " + tools::quoted_value(path) + " lists no image");
  return out;
}

}  // namespace

namespace {

// The table's option whose flag is `flag`; null for another argument.
const stampede::app::MetadetectOptionKey* option_key(const std::string& flag) {
  for (const stampede::app::MetadetectOptionKey& k : stampede::app::metadetect_option_keys())
    if (!k.flag.empty() && k.flag == flag) return &k;
  return nullptr;
}

}  // namespace

int parse_metadetect_arguments(int argc, char** argv, MetadetectCommandLine* command, bool print) {
  using namespace stampede;
  app::MetadetectRunOptions& o = command->run;
  MetadetectOptions& m = o.metadetect;
  bool& quiet = command->quiet;
  std::set<std::string> seen;  // one-value options given twice are refused
  std::vector<std::string> meds;  // --meds tiles, a band each
  std::optional<std::pair<int, int>> geometry;  // --geometry: cell side and buffer
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    auto integer = [&](long long lo, long long hi) { return static_cast<int>(tools::integer_in(argc, argv, &i, lo, hi)); };
    if (s.starts_with("-") && s != "--help" && s != "-h" && s != "--meds" && !seen.insert(s == "-o" ? "--output" : s).second)
      throw std::invalid_argument("option " + s + " is given twice");
    if (s == "--help" || s == "-h") {
      if (print) print_help();
      return 0;
    } else if (s == "-o" || s == "--output") {
      o.output = value();
    } else if (s == "--meds") {
      meds.push_back(value());
      o.tile = true;
    } else if (s == "--bands" || s == "--detect-bands" || s == "--shear-bands") {
      const std::string v = value();
      std::vector<std::string>& names = s == "--bands" ? o.bands : s == "--detect-bands" ? o.detect_bands : o.shear_bands;
      names.clear();
      for (std::size_t begin = 0;;) {
        const std::size_t comma = v.find(',', begin);
        names.push_back(v.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
        if (comma == std::string::npos) break;
        begin = comma + 1;
      }
    } else if (s == "--psfex") {
      o.psfex = value();
    } else if (s == "--star-mask") {
      o.star_mask = value();
    } else if (s == "--package-output") {
      o.package_output = value();
    } else if (s == "--star-mask-hdu") {
      o.star_hdu = value();
    } else if (s == "--star-margin") {
      o.star_margin = tools::number_value(argc, argv, &i);
    } else if (s == "--input-list") {
      for (std::string& p : read_list(value())) o.inputs.push_back(std::move(p));
    } else if (const app::MetadetectOptionKey* k = option_key(s)) {
      const std::string v = k->kind == app::MetadetectOptionKey::Kind::kSwitch ? (k->switch_sets ? "true" : "false") : value();
      if (const std::string why = k->set(m, v); !why.empty())
        throw std::invalid_argument("option " + s + " " + tools::quoted_value(v) + ": " + why);
    } else if (s == "--threads") {
      o.threads = integer(1, 4096);
    } else if (s == "--shard") {
      const std::string v = value();
      const auto shard = app::parse_shard(v);
      if (!shard) throw std::invalid_argument("--shard " + tools::quoted_value(v) + ": must be I/N with 0 <= I < N <= 1000000");
      o.shard = shard->first, o.shards = shard->second;
    } else if (s == "--geometry") {
      const std::string v = value();
      if (v == "des-y6") geometry = {200, 50};
      else if (v == "rubin") geometry = {250, 50};
      else throw std::invalid_argument("option --geometry " + tools::quoted_value(v) + ": must be des-y6 or rubin");
    } else if (s == "--resume") {
      o.resume = true;
    } else if (s == "--overwrite") {
      o.overwrite = true;
    } else if (s == "--quiet") {
      quiet = true;
    } else if (s.starts_with("-")) {
      throw std::invalid_argument("unknown option " + tools::quoted_value(s) + " (see stampede metadetect --help)");
    } else {
      o.inputs.push_back(s);
    }
  }
  if (o.output.empty()) throw std::invalid_argument("-o OUT.fits is required (see stampede metadetect --help)");
  if (o.inputs.empty() && meds.empty()) throw std::invalid_argument("no input image (see stampede metadetect --help)");
  if (o.tile && !o.inputs.empty())
    throw std::invalid_argument("--meds takes cell tiles and no image files (see stampede metadetect --help)");
  if (o.tile) o.inputs = meds;
  if (o.resume && o.overwrite) throw std::invalid_argument("--resume and --overwrite exclude each other");
  if (geometry) {
    if ((seen.count("--cell-size") && m.cell_size != geometry->first) ||
        (seen.count("--cell-buffer") && m.cell_buffer != geometry->second))
      throw std::invalid_argument("--geometry sets --cell-size " + std::to_string(geometry->first) + " --cell-buffer " +
                                  std::to_string(geometry->second) + ": give one or the other");
    m.cell_size = geometry->first, m.cell_buffer = geometry->second;
  }
  // The options' rules, in the command line's words (the core names the fields).
  if (std::string why; !m.IsValid(&why)) throw std::invalid_argument(app::with_metadetect_flags(why));
  return -1;
}

namespace {

int run_and_report(const MetadetectCommandLine& command) {
  using namespace stampede;
  app::MetadetectRunOptions o = command.run;
  const bool quiet = command.quiet;
  tools::ProgressPrinter printer(stderr, isatty(STDERR_FILENO) != 0);
  o.on_warning = [](const std::string& text) { std::fprintf(stderr, "stampede metadetect: warning: %s\n", text.c_str()); };
  if (!quiet) o.on_progress = [&](const app::RunProgress& p) { printer.update(p.seconds, "stampede metadetect: " + p.Line()); };
  const app::MetadetectRunSummary r = app::run_metadetect(o);
  printer.finish();
  if (r.skipped) {
    if (!quiet) std::fprintf(stderr, "stampede metadetect: %s is complete, skipped\n", o.output.c_str());
    return 0;
  }
  for (const std::string& p : r.problems) std::fprintf(stderr, "stampede metadetect: warning: %s\n", p.c_str());
  if (r.cells_failed > static_cast<long long>(r.problems.size()))
    std::fprintf(stderr, "stampede metadetect: warning: %lld more cells failed\n",
                 r.cells_failed - static_cast<long long>(r.problems.size()));
  std::fprintf(stderr, "stampede metadetect: %lld cells (%lld resumed, %lld failed), %lld rows, %.2f s on %d threads%s -> %s\n",
               r.cells + r.cells_resumed, r.cells_resumed, r.cells_failed, r.rows, r.seconds, r.threads,
               r.stopped ? " (stopped)" : "", o.output.c_str());
  if (r.cells > 0 && r.cells_failed == r.cells) {  // the table holds only flagged rows: no measurement at all
    std::fprintf(stderr, "stampede metadetect: error: none of the %lld cells could be measured (the warnings above say "
                 "why); the table holds their flagged rows\n", r.cells);
    return 3;
  }
  return r.stopped ? 1 : 0;
}

}  // namespace

int run_metadetect_with_reports(const MetadetectCommandLine& command) {
  try {
    return run_and_report(command);
  } catch (const stampede::io::ConfigError& e) {  // the core names option fields: the command line's are flags
    throw stampede::io::ConfigError(stampede::app::with_metadetect_flags(e.what()));
  }
}

int run_metadetect_command(int argc, char** argv) {
  MetadetectCommandLine command;
  if (const int code = parse_metadetect_arguments(argc, argv, &command, true); code >= 0) return code;
  return run_metadetect_with_reports(command);
}
