// `stampede demo`; see demo_command.hpp.
#include "tools/arguments.hpp"
#include "tools/demo_command.hpp"

#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/fit_run.hpp"
#include "io/fits_file.hpp"
#include "io/psf_keys.hpp"
#include "io/stamp_grid.hpp"

namespace {

using namespace stampede;

void print_help() {
  std::printf(
      "usage: stampede demo [--data DIR] [--set K] [--rows N] [--threads N]\n"
      "\n"
      "Fits every stamp of DIR/set_K.fits (a GREAT08-layout grid; PSF from its header keys\n"
      "PSFBETA PSFFWHM PSFE1 PSFE2, noise from NOISESIG) with the default im3shape settings\n"
      "(upsampling 5, n_central_pixels_to_upsample 3, n_central_pixel_upsampling 7) and prints\n"
      "true (DIR/truth_K.fits, e1_obs e2_obs) against recovered ellipticities.\n"
      "\n"
      "  --data DIR    default: %s/galsim-great08-mini/nf\n"
      "  --set K       set index (default 0)\n"
      "  --rows N      table rows to print (default 12; all objects are fitted)\n"
      "  --threads N   worker threads (default: all cores)\n",
      STAMPEDE_DEFAULT_DATA_DIR);
}

}  // namespace

int run_demo_command(int argc, char** argv) {
  std::string dir = std::string(STAMPEDE_DEFAULT_DATA_DIR) + "/galsim-great08-mini/nf";
  int set = 0, rows = 12, threads = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto int_in = [&](long long lo, long long hi) { return static_cast<int>(tools::integer_in(argc, argv, &i, lo, hi)); };
    if (a == "--help" || a == "-h") {
      print_help();
      return 0;
    } else if (a == "--data") {
      dir = tools::option_value(argc, argv, &i);
    } else if (a == "--set") {
      set = int_in(0, 1000000);
    } else if (a == "--rows") {
      rows = int_in(0, 1000000);
    } else if (a == "--threads") {
      threads = int_in(1, 4096);
    } else {
      throw std::invalid_argument("unknown option " + tools::quoted_value(a) + " (see stampede demo --help)");
    }
  }
  const std::string image_path = dir + "/set_" + std::to_string(set) + ".fits";
  const std::string truth_path = dir + "/truth_" + std::to_string(set) + ".fits";
  // The fit is `stampede fit` of the set with its recorded PSF and noise, without an output file.
  app::FitRunOptions run;
  run.input = image_path;
  run.threads = threads;
  io::StampGridReader grid(image_path);
  io::FitsFile& header = grid.file();
  run.config.fitter.noise_sigma = header.key_double("NOISESIG");
  const PsfModel psf = io::read_psf_keys(header);
  run.config.psf_kind = psf.kind == PsfKind::kAiry ? PsfKind::kAiry : PsfKind::kMoffat;
  run.config.moffat = psf.moffat;
  run.config.airy = psf.airy;
  io::FitsFile truth = io::FitsFile::open_read(truth_path);
  truth.move_to("TRUTH");
  const std::vector<double> e1_true = truth.read_column("e1_obs"), e2_true = truth.read_column("e2_obs");

  const int n = grid.grid_nx() * grid.grid_ny();
  if (static_cast<int>(e1_true.size()) != n)
    throw std::runtime_error(truth.describe() + ": " + std::to_string(e1_true.size()) + " truth rows for " +
                             std::to_string(n) + " stamps");

  std::printf("stampede demo: %d stamps of %d x %d from %s\n", n, grid.stamp_size(), grid.stamp_size(), image_path.c_str());
  if (psf.kind == PsfKind::kAiry)
    std::printf("PSF: Airy lambda/D %.2f obscuration %.2f; noise sigma %g\n", psf.airy.lambda_over_d,
                psf.airy.obscuration, run.config.fitter.noise_sigma);
  else
    std::printf("PSF: Moffat beta %.2f FWHM %.2f e (%.3f, %.3f); noise sigma %g\n", psf.moffat.beta, psf.moffat.fwhm,
                psf.moffat.e1, psf.moffat.e2, run.config.fitter.noise_sigma);
  std::vector<FitResult> results(n);
  run.on_rows = [&](std::span<const ObjectRecord> rows) {  // grid ids are the stamp indices 0..n-1
    for (const ObjectRecord& r : rows) results[r.id] = r.fit;
  };
  run.on_warning = [](const std::string& w) { std::fprintf(stderr, "stampede demo: warning: %s\n", w.c_str()); };
  const app::RunSummary summary = app::FitRun(run).run();
  const double seconds = summary.total_seconds;

  std::printf("\n%6s %9s %9s %9s %9s %9s %9s  %s\n", "object", "e1_true", "e1_fit", "e2_true", "e2_fit", "de1", "de2",
              "status");
  double s1 = 0, s2 = 0, q1 = 0, q2 = 0;
  int used = 0;
  for (int i = 0; i < n; ++i) {
    const FitResult& r = results[i];
    const double e1 = r.params[index(Param::kE1)], e2 = r.params[index(Param::kE2)];
    if (i < rows)
      std::printf("%6d %9.5f %9.5f %9.5f %9.5f %+9.1e %+9.1e  %s\n", i, e1_true[i], e1, e2_true[i], e2, e1 - e1_true[i],
                  e2 - e2_true[i], ToString(r.status));
    if (!IsUsable(r.status)) continue;
    ++used;
    s1 += e1 - e1_true[i];
    s2 += e2 - e2_true[i];
    q1 += (e1 - e1_true[i]) * (e1 - e1_true[i]);
    q2 += (e2 - e2_true[i]) * (e2 - e2_true[i]);
  }
  if (rows < n) std::printf("%6s (%d more rows not shown)\n", "...", n - rows);
  std::printf("\nfitted %d objects in %.1f s (%.1f objects/s); status:", n, seconds, n / seconds);
  std::map<std::string, long long> counts;  // by name, as the demo always listed them
  for (int st = 0; st < kFitStatusCount; ++st)
    if (summary.by_status[st]) counts[ToString(static_cast<FitStatus>(st))] = summary.by_status[st];
  for (const auto& [name, count] : counts) std::printf(" %s=%lld", name.c_str(), count);
  if (used > 0)
    std::printf("\nmean(e_fit - e_true) = (%+.2e, %+.2e), rms = (%.2e, %.2e) over %d usable fits\n", s1 / used, s2 / used,
                std::sqrt(q1 / used), std::sqrt(q2 / used), used);
  return 0;
}
