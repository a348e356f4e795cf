// `stampede fit`; see fit_command.hpp.
#include "tools/arguments.hpp"
#include "tools/fit_command.hpp"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/fit_run.hpp"
#include "app/run_config.hpp"
#include "tools/progress_printer.hpp"

namespace {

using namespace stampede;

constexpr const char* kUsage =
    "usage: stampede fit INPUT.fits -o OUT.fits [--config run.ini] [--set key=value ...]\n"
    "                    [--threads N] [--catalog CAT] [--weight W.fits] [--text OUT.txt]\n"
    "                    [--shard I/N] [--resume] [--overwrite] [--quiet]\n"
    "       stampede fit --meds TILE.fits[.fz] -o OUT.fits [options]\n"
    "       stampede fit --meds G.fits --meds R.fits ... [--bands g,r,...] -o OUT.fits [options]\n"
    "       stampede fit --input-list LIST -o DIR [options]\n";

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
      "  --threads N   worker threads, 1..4096 or 0 = all cores (the default); results are identical for any N\n"
      "  --catalog C   catalogue (FITS table or text 'id x y', FITS 1-based pixels) of objects to cut\n"
      "                from INPUT; stamps reaching past the image edge are fitted with the outside\n"
      "                masked and flagged (flag bit 65536)\n"
      "  --weight W    inverse-variance image of INPUT's shape (0 masks a pixel); else noise_sigma\n"
      "  --text T      also write the table as whitespace text\n"
      "  --shard I/N   fit only shard I of N (0 <= I < N), a contiguous 1/N of the objects with their\n"
      "                whole-input ids, for job arrays; `stampede merge` joins the N tables into the\n"
      "                one table a single run writes\n"
      "  --meds TILE   a MEDS tile (survey input): each object fitted jointly on its single-epoch\n"
      "                cutouts (meds_fit_coadd: the coadd alone), each with its source image's PSFEx\n"
      "                model (image_info psf_path, relative to meds_psf_dir), WCS Jacobian, weights,\n"
      "                bmask bits (meds_bmask_bits) and uberseg (meds_uberseg), fluxes scaled to\n"
      "                meds_magzp_ref; models meds_model = bd | bord. One row per object_data row, in\n"
      "                order: id number ra dec, e1 e2 in (u, v), radius arcsec, n_epochs,\n"
      "                masked_frac, psf_size, is_bulge, other_likelihood (bord's loser), flags\n"
      "                (no usable epoch 524288, too masked 1048576, PSF failure 131072 when no\n"
      "                cutout is left, bad zero point 2097152, a band left out 4194304, a cutout\n"
      "                dropped for its PSF 8388608). renderer = exact is implied\n"
      "  --meds ... --bands B1,B2,...  one tile per band of the same objects (ids in the same\n"
      "                order at the same ra, dec within 1 arcsec, else refused; names apart in more\n"
      "                than case; not the same tile twice), in the order of --bands (default b0, b1,\n"
      "                ...; at most 8): one shape fitted to every band's cutouts, a bulge and a disc\n"
      "                amplitude per band; adds n_epochs_B flux_B bulge_flux_B disc_flux_B snr_B per\n"
      "                band (flux, bulge_flux, disc_flux: summed over bands; snr: all bands). A band\n"
      "                whose cutouts are all unusable is left out (n_epochs_B = 0, flag 4194304).\n"
      "                One tile with --bands gives its single-tile rows plus its band's columns\n"
      "  --input-list L  fit every grid named in L (one path per line, # comments), each to\n"
      "                DIR/<name>_fit.fits, -o naming the directory (created if missing); with\n"
      "                --resume, complete outputs are skipped and interrupted ones resumed\n"
      "  --resume      continue an interrupted run (same input and options) from its last batch; an\n"
      "                output this run already completed is left as it is (exit 0)\n"
      "  --overwrite   replace existing outputs (default: refuse); an output is never an input\n"
      "  --quiet       no progress or summary on stderr\n"
      "  --help-config print every option with its default as an ini file\n"
      "\n"
      "The PSF comes from the options (psf_input and the psf_* or airy_* keys). A grid whose header\n"
      "records its PSF (PSFTYPE PSFBETA PSFFWHM PSFE1 PSFE2 PSFTRUNC, or PSFLOD PSFOBSC, as GREAT08-like\n"
      "sets do) is fitted with that PSF when the run sets none of those options, else checked against\n"
      "the run's (a warning names each key that differs).\n",
      kUsage);
}

}  // namespace

int parse_fit_arguments(int argc, char** argv, FitCommandLine* command, bool messages) {
  app::FitRunOptions& r = command->run;
  std::string config;
  std::vector<std::string> sets;
  bool bands_given = false;
  std::string bands_text;
  std::set<std::string> given_once;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    // An option that takes one value, given twice: the last would silently win over the first.
    if (s == "-o" || s == "--output" || s == "--config" || s == "--threads" || s == "--catalog" || s == "--weight" ||
        s == "--text" || s == "--shard" || s == "--input-list") {
      const std::string name = s == "--output" ? "-o" : s;
      if (!given_once.insert(name).second)
        throw std::invalid_argument(name + " is given twice: give it once (see stampede fit --help)");
    }
    if (s == "--help" || s == "-h") {
      if (messages) print_help();
      return 0;
    } else if (s == "--help-config") {
      if (messages) std::fputs(app::ini_template().c_str(), stdout);
      return 0;
    } else if (s == "-o" || s == "--output") {
      r.output = value();
    } else if (s == "--config") {
      config = value();
    } else if (s == "--set") {
      sets.push_back(value());
    } else if (s == "--threads") {
      r.threads = static_cast<int>(tools::integer_in(argc, argv, &i, 0, app::kMaxThreads));
    } else if (s == "--catalog") {
      r.catalog = value();
    } else if (s == "--weight") {
      r.weight = value();
    } else if (s == "--text") {
      r.text_output = value();
    } else if (s == "--shard") {
      const std::string v = value();
      const auto shard = app::parse_shard(v);
      if (!shard) throw std::invalid_argument("--shard " + tools::quoted_value(v) + ": must be I/N with 0 <= I < N <= 1000000");
      r.shard = shard->first;
      r.shards = shard->second;
    } else if (s == "--meds") {
      r.meds.push_back(value());
    } else if (s == "--bands") {
      const std::string v = value();
      // Given twice, the last would silently win over the first: say so instead.
      if (bands_given)
        throw std::invalid_argument("--bands " + tools::quoted_value(v) + ": --bands is given twice (first " +
                                    tools::quoted_value(bands_text) + "); give the bands once, in the tiles' order");
      bands_given = true;
      bands_text = v;
      r.bands.clear();
      std::size_t begin = 0;
      while (true) {
        const std::size_t comma = v.find(',', begin);
        r.bands.push_back(v.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
        if (comma == std::string::npos) break;
        begin = comma + 1;
      }
    } else if (s == "--input-list") {
      command->input_list = value();
    } else if (s == "--resume") {
      r.resume = true;
    } else if (s == "--overwrite") {
      r.overwrite = true;
    } else if (s == "--quiet") {
      r.quiet = true;
    } else if (!s.empty() && s[0] == '-') {
      throw std::invalid_argument("unknown option " + tools::quoted_value(s) + " (see stampede fit --help)");
    } else if (r.input.empty()) {
      r.input = s;
    } else {
      throw std::invalid_argument("unexpected argument " + tools::quoted_value(s) + " (one INPUT only)");
    }
  }
  if (!command->input_list.empty()) {
    if (!r.input.empty())
      throw std::invalid_argument("--input-list " + tools::quoted_value(command->input_list) + " and INPUT " +
                                  tools::quoted_value(r.input) + ": give one");
    if (!r.catalog.empty() || !r.weight.empty() || !r.text_output.empty() || r.shards > 1)
      throw std::invalid_argument("--input-list takes grids of stamps only (no --catalog, --weight, --text or --shard)");
  }
  if (!r.meds.empty()) {
    if (!r.input.empty())
      throw std::invalid_argument("--meds " + tools::quoted_value(r.meds[0]) + " and INPUT " + tools::quoted_value(r.input) +
                                  ": give one");
    if (!command->input_list.empty() || !r.catalog.empty() || !r.weight.empty())
      throw std::invalid_argument("--meds takes no --input-list, --catalog or --weight (the tile holds the cutouts and weights)");
  }
  if (!r.bands.empty() && r.meds.empty()) throw std::invalid_argument("--bands names the bands of --meds tiles: give them");
  if ((r.input.empty() && r.meds.empty() && command->input_list.empty()) || r.output.empty()) {
    if (messages) std::fputs(kUsage, stderr);
    return 2;
  }

  if (!config.empty()) app::load_ini(r.config, config);
  for (const auto& s : sets) app::apply_set(r.config, s);
  return -1;
}

namespace {

// One input, with progress and the summary on stderr (unless --quiet); the exit code.
int run_fit_with_reports(app::FitRunOptions& r) {
  tools::ProgressPrinter printer(stderr, isatty(fileno(stderr)));
  if (!r.quiet) r.on_progress = [&](const app::RunProgress& p) { printer.update(p.seconds, p.Line()); };
  r.on_warning = [](const std::string& w) { std::fprintf(stderr, "stampede fit: warning: %s\n", w.c_str()); };
  const app::RunSummary summary = app::FitRun(r).run();
  printer.finish();
  if (summary.skipped) {
    if (!r.quiet) std::fprintf(stderr, "stampede fit: %s is complete, skipped\n", r.output.c_str());
    return 0;
  }
  if (!r.quiet) std::fprintf(stderr, "%s\n", summary.BriefReport().c_str());
  // A table of nothing but failures is a run that did not work (a wrong meds_psf_dir, a PSF no
  // object can use): said even with --quiet, and an exit status a job script sees.
  long long usable = 0;
  for (int k = 0; k < kFitStatusCount; ++k)
    if (IsUsable(static_cast<FitStatus>(k))) usable += summary.by_status[static_cast<std::size_t>(k)];
  if (summary.objects > 0 && usable == 0) {
    std::fprintf(stderr, "stampede fit: error: none of the %lld objects could be fitted (status: %s); the table "
                 "holds their flagged rows\n", summary.objects, summary.StatusCounts().c_str());
    return 3;
  }
  return 0;
}

}  // namespace

std::vector<app::ListedInput> listed_inputs(const FitCommandLine& command) {
  if (command.input_list.empty()) return {};
  const std::string& dir = command.run.output;
  if (std::filesystem::exists(dir) && !std::filesystem::is_directory(dir))
    throw std::invalid_argument("--input-list writes a table per input into the directory -o names; '" + dir +
                                "' is a file");
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) throw std::invalid_argument("-o '" + dir + "': cannot create the directory: " + error.message());
  return app::read_input_list(command.input_list, command.run.output);
}

int run_listed_input(const FitCommandLine& command, const app::ListedInput& input) {
  app::FitRunOptions r = command.run;
  r.input = input.input;
  r.output = input.output;
  // A complete output is skipped only when it is this run's (the run checks its RUNFP); one not
  // started yet is fitted afresh.
  if (r.resume && !std::filesystem::exists(input.output) && !std::filesystem::exists(input.output + ".checkpoint"))
    r.resume = false;
  return run_fit_with_reports(r);
}

int run_fit_command_line(FitCommandLine& command) {
  // --resume of an output that is already complete: this run's table is left as it is (exit 0),
  // another run's is refused (app/run_harness).
  if (command.input_list.empty()) return run_fit_with_reports(command.run);
  for (const app::ListedInput& input : listed_inputs(command))
    if (const int code = run_listed_input(command, input); code != 0) return code;
  return 0;
}

int run_fit_command(int argc, char** argv) {
  FitCommandLine command;
  if (const int exit_code = parse_fit_arguments(argc, argv, &command); exit_code >= 0) return exit_code;
  return run_fit_command_line(command);
}
