// `stampede demo`; see demo_command.hpp.
#include "tools/arguments.hpp"
#include "tools/demo_command.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "engine/fit/fitter.hpp"
#include "engine/render/psf_kernel.hpp"
#include "io/fits_file.hpp"
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
      throw std::invalid_argument("unknown option '" + a + "' (see stampede demo --help)");
    }
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);

  const std::string image_path = dir + "/set_" + std::to_string(set) + ".fits";
  const std::string truth_path = dir + "/truth_" + std::to_string(set) + ".fits";
  io::StampGridReader grid(image_path);
  io::FitsFile& header = grid.file();
  FitterOptions options;
  options.render.stamp_size = grid.stamp_size();
  options.noise_sigma = header.key_double("NOISESIG");
  PsfModel psf;
  psf.moffat = {header.key_double("PSFBETA"), header.key_double("PSFFWHM"), header.key_double("PSFE1"),
                header.key_double("PSFE2"), header.read_key_double("PSFTRUNC").value_or(0.0)};
  io::FitsFile truth = io::FitsFile::open_read(truth_path);
  truth.move_to("TRUTH");
  const std::vector<double> e1_true = truth.read_column("e1_obs"), e2_true = truth.read_column("e2_obs");

  const int n = grid.grid_nx() * grid.grid_ny();
  const std::size_t npix = static_cast<std::size_t>(grid.stamp_size()) * grid.stamp_size();
  if (static_cast<int>(e1_true.size()) != n)
    throw std::runtime_error(truth.describe() + ": " + std::to_string(e1_true.size()) + " truth rows for " +
                             std::to_string(n) + " stamps");
  std::vector<double> stamps(static_cast<std::size_t>(n) * npix);
  for (int iy = 0; iy < grid.grid_ny(); ++iy)
    grid.read_stamp_row(iy, std::span<double>(stamps).subspan(static_cast<std::size_t>(iy) * grid.grid_nx() * npix));

  std::printf("stampede demo: %d stamps of %d x %d from %s\n", n, grid.stamp_size(), grid.stamp_size(), image_path.c_str());
  std::printf("PSF: Moffat beta %.2f FWHM %.2f e (%.3f, %.3f); noise sigma %g\n", psf.moffat.beta, psf.moffat.fwhm,
              psf.moffat.e1, psf.moffat.e2, options.noise_sigma);
  const auto t0 = std::chrono::steady_clock::now();
  FftPlanCache setup_plans;
  std::string error;
  auto kernel = PsfKernel::build(psf, GridGeometry(options.render), setup_plans, &error);
  if (!kernel) throw std::runtime_error("PSF: " + error);
  struct Worker {
    FftPlanCache plans;
    std::unique_ptr<Fitter> fitter;
  };
  tbb::enumerable_thread_specific<Worker> workers;
  std::vector<FitResult> results(n);
  tbb::parallel_for(0, n, [&](int i) {
    Worker& w = workers.local();
    if (!w.fitter) w.fitter = std::make_unique<Fitter>(options, kernel, w.plans);
    results[i] = w.fitter->fit(std::span<const double>(stamps).subspan(static_cast<std::size_t>(i) * npix, npix));
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::printf("\n%6s %9s %9s %9s %9s %9s %9s  %s\n", "object", "e1_true", "e1_fit", "e2_true", "e2_fit", "de1", "de2",
              "status");
  double s1 = 0, s2 = 0, q1 = 0, q2 = 0;
  int used = 0;
  std::map<std::string, int> counts;
  for (int i = 0; i < n; ++i) {
    const FitResult& r = results[i];
    const double e1 = r.params[index(Param::kE1)], e2 = r.params[index(Param::kE2)];
    ++counts[ToString(r.status)];
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
  for (const auto& [name, count] : counts) std::printf(" %s=%d", name.c_str(), count);
  if (used > 0)
    std::printf("\nmean(e_fit - e_true) = (%+.2e, %+.2e), rms = (%.2e, %.2e) over %d usable fits\n", s1 / used, s2 / used,
                std::sqrt(q1 / used), std::sqrt(q2 / used), used);
  return 0;
}
