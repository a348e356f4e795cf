// The noise-bias model: cubic curves recover an injected bias, the RBF model reproduces the grid
// and a plane between nodes exactly, m is the shear response of a radial bias, and c is scaled with
// S/N and turned with the PSF as appendix C says.
#include "engine/calibration/noise_bias.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>

namespace stampede {
namespace {

CalibrationGridOptions grid_options() {
  CalibrationGridOptions o;
  o.radii = {1.0, 2.5, 5.0};
  o.bulge_fractions = {0.0, 0.5, 1.0};
  o.e_steps = 9;
  o.psf.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  return o;
}

// An injected bias whose cubic coefficients depend linearly on (ln r, F) (so the RBF's linear term
// carries them exactly between nodes): a_j(axis, comp) = base + slope_r ln r + slope_f F.
double injected(int slot, int j, double r, double f) {
  const double base = 0.001 * (1 + slot) * (j + 1) * (j % 2 ? 1 : -1);
  return base * (1 + 0.3 * std::log(r) - 0.4 * f);
}

// Biases at every grid point from the injected cubics, with errors 1e-4.
CalibrationTable injected_table() {
  CalibrationTable t;
  t.grid = grid_options();
  const CalibrationGrid grid(t.grid);
  t.points = grid.points();
  for (const CalibrationPoint& p : t.points) {
    PointBias b;
    for (int c = 0; c < 2; ++c) {
      const int slot = 2 * static_cast<int>(p.axis) + c;
      double y = 0;
      for (int j = 3; j >= 0; --j) y = y * p.e_true + injected(slot, j, p.radius, p.bulge_fraction);
      b.bias[c] = y;
      b.error[c] = 1e-4;
    }
    b.pairs_used = 16;
    t.biases.push_back(b);
  }
  t.curves = fit_bias_curves(t.grid, t.points, t.biases);
  return t;
}

TEST(NoiseBias, CubicCurvesRecoverTheInjectedBias) {
  const CalibrationTable t = injected_table();
  ASSERT_EQ(t.curves.size(), 9u * 4);
  for (std::size_t k = 0; k < t.curves.size(); ++k) {
    const BiasCurve& c = t.curves[k];
    EXPECT_EQ(static_cast<int>(k % 4), 2 * static_cast<int>(c.axis) + c.component);
    EXPECT_EQ(c.points, 9);
    for (int j = 0; j < 4; ++j) {
      EXPECT_NEAR(c.coefficients[j], injected(static_cast<int>(k % 4), j, c.radius, c.bulge_fraction), 1e-12);
      EXPECT_GT(c.errors[j], 0.0);
    }
    EXPECT_LT(c.chi2, 1e-12);
  }
}

// The model's m, c from injected coefficients, by the formulas of noise_bias.hpp.
Bias expected(double r, double f, double e) {
  auto a = [&](int slot, int j) { return injected(slot, j, r, f); };
  Bias b;
  const double w = e * e * (2 - e * e);
  b.m = 0.5 * (a(0, 1) + a(0, 3) * w + a(3, 1) + a(3, 3) * w);
  b.c1 = 0.5 * (a(0, 0) + a(0, 2) * e * e + a(2, 0) + a(2, 2) * e * e);
  b.c2 = 0.5 * (a(1, 0) + a(1, 2) * e * e + a(3, 0) + a(3, 2) * e * e);
  return b;
}

TEST(NoiseBias, ModelReproducesNodesAndAPlaneBetweenThem) {
  const NoiseBiasModel model(injected_table());
  EXPECT_EQ(model.snr_ref(), 20.0);
  EXPECT_EQ(model.psf_e0(), std::complex<double>(0.0, 0.05));
  for (double r : {1.0, 1.7, 2.5, 3.9, 5.0})
    for (double f : {0.0, 0.2, 0.5, 0.9, 1.0})
      for (double e : {0.0, 0.3, 0.7}) {
        bool clamped = true;
        const Bias b = model.at({r, f, e}, &clamped), x = expected(r, f, e);
        EXPECT_FALSE(clamped);
        EXPECT_NEAR(b.m, x.m, 1e-12) << r << " " << f << " " << e;
        // The calibration PSF is along e2: c keeps its e2 part only.
        EXPECT_EQ(b.c1, 0.0);
        EXPECT_NEAR(b.c2, x.c2, 1e-12);
      }
  // Outside the grid: clamped to its edge, and said so.
  bool clamped = false;
  const Bias out = model.at({9.0, 1.3, 0.95}, &clamped), edge = expected(5.0, 1.0, 0.8);
  EXPECT_TRUE(clamped);
  EXPECT_NEAR(out.m, edge.m, 1e-12);
}

// m = a1 + 2 a3 |e|^2 - a3 |e|^4 is the shear response of an isotropic population with a radial
// bias e_fit = e' + f(|e'|) e' / |e'|, f = a1 r + a3 r^3, where e' = (e + g) / (1 + conj(g) e) is the
// sheared ellipticity: check against a numerical derivative of the orientation-averaged e_fit,1.
TEST(NoiseBias, MultiplicativeBiasIsTheResponseOfARadialBias) {
  auto mean_e1 = [](double r, double g, double a1, double a3) {
    const int n = 720;
    double sum = 0;
    for (int k = 0; k < n; ++k) {
      const std::complex<double> e = std::polar(r, 2 * std::numbers::pi * (k + 0.5) / n);
      const std::complex<double> sheared = (e + g) / (1.0 + g * e);
      const double s = std::abs(sheared);
      sum += (sheared + (a1 * s + a3 * s * s * s) * sheared / s).real();
    }
    return sum / n;
  };
  const double a1 = 0.03, a3 = -0.02, h = 1e-5;
  for (double r : {0.1, 0.3, 0.6, 0.8}) {
    const double response = (mean_e1(r, h, a1, a3) - mean_e1(r, -h, a1, a3)) / (2 * h);
    EXPECT_NEAR(response - 1, a1 + 2 * a3 * r * r - a3 * r * r * r * r, 1e-8) << r;
    // Without the bias the response is exactly 1: the ring mean of e' is g.
    EXPECT_NEAR((mean_e1(r, h, 0, 0) - mean_e1(r, -h, 0, 0)) / (2 * h), 1.0, 1e-8) << r;
  }
}

TEST(NoiseBias, CorrectionScalesWithSnrAndTurnsWithThePsf) {
  const Bias b{0.04, 2e-3, -1e-3};
  const std::complex<double> e0(0.0, 0.05);  // calibration PSF along e2
  // Same PSF, reference S/N: unchanged; twice the S/N: a quarter.
  Bias k = object_correction(b, 20, e0, 20, e0);
  EXPECT_DOUBLE_EQ(k.m, 0.04);
  EXPECT_DOUBLE_EQ(k.c1, 2e-3);
  EXPECT_DOUBLE_EQ(k.c2, -1e-3);
  k = object_correction(b, 20, e0, 40, e0);
  EXPECT_DOUBLE_EQ(k.m, 0.01);
  EXPECT_NEAR(k.c1, 0.5e-3, 1e-18);
  // PSF turned by 90 degrees (e -> -e): c reverses; twice as elliptical: c doubles.
  k = object_correction(b, 20, e0, 20, -e0);
  EXPECT_NEAR(k.c1, -2e-3, 1e-18);
  EXPECT_NEAR(k.c2, 1e-3, 1e-18);
  k = object_correction(b, 20, e0, 20, 2.0 * e0);
  EXPECT_NEAR(k.c1, 4e-3, 1e-18);
  // PSF along e1 (45 degrees on the sky from e2, 90 in e-space): c turns by -90 degrees in e-space.
  k = object_correction(b, 20, e0, 20, {0.05, 0.0});
  EXPECT_NEAR(k.c1, -1e-3, 1e-18);
  EXPECT_NEAR(k.c2, -2e-3, 1e-18);
  EXPECT_DOUBLE_EQ(k.m, 0.04);  // m does not turn
  // Unknown PSF: the calibration's assumed. No usable S/N: NaN.
  k = object_correction(b, 20, e0, 20, {NAN, NAN});
  EXPECT_DOUBLE_EQ(k.c1, 2e-3);
  EXPECT_TRUE(std::isnan(object_correction(b, 20, e0, NAN, e0).m));
  EXPECT_TRUE(std::isnan(object_correction(b, 20, e0, -3, e0).c1));
  // Round calibration PSF: c cannot be turned and is applied as measured.
  k = object_correction(b, 20, 0.0, 20, {0.05, 0.0});
  EXPECT_DOUBLE_EQ(k.c1, 2e-3);
  // Calibrated e inverts e = (1 + m) e_true + c.
  double e1, e2;
  calibrate_ellipticity(b, (1 + 0.04) * 0.3 + 2e-3, (1 + 0.04) * -0.1 - 1e-3, &e1, &e2);
  EXPECT_NEAR(e1, 0.3, 1e-15);
  EXPECT_NEAR(e2, -0.1, 1e-15);
}

TEST(NoiseBias, AdditiveBiasIsProjectedOnThePsf) {
  CalibrationTable t = injected_table();
  const GalaxyProperties g{2.0, 0.4, 0.3};
  t.grid.psf.moffat.e1 = 0.0, t.grid.psf.moffat.e2 = 0.0;  // round: nothing to project on
  const Bias whole = NoiseBiasModel(t).at(g), x = expected(2.0, 0.4, 0.3);
  EXPECT_NEAR(whole.c1, x.c1, 1e-12);
  EXPECT_NEAR(whole.c2, x.c2, 1e-12);
  t.grid.psf.moffat.e1 = 0.03, t.grid.psf.moffat.e2 = 0.04;  // along (0.6, 0.8)
  const Bias along = NoiseBiasModel(t).at(g);
  const double c = 0.6 * x.c1 + 0.8 * x.c2;
  EXPECT_NEAR(along.c1, 0.6 * c, 1e-12);
  EXPECT_NEAR(along.c2, 0.8 * c, 1e-12);
  EXPECT_NEAR(along.m, whole.m, 1e-15);
}

TEST(NoiseBias, PopulationMeanIsTheMeanOverTheSample) {
  const NoiseBiasModel model(injected_table());
  PopulationBias pop(model);
  double m = 0;
  const GalaxyProperties sample[] = {{1.2, 0.1, 0.2}, {3.0, 0.6, 0.5}, {4.0, 0.9, 0.1}, {7.0, 0.5, 0.3}};
  for (const GalaxyProperties& g : sample) {
    pop.add(g);
    m += model.at(g).m;
  }
  EXPECT_EQ(pop.count(), 4);
  EXPECT_EQ(pop.clamped(), 1);
  EXPECT_NEAR(pop.mean().m, m / 4, 1e-15);
}

// The calibration's error on a population mean is linear in the point errors (everything between
// the point biases and the mean is linear), and of the size the cubic fits imply.
TEST(NoiseBias, PopulationErrorScalesWithThePointErrors) {
  CalibrationTable t = injected_table();
  const std::vector<GalaxyProperties> sample = {{1.3, 0.2, 0.3}, {2.0, 0.7, 0.1}, {2.8, 0.5, 0.4}};
  const Bias e1 = population_bias_error(t, sample, 200, 5);
  for (PointBias& b : t.biases) b.error[0] *= 2, b.error[1] *= 2;
  const Bias e2 = population_bias_error(t, sample, 200, 5);
  EXPECT_GT(e1.m, 0.0);
  EXPECT_NEAR(e2.m, 2 * e1.m, 1e-9 * e1.m);
  EXPECT_GT(e1.c2, 0.0);
  EXPECT_NEAR(e2.c2, 2 * e1.c2, 1e-9 * e1.c2);
  // Points known to 1e-4 over 9 values of e in [-0.8, 0.8]: a1 to ~1e-4 / (3 x 0.55) x (cubic
  // inflation ~2), and the mean of two components over a few nodes: m to a few 1e-5.
  EXPECT_GT(e1.m, 5e-6);
  EXPECT_LT(e1.m, 2e-4);
  EXPECT_TRUE(std::isnan(population_bias_error(t, {}, 200, 5).m));
}

TEST(NoiseBias, ModelRefusesAnIncompleteTable) {
  CalibrationTable t = injected_table();
  t.curves[5].coefficients[2] = NAN;
  EXPECT_THROW(NoiseBiasModel{t}, std::invalid_argument);
  t = injected_table();
  t.curves.pop_back();
  EXPECT_THROW(NoiseBiasModel{t}, std::invalid_argument);
}

}  // namespace
}  // namespace stampede
