// Tests for joint fits with the amplitudes projected out (engine/fit/projected_joint_problem): the
// projected gradient is the derivative of the projected chi2 (finite differences); J^T W J over
// every parameter, in the fitter's layout, has the projected matrix as its Schur complement; and
// the multi-epoch and multi-band fits reach the joint fit's optimum, errors and fluxes.
#include "engine/fit/projected_joint_problem.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "engine/fit/object_fitter.hpp"
#include "engine/render/exact_renderer.hpp"
#include "support/sky_epochs.hpp"

namespace stampede {
namespace {

using testing::kEpochBox;
using testing::SkyEpoch;
using testing::SkyGalaxy;

// Three bands of two noisy epochs each (random frames and PSFs, per-band bulge and disc fluxes).
struct ThreeBands {
  std::vector<std::vector<SkyEpoch>> epochs;
  explicit ThreeBands(std::uint32_t seed, double sigma = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::normal_distribution<double> noise(0, sigma);
    for (int b = 0; b < 3; ++b) {
      const SkyGalaxy g{0.25, -0.15, 0.6, 0.02, -0.01, 150.0 + 100 * b, 900.0 - 150 * b};
      std::vector<SkyEpoch> band(2);
      for (SkyEpoch& e : band) {
        e.frame = testing::random_frame(rng);
        e.psf = testing::moffat_psf(3.6 - 0.3 * b + 0.2 * u(rng), 0.05 * u(rng), 0.05 * u(rng));
        e.pixels = testing::draw(g, e.frame, e.psf);
        for (double& v : e.pixels) v += noise(rng);
        e.weight.assign(kEpochBox * kEpochBox, 1.0 / (sigma * sigma));
      }
      epochs.push_back(std::move(band));
    }
  }
  std::vector<Observation> data(Renderer& r) {
    std::vector<Observation> out;
    for (int b = 0; b < 3; ++b)
      for (const Observation& e : testing::epoch_data(r, epochs[static_cast<std::size_t>(b)], b)) out.push_back(e);
    return out;
  }
};

// The problem over ThreeBands' cutouts in ObjectFitter's layout: the five shape parameters,
// then each band's two amplitudes.
RenderOptions box_options() {
  RenderOptions o;
  o.stamp_size = kEpochBox;
  return o;
}

struct ThreeBandProblem {
  ExactRenderer renderer;
  ThreeBands bands;
  std::vector<Observation> data;
  std::array<Param, kNumParams> free_all{};
  std::span<const Param> free;
  std::vector<int> slot;
  ProjectedJointProblem problem;

  ThreeBandProblem()
      : renderer(box_options(), ModelOptions{}),
        bands(5),
        data(bands.data(renderer)),
        problem([this](int) -> Renderer& { return renderer; }, kernels::least_squares_kernels()) {
    free = std::span<const Param>(free_all.data(), static_cast<std::size_t>(ParameterSet{}.free_params(&free_all)));
    for (const Observation& e : data) slot.push_back(e.band);
    problem.reset(data, ParameterSet::default_values(), free, slot, 3,
                  [](std::size_t a, int s) { return a < 5 ? static_cast<int>(a) : 5 + 2 * s + static_cast<int>(a - 5); },
                  11);
  }
};

TEST(ProjectedJointProblem, TheGradientIsTheDerivativeOfTheProjectedChi2) {
  ThreeBandProblem s;
  ASSERT_EQ(s.problem.size(), 5);  // x0, y0, e1, e2, radius: the amplitudes are not the solver's
  LmVector x(5);
  x << 0.05, -0.04, 0.2, -0.1, 0.7;  // away from the optimum, so the gradient is not small
  double chi2 = 0;
  LmMatrix alpha;
  LmVector beta;
  ASSERT_TRUE(s.problem.normal_equations(x, &chi2, &alpha, &beta));
  double at_x = 0;
  ASSERT_TRUE(s.problem.chi2(x, &at_x));
  EXPECT_NEAR(at_x, chi2, 1e-9 * chi2);
  // d chi2 / dx_j = -2 J_p^T W r = -2 beta_j at the best amplitudes (the residual is W-orthogonal
  // to the amplitude columns, so the amplitudes' own change does not enter).
  for (int j = 0; j < 5; ++j) {
    const double h = 1e-5;
    LmVector up = x, down = x;
    up[j] += h, down[j] -= h;
    double cu = 0, cd = 0;
    ASSERT_TRUE(s.problem.chi2(up, &cu));
    ASSERT_TRUE(s.problem.chi2(down, &cd));
    const double numeric = (cu - cd) / (2 * h);
    std::printf("param %d: -2 beta %.9e, finite difference %.9e\n", j, -2 * beta[j], numeric);
    EXPECT_NEAR(-2 * beta[j], numeric, 1e-5 * std::abs(numeric) + 1e-6 * chi2);
  }
}

TEST(ProjectedJointProblem, TheFullMatrixHasTheProjectedOneAsItsSchurComplement) {
  ThreeBandProblem s;
  LmVector x(5);
  x << 0.01, -0.02, 0.22, -0.12, 0.62;
  double chi2 = 0;
  LmMatrix alpha;
  LmVector beta;
  ASSERT_TRUE(s.problem.normal_equations(x, &chi2, &alpha, &beta));
  LmVector full = x;
  LmMatrix all;
  ASSERT_TRUE(s.problem.expand(&full, &all));
  ASSERT_EQ(full.size(), 11);
  for (int j = 0; j < 5; ++j) EXPECT_EQ(full[j], x[j]);
  // The shape block of the full inverse is the projected matrix's inverse: each band's amplitudes
  // are marginalised exactly.
  const LmMatrix cov = all.inverse();
  const LmMatrix shape_cov = alpha.inverse();
  for (int j = 0; j < 5; ++j)
    for (int k = 0; k < 5; ++k) EXPECT_NEAR(cov(j, k), shape_cov(j, k), 1e-8 * std::sqrt(cov(j, j) * cov(k, k)));
  // Each band's amplitudes are its own: positive fluxes here.
  for (int b = 0; b < 3; ++b) {
    EXPECT_TRUE(std::isfinite(full[5 + 2 * b]) && std::isfinite(full[6 + 2 * b]));
    EXPECT_GT(full[5 + 2 * b] + full[6 + 2 * b], 0);
  }
}

// The same optimum as the joint fit's, both fitted to it (eps4 1e-12), with the same errors.
TEST(ProjectedJointProblem, MultiEpochAndMultiBandFitsReachTheJointFitsOptimum) {
  FitterOptions projected = testing::exact_fit_options(), joint = projected;
  projected.lm.eps4 = joint.lm.eps4 = 1e-12;
  joint.project_amplitudes = false;
  ASSERT_TRUE(projects_amplitudes(projected));
  ASSERT_FALSE(projects_amplitudes(joint));
  for (std::uint32_t seed : {11u, 12u, 13u}) {
    ThreeBands bands(seed);
    ObjectFitter p(projected), j(joint);
    const std::vector<Observation> dp = bands.data(p.renderer_for(kEpochBox)), dj = bands.data(j.renderer_for(kEpochBox));
    const MultiBandFitResult rp = testing::fit_bands(p, dp, 3), rj = testing::fit_bands(j, dj, 3);
    ASSERT_EQ(rp.fit.status, FitStatus::kOk);
    ASSERT_EQ(rj.fit.status, FitStatus::kOk);
    std::printf("seed %u bands: e (%.9f, %.9f) vs (%.9f, %.9f); iterations %d+%d vs %d+%d\n", seed,
                rp.fit.params[index(Param::kE1)], rp.fit.params[index(Param::kE2)], rj.fit.params[index(Param::kE1)],
                rj.fit.params[index(Param::kE2)], rp.fit.surrogate_iterations, rp.fit.iterations,
                rj.fit.surrogate_iterations, rj.fit.iterations);
    for (Param q : {Param::kE1, Param::kE2, Param::kRadius, Param::kX0, Param::kY0}) {
      EXPECT_NEAR(rp.fit.params[index(q)], rj.fit.params[index(q)], 1e-3 * rj.fit.errors[index(q)]) << param_name(q);
      EXPECT_NEAR(rp.fit.errors[index(q)], rj.fit.errors[index(q)], 1e-4 * rj.fit.errors[index(q)]) << param_name(q);
    }
    EXPECT_NEAR(rp.fit.chi2, rj.fit.chi2, 1e-9 * rj.fit.chi2);
    for (int b = 0; b < 3; ++b) {
      const BandFit &bp = rp.bands[static_cast<std::size_t>(b)], &bj = rj.bands[static_cast<std::size_t>(b)];
      EXPECT_NEAR(bp.flux, bj.flux, 1e-5 * bj.flux) << "band " << b;
      EXPECT_NEAR(bp.snr, bj.snr, 1e-6 * bj.snr) << "band " << b;
    }
    // One band's cutouts, projected and joint.
    ObjectFitter ep(projected), ej(joint);
    const std::vector<Observation> one_p = testing::epoch_data(ep.renderer_for(kEpochBox), bands.epochs[1]);
    const std::vector<Observation> one_j = testing::epoch_data(ej.renderer_for(kEpochBox), bands.epochs[1]);
    const FitResult fp = ep.fit(one_p), fj = ej.fit(one_j);
    ASSERT_EQ(fp.status, FitStatus::kOk);
    ASSERT_EQ(fj.status, FitStatus::kOk);
    for (Param q : {Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA}) {
      EXPECT_NEAR(fp.params[index(q)], fj.params[index(q)], 1e-3 * fj.errors[index(q)]) << param_name(q);
      EXPECT_NEAR(fp.errors[index(q)], fj.errors[index(q)], 1e-4 * fj.errors[index(q)]) << param_name(q);
    }
    EXPECT_NEAR(fp.flux, fj.flux, 1e-5 * fj.flux);
  }
}

}  // namespace
}  // namespace stampede
