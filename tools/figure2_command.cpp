// `stampede figure2`; see figure2_command.hpp.
#include "tools/figure2_command.hpp"

#include <tbb/parallel_for.h>

#include <cstdio>
#include <string>
#include <vector>

#include "engine/ring_test.hpp"

int run_figure2_command(int argc, char** argv) {
  using namespace stampede;
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
      std::printf(
          "usage: stampede figure2\n\n"
          "Noise-free ring tests (4 angles, |e| = 0.3, shear +-(0.02, 0.01)) of pure de Vaucouleurs bulges\n"
          "and pure exponential discs at Rgp/Rp = 1.14 and 1.4, Moffat beta 3.5 FWHM 2.85, stamp 25,\n"
          "truth drawn at U1 = N_u = U2 = 25 with padding; fitted with the default bulge + disc model at\n"
          "U1 in {1,3,5,7}, N_u in {1,3,5,7}, U2 = 7. Prints m1 and m2 (im3shape paper, figure 2).\n");
      return 0;
    }
    throw std::invalid_argument(std::string("unknown option '") + argv[i] + "' (see stampede figure2 --help)");
  }
  PsfOptions psf;
  psf.moffat = {3.5, 2.85, 0.0, 0.0, 0.0};
  struct Row {
    double bulge_fraction, size;
    int u1, nu;
    RingTestResult r;
  };
  std::vector<Row> rows;
  for (double bf : {1.0, 0.0})
    for (double size : {1.14, 1.4})
      for (int nu : {1, 3, 5, 7})
        for (int u1 : {1, 3, 5, 7}) rows.push_back({bf, size, u1, nu, {}});
  FftPlanCache calib(FftPlanning::kEstimate);
  const double hlr[2][2] = {{half_light_radius_for_size_ratio(1.0, 1.14, psf, calib), half_light_radius_for_size_ratio(1.0, 1.4, psf, calib)},
                            {half_light_radius_for_size_ratio(4.0, 1.14, psf, calib), half_light_radius_for_size_ratio(4.0, 1.4, psf, calib)}};
  tbb::parallel_for(std::size_t(0), rows.size(), [&](std::size_t i) {
    Row& row = rows[i];
    FftPlanCache plans(FftPlanning::kEstimate);
    RingTestConfig cfg;
    cfg.psf = psf;
    cfg.bulge_fraction = row.bulge_fraction;
    cfg.half_light_radius = hlr[row.bulge_fraction > 0][row.size > 1.2];
    cfg.fit.render.stamp_size = 25;
    cfg.fit.render.upsampling = row.u1;
    cfg.fit.render.n_central_pixels_to_upsample = row.nu;
    cfg.fit.render.n_central_pixel_upsampling = 7;
    row.r = run_ring_test(cfg, plans);
  });
  std::printf("| galaxy | Rgp/Rp | r_e (px) | N_u | U1 | m1 | m2 | failed fits |\n|---|---|---|---|---|---|---|---|\n");
  for (const Row& row : rows)
    std::printf("| %s | %.2f | %.3f | %d | %d | %+.2e | %+.2e | %d/%d |\n", row.bulge_fraction > 0 ? "bulge" : "disc", row.size,
                hlr[row.bulge_fraction > 0][row.size > 1.2], row.nu, row.u1, row.r.m1, row.r.m2, row.r.failed, row.r.fits);
  return 0;
}
