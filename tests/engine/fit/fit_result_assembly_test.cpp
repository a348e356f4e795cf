// Tests for engine/fit/fit_result_assembly: a solve's optimum made a FitResult in data units, one
// band or several, with and without bounds, weights and a usable covariance.
#include "engine/fit/fit_result_assembly.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>
#include <vector>

#include "engine/render/renderer_factory.hpp"

namespace stampede {
namespace {

const std::array<Param, 7> kFree = {Param::kX0, Param::kY0, Param::kE1,   Param::kE2,
                                    Param::kRadius, Param::kBulgeA, Param::kDiscA};
// Data units per internal unit: 4 for the data, 1/4 for the weights, so chi2's is 4.
const FitUnits kUnits{4.0, 0.25};

ParamVector optimum(double bulge_a, double disc_a) {
  ParamVector p{};
  p.fill(0.0);
  p[index(Param::kX0)] = 10.25, p[index(Param::kY0)] = 11.5;
  p[index(Param::kE1)] = 0.1, p[index(Param::kE2)] = -0.2;
  p[index(Param::kRadius)] = 2.0;
  p[index(Param::kBulgeA)] = bulge_a, p[index(Param::kDiscA)] = disc_a;
  p[index(Param::kRadiusRatio)] = 1.0, p[index(Param::kBulgeIndex)] = 4.0, p[index(Param::kDiscIndex)] = 1.0;
  return p;
}

// A solve that stopped converged at chi2 = 30 (internal units) with variances 0.01 (k + 1).
SolveResult solved(bool cov_ok) {
  SolveResult s;
  s.summary.reason = StopReason::kRelativeChi2Change;
  s.chi2 = 30.0;
  const int n = static_cast<int>(kFree.size());
  s.cov = LmMatrix::Zero(n, n);
  for (int k = 0; k < n; ++k) s.cov(k, k) = 0.01 * (k + 1);
  s.cov_ok = cov_ok;
  return s;
}

class FitResultAssembly : public testing::Test {
 protected:
  FitResultAssembly() : renderer_(make_renderer(RendererKind::kExact, RenderOptions{}, ModelOptions{}, plans_)) {}

  SolvedFit fit(const SolveResult& s, std::span<const SolvedBand> bands) const {
    return {.solved = s,
            .free = kFree,
            .bands = bands,
            .units = kUnits,
            .renderer = *renderer_,
            .ellipticity_mirror = ModelOptions{}.ellipticity_mirror};
  }

  FftPlanCache plans_{FftPlanning::kEstimate};
  std::unique_ptr<Renderer> renderer_;
};

TEST_F(FitResultAssembly, OneBandIsItsOptimumInDataUnits) {
  const SolveResult s = solved(true);
  const SolvedBand band{.band = 0, .params = optimum(3.0, 5.0), .signal = 900.0};
  FitResult r;
  r.iterations = 7;  // solve()'s fields are kept
  SolvedFit f = fit(s, {&band, 1});
  f.flags = kFlagMaskedPixels;
  assemble_fit_result(f, {}, &r);

  ParamVector effective{};
  ASSERT_TRUE(renderer_->effective_params(band.params, &effective));
  for (int k = 0; k < kNumParams; ++k) EXPECT_EQ(r.params[k], effective[k] * kUnits.of(static_cast<Param>(k))) << k;
  EXPECT_EQ(r.params[index(Param::kBulgeA)], 12.0);
  for (std::size_t k = 0; k < kFree.size(); ++k) {
    const Param q = kFree[k];
    EXPECT_DOUBLE_EQ(r.errors[index(q)], kUnits.of(q) * std::sqrt(0.01 * static_cast<double>(k + 1) / 4.0)) << k;
  }
  EXPECT_TRUE(std::isnan(r.errors[index(Param::kRadiusRatio)]));  // fixed
  EXPECT_EQ(r.e1_err, r.errors[index(Param::kE1)]);
  EXPECT_EQ(r.e2_err, r.errors[index(Param::kE2)]);
  double bulge = 0, disc = 0;
  renderer_->component_fluxes(band.params, &bulge, &disc);
  EXPECT_EQ(r.bulge_flux, bulge * 4.0);
  EXPECT_EQ(r.disc_flux, disc * 4.0);
  EXPECT_EQ(r.flux, r.bulge_flux + r.disc_flux);
  EXPECT_EQ(r.chi2, 120.0);
  EXPECT_EQ(r.likelihood, -60.0);
  EXPECT_EQ(r.snr, 60.0);  // sqrt(900 x 4)
  EXPECT_EQ(r.status, FitStatus::kOk);
  EXPECT_EQ(r.flags, kFlagMaskedPixels);
  EXPECT_EQ(r.iterations, 7);
}

TEST_F(FitResultAssembly, NoWeightsNoSnrNoCovarianceNoErrors) {
  SolveResult s = solved(false);
  s.summary.reason = StopReason::kMaxIterations;
  const SolvedBand band{.band = 0, .params = optimum(3.0, 5.0)};  // signal not computed
  FitResult r;
  SolvedFit f = fit(s, {&band, 1});
  f.flags = kFlagUnweighted;
  assemble_fit_result(f, {}, &r);
  EXPECT_TRUE(std::isnan(r.snr));
  for (Param q : kFree) EXPECT_TRUE(std::isnan(r.errors[index(q)]));
  EXPECT_TRUE(std::isnan(r.e1_err));
  EXPECT_EQ(r.status, FitStatus::kMaxIterations);
  EXPECT_EQ(r.flags, kFlagUnweighted | kFlagNoErrors | kFlagNotConverged);
  EXPECT_EQ(r.chi2, 120.0);
}

TEST_F(FitResultAssembly, BoundsAreCheckedOnlyWhereGiven) {
  const SolveResult s = solved(true);
  const SolvedBand band{.band = 0, .params = optimum(3.0, 5.0), .signal = 1.0};
  ParamVector lower{}, upper{};
  lower.fill(NAN), upper.fill(NAN);
  // Bulge amplitude 3 internal units = 12 in data units: at its upper bound within 1e-6.
  upper[index(Param::kBulgeA)] = 12.0 + 1e-6;
  FitResult unbounded, bounded;
  assemble_fit_result(fit(s, {&band, 1}), {}, &unbounded);
  SolvedFit f = fit(s, {&band, 1});
  f.lower = &lower, f.upper = &upper;
  assemble_fit_result(f, {}, &bounded);
  EXPECT_EQ(unbounded.flags & kFlagAtBound, 0u);
  EXPECT_EQ(bounded.flags & kFlagAtBound, kFlagAtBound);
  upper[index(Param::kBulgeA)] = 12.0 + 1e-4;  // 2.5e-5 internal units away
  FitResult clear;
  assemble_fit_result(f, {}, &clear);
  EXPECT_EQ(clear.flags & kFlagAtBound, 0u);
}

TEST_F(FitResultAssembly, BeyondTheMirrorIsFlagged) {
  const SolveResult s = solved(true);
  SolvedBand band{.band = 0, .params = optimum(3.0, 5.0), .signal = 1.0};
  band.params[index(Param::kE1)] = 0.97;
  FitResult r;
  assemble_fit_result(fit(s, {&band, 1}), {}, &r);
  EXPECT_EQ(r.flags & kFlagMirrored, kFlagMirrored);
  EXPECT_LT(r.params[index(Param::kE1)], 0.95);  // the effective, folded value
}

TEST_F(FitResultAssembly, SeveralBandsHaveTheirAmplitudesAndFluxesApart) {
  const SolveResult s = solved(true);
  // Bands 0 and 2 of three fitted; band 1 had no observations.
  const std::array<SolvedBand, 2> bands = {SolvedBand{.band = 0, .params = optimum(3.0, 5.0), .signal = 100.0},
                                           SolvedBand{.band = 2, .params = optimum(1.0, 2.0), .signal = 44.0}};
  std::vector<BandFit> band_fits(3);
  band_fits[0].n_epochs = 2, band_fits[2].n_epochs = 3;
  FitResult r;
  assemble_fit_result(fit(s, bands), band_fits, &r);

  EXPECT_TRUE(std::isnan(r.params[index(Param::kBulgeA)]));
  EXPECT_TRUE(std::isnan(r.params[index(Param::kDiscA)]));
  EXPECT_TRUE(std::isnan(r.errors[index(Param::kBulgeA)]));
  EXPECT_TRUE(std::isnan(r.errors[index(Param::kDiscA)]));
  EXPECT_DOUBLE_EQ(r.errors[index(Param::kE1)], std::sqrt(0.03 / 4.0));
  EXPECT_EQ(r.snr, 24.0);  // sqrt(144 x 4)
  for (std::size_t b : {std::size_t{0}, std::size_t{2}}) {
    const SolvedBand& band = bands[b == 0 ? 0 : 1];
    double bulge = 0, disc = 0;
    renderer_->component_fluxes(band.params, &bulge, &disc);
    EXPECT_EQ(band_fits[b].bulge_flux, 4.0 * bulge) << b;
    EXPECT_EQ(band_fits[b].disc_flux, 4.0 * disc) << b;
    EXPECT_EQ(band_fits[b].flux, band_fits[b].bulge_flux + band_fits[b].disc_flux) << b;
    EXPECT_EQ(band_fits[b].bulge_a, 4.0 * band.params[index(Param::kBulgeA)]) << b;
    EXPECT_EQ(band_fits[b].disc_a, 4.0 * band.params[index(Param::kDiscA)]) << b;
    EXPECT_EQ(band_fits[b].snr, std::sqrt(band.signal * 4.0)) << b;
  }
  EXPECT_EQ(band_fits[0].n_epochs, 2);
  EXPECT_EQ(band_fits[2].n_epochs, 3);
  EXPECT_TRUE(std::isnan(band_fits[1].flux));  // not fitted, untouched
  EXPECT_EQ(r.bulge_flux, band_fits[0].bulge_flux + band_fits[2].bulge_flux);
  EXPECT_EQ(r.disc_flux, band_fits[0].disc_flux + band_fits[2].disc_flux);
  EXPECT_EQ(r.flux, r.bulge_flux + r.disc_flux);
}

}  // namespace
}  // namespace stampede
