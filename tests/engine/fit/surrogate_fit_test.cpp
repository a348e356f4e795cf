// The exact renderer's surrogate (Renderer::surrogate): a fit that iterates on it first and then
// exactly reaches the exact fit's optimum, status and errors. Noise-free GalSim cases to 1e-6 in e;
// simulated S/N 20 stamps to 1 % of the fit's own error; and the exact stage is short.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "engine/fit/fitter.hpp"
#include "engine/render/exact_renderer.hpp"
#include "engine/render/renderer_factory.hpp"
#include "engine/sim/great08_sim.hpp"
#include "support/reference_data.hpp"

namespace stampede {
namespace {

double max_de(const FitResult& a, const FitResult& b) {
  return std::max(std::abs(a.params[index(Param::kE1)] - b.params[index(Param::kE1)]),
                  std::abs(a.params[index(Param::kE2)] - b.params[index(Param::kE2)]));
}

TEST(SurrogateFit, TheExactRendererHasOneAndTheUpsampledNone) {
  FftPlanCache plans(FftPlanning::kEstimate);
  RenderOptions ro;
  PsfModel psf;
  psf.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  std::string err;
  auto exact = make_renderer(RendererKind::kExact, ro, ModelOptions{}, plans);
  exact->set_psf(exact->prepare_psf(psf, &err));
  ASSERT_NE(exact->surrogate(), nullptr);
  EXPECT_EQ(static_cast<ExactRenderer*>(exact->surrogate())->period(), exact_surrogate_period(ro.stamp_size));
  EXPECT_LT(static_cast<ExactRenderer*>(exact->surrogate())->period(), static_cast<ExactRenderer&>(*exact).period());
  ro.exact.surrogate = false;
  auto off = make_renderer(RendererKind::kExact, ro, ModelOptions{}, plans);
  off->set_psf(off->prepare_psf(psf, &err));
  EXPECT_EQ(off->surrogate(), nullptr);
  auto upsampled = make_renderer(RendererKind::kUpsampled, ro, ModelOptions{}, plans);
  upsampled->set_psf(upsampled->prepare_psf(psf, &err));
  EXPECT_EQ(upsampled->surrogate(), nullptr);
}

TEST(SurrogateFit, NoiseFreeGalSimCasesGiveTheExactFitsEllipticity) {
  const auto cases = testing::load_render_cases();
  FftPlanCache plans(FftPlanning::kEstimate);
  double worst = 0;
  int exact_iterations[2] = {0, 0};
  for (const auto& c : cases) {
    FitterOptions fo;
    fo.renderer = RendererKind::kExact;
    fo.render.stamp_size = c.stamp;
    FitResult r[2];
    for (bool surrogate : {false, true}) {
      fo.render.exact.surrogate = surrogate;
      std::string err;
      auto psf = make_renderer(fo.renderer, fo.render, fo.model, plans)->prepare_psf(testing::case_psf(c), &err);
      ASSERT_TRUE(psf) << err;
      Fitter fitter(fo, psf, plans);
      r[surrogate] = fitter.fit(c.image);
      exact_iterations[surrogate] += r[surrogate].iterations;
    }
    ASSERT_EQ(r[1].status, r[0].status) << "case " << c.id;
    EXPECT_GT(r[1].surrogate_iterations, 0) << "case " << c.id;
    worst = std::max(worst, max_de(r[0], r[1]));
    EXPECT_NEAR(r[1].flux, r[0].flux, 1e-6 * std::abs(r[0].flux)) << "case " << c.id;
  }
  std::printf("22 noise-free GalSim cases: worst |e_surrogate - e_exact| = %.2e; exact iterations %d with the "
              "surrogate, %d without\n", worst, exact_iterations[1], exact_iterations[0]);
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(exact_iterations[1], exact_iterations[0]);
}

TEST(SurrogateFit, Snr20StampsGiveTheExactFitToAPercentOfItsError) {
  Great08SimOptions o;
  o.sets = 1;
  o.grid = 6;
  o.snr = 20;
  o.seed = 2029;
  const SimSet set = Great08Simulator(o).simulate_set(0);
  const int s = o.stamp_size;
  FftPlanCache plans(FftPlanning::kEstimate);
  FitterOptions fo;
  fo.renderer = RendererKind::kExact;
  fo.render.stamp_size = s;
  fo.noise_sigma = o.noise_sigma;
  std::unique_ptr<Fitter> fitters[2];
  for (bool surrogate : {false, true}) {
    fo.render.exact.surrogate = surrogate;
    std::string err;
    auto psf = make_renderer(fo.renderer, fo.render, fo.model, plans)->prepare_psf(o.psf, &err);
    ASSERT_TRUE(psf) << err;
    fitters[surrogate] = std::make_unique<Fitter>(fo, psf, plans);
  }
  std::vector<double> stamp(static_cast<std::size_t>(s) * s);
  double worst = 0;
  int one_jacobian = 0, n = 0;
  for (int iy = 0; iy < o.grid; ++iy)
    for (int ix = 0; ix < o.grid; ++ix, ++n) {
      for (int y = 0; y < s; ++y)
        for (int x = 0; x < s; ++x)
          stamp[y * s + x] = set.image[static_cast<std::size_t>(iy * s + y) * set.width + ix * s + x];
      const FitResult exact = fitters[0]->fit(stamp), fast = fitters[1]->fit(stamp);
      ASSERT_EQ(fast.status, exact.status) << "object " << n;
      if (!IsUsable(exact.status)) continue;
      worst = std::max(worst, max_de(exact, fast) / std::min(exact.e1_err, exact.e2_err));
      EXPECT_NEAR(fast.e1_err, exact.e1_err, 1e-2 * exact.e1_err) << "object " << n;
      // The same optimum: chi2 to 1e-6 of itself, far below the unit change of a 1-sigma step.
      EXPECT_NEAR(fast.chi2, exact.chi2, 1e-6 * exact.chi2) << "object " << n;
      one_jacobian += fast.iterations == 1;
    }
  std::printf("%d S/N 20 stamps: worst |e_surrogate - e_exact| / sigma_e = %.2e; %d finished on one exact Jacobian\n",
              n, worst, one_jacobian);
  EXPECT_LT(worst, 1e-2);
  EXPECT_GT(one_jacobian, n / 2);
}

}  // namespace
}  // namespace stampede
