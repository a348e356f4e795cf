// Every instruction-set build of the exact renderer's term loop against the scalar reference (the
// same source with double lanes), over dense term lists, shapes and table regions (small q, the
// interpolated range, the power-law tail). Tolerances are multiples of machine epsilon times each
// spectrum's largest |value|: the builds differ in log and exp rounding (xsimd's vs libm's) and in
// fused multiply-adds.
#include "kernels/kspace_render.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "kernels/ellipse.hpp"
#include "kernels/fourier_profiles.hpp"
#include "support/image_compare.hpp"

namespace stampede::kernels {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kPi = std::numbers::pi;

// A dense term list: every block holds all 3 x 3 aliases with random PPi.
KSpaceTerms dense_terms(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  KSpaceTerms t;
  t.n = n;
  t.row_stride = (n / 2 + 1 + kKBlock - 1) / kKBlock * kKBlock;
  const int m = 1, aliases = 3;
  t.alias_max = m;
  const double dk = 2 * kPi / n;
  for (int a = 0; a < aliases; ++a) {
    for (int jx = 0; jx < t.row_stride; ++jx) t.kx_values.push_back(2 * kPi * (a - m) + dk * jx);
    for (int jy = 0; jy < n; ++jy) t.ky_values.push_back(2 * kPi * (a - m) + dk * (jy <= n / 2 ? jy : jy - n));
  }
  const int per_row = t.row_stride / kKBlock;
  for (int jy = 0; jy < n; ++jy)
    for (int b = 0; b < per_row; ++b) {
      t.block_begin.push_back(static_cast<std::int32_t>(t.entry_ix.size()));
      for (int ay = 0; ay < aliases; ++ay)
        for (int ax = 0; ax < aliases; ++ax) {
          t.entry_ix.push_back(ax * t.row_stride + b * kKBlock);
          t.entry_iy.push_back(ay * n + jy);
          t.entry_alias.push_back(ax * aliases + ay);
          for (int l = 0; l < kKBlock; ++l) t.ppi.push_back(u(rng));
        }
    }
  t.block_begin.push_back(static_cast<std::int32_t>(t.entry_ix.size()));
  return t;
}

void set_component(double e1, double e2, double r, double amplitude, const SersicKTable* table, KSpaceComponent* c) {
  // The k-space form is the real-space form of the opposite shear at radius 1 / r, scaled: any
  // symmetric positive form serves the comparison.
  const EllipseQuadratic w = ellipse_quadratic(-e1, -e2, 1.0 / r);
  EllipseQuadratic d1, d2;
  ellipse_quadratic_derivatives(-e1, -e2, 1.0 / r, &d1, &d2);
  c->table = table;
  c->wxx = w.xx, c->wxy = w.xy, c->wyy = w.yy;
  c->e1xx = -d1.xx, c->e1xy = -d1.xy, c->e1yy = -d1.yy;
  c->e2xx = -d2.xx, c->e2xy = -d2.xy, c->e2yy = -d2.yy;
  c->flux_per_amplitude = 0.7 * r * r;
  c->flux = amplitude * c->flux_per_amplitude;
}

struct Spectra {
  std::vector<std::vector<double>> re, im;
  KSpaceSpectra view;
  explicit Spectra(const KSpaceTerms& t) {
    const std::size_t size = static_cast<std::size_t>(t.n) * t.row_stride;
    re.assign(kNumKSpaceImages, std::vector<double>(size, NAN));
    im.assign(kNumKSpaceImages, std::vector<double>(size, NAN));
    for (int k = 0; k < kNumKSpaceImages; ++k) {
      view.re[k] = re[k].data();
      view.im[k] = im[k].data();
    }
  }
};

// Worst |a - b| over the reference's peak, in epsilons.
double worst_in_peak_eps(const std::vector<double>& a, const std::vector<double>& b) {
  return testing::worst_over_peak(a, b) / kEps;
}

TEST(KSpaceKernelsIsa, ScalarReferenceAndBestAreAvailable) {
  ASSERT_NE(kspace_kernels_for(Isa::kScalar), nullptr);
  EXPECT_EQ(kspace_kernels_for(Isa::kScalar)->lanes, 1);
  std::printf("best: %s (%d doubles per vector)\n", kspace_kernels().name, kspace_kernels().lanes);
}

TEST(KSpaceKernelsIsa, EveryBuildMatchesTheScalarReference) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // A smooth unit-flux transform on a short table (q_max = 20), so lanes fall below q_min
  // (k = 0), inside, and in the tail (k r ~ 3 pi x 2.5 x stretch).
  const LogGrid grid = LogGrid::covering(1e-4, 20.0, 40);
  std::vector<double> values;
  for (int i = 0; i < grid.count; ++i) values.push_back(exponential_fourier(2.0 * grid.node(i)));
  const SersicKTable table(grid, values);
  const KSpaceKernels& scalar = *kspace_kernels_for(Isa::kScalar);
  int compared = 0;
  for (Isa isa : {Isa::kSse42, Isa::kAvx2, Isa::kAvx512}) {
    const KSpaceKernels* k = kspace_kernels_for(isa);
    if (!k) continue;
    double worst = 0;
    for (int n : {16, 24, 30}) {
      const KSpaceTerms terms = dense_terms(n, rng);
      for (int shape = 0; shape < 6; ++shape) {
        const double e = 0.9 * u(rng), th = kPi * u(rng);
        KSpaceModel m;
        set_component(e * std::cos(2 * th), e * std::sin(2 * th), 0.2 + 2.5 * u(rng), 3.0, &table, &m.bulge);
        set_component(0.5 * e * std::cos(2 * th), 0.5 * e * std::sin(2 * th), 0.2 + 2.5 * u(rng), 0.4,
                      shape % 2 ? &table : nullptr, &m.disc);
        m.dlnr = 1.0 / (0.3 + u(rng));
        // Phases of a centre at (7.3, 8.1): the bins' and the aliases'.
        const double x0 = 7.3, y0 = 8.1, dk = 2 * kPi / n;
        std::vector<double> pxr, pxi, pyr, pyi, ar, ai;
        for (int jx = 0; jx < terms.row_stride; ++jx) {
          pxr.push_back(std::cos(dk * jx * x0));
          pxi.push_back(-std::sin(dk * jx * x0));
        }
        for (int jy = 0; jy < n; ++jy) {
          const double ky = dk * (jy <= n / 2 ? jy : jy - n);
          pyr.push_back(std::cos(ky * y0));
          pyi.push_back(-std::sin(ky * y0));
        }
        for (int ax = 0; ax < terms.aliases(); ++ax)
          for (int ay = 0; ay < terms.aliases(); ++ay) {
            const double phase = -2 * kPi * ((ax - terms.alias_max) * x0 + (ay - terms.alias_max) * y0);
            ar.push_back(std::cos(phase));
            ai.push_back(std::sin(phase));
          }
        m.bin_phase_x_re = pxr.data(), m.bin_phase_x_im = pxi.data(), m.bin_phase_y_re = pyr.data(),
        m.bin_phase_y_im = pyi.data(), m.alias_phase_re = ar.data(), m.alias_phase_im = ai.data();
        Spectra ref(terms), got(terms), ref_model(terms), got_model(terms), got_components(terms);
        scalar.accumulate_jacobian(terms, m, ref.view);
        k->accumulate_jacobian(terms, m, got.view);
        scalar.accumulate_model(terms, m, ref_model.view);
        k->accumulate_model(terms, m, got_model.view);
        k->accumulate_components(terms, m, got_components.view);
        // The components pass gives the Jacobian pass's component spectra.
        for (int img : {kKBulge, kKDisc}) {
          const double w = std::max(worst_in_peak_eps(got_components.re[img], ref.re[img]),
                                    worst_in_peak_eps(got_components.im[img], ref.im[img]));
          EXPECT_LT(w, 64.0) << k->name << " components image " << img << " n " << n << " shape " << shape;
          worst = std::max(worst, w);
        }
        for (int img = 0; img < kNumKSpaceImages; ++img) {
          const double w = std::max(worst_in_peak_eps(got.re[img], ref.re[img]), worst_in_peak_eps(got.im[img], ref.im[img]));
          EXPECT_LT(w, 64.0) << k->name << " image " << img << " n " << n << " shape " << shape;
          worst = std::max(worst, w);
        }
        const double w = std::max(worst_in_peak_eps(got_model.re[0], ref_model.re[0]),
                                  worst_in_peak_eps(got_model.im[0], ref_model.im[0]));
        EXPECT_LT(w, 64.0) << k->name << " model n " << n << " shape " << shape;
        worst = std::max(worst, w);
        ++compared;
      }
    }
    std::printf("%s vs scalar: worst %.1f eps of each spectrum's peak\n", k->name, worst);
  }
  EXPECT_GT(compared, 0);
}

// The table resamples LogTable's interpolant (six-point Lagrange in log q) into polynomials in
// w = q^2 per sixteenth of an octave: against the closed-form exponential transform it must be as
// accurate as LogTable itself (whose node spacing sets the error), it must reproduce LogTable to
// a small fraction of that error, and its slope must be its own values' derivative.
TEST(KSpaceKernelsIsa, TableIsAsAccurateAsLogTableAndHasItsOwnDerivative) {
  const LogGrid grid = LogGrid::covering(1e-4, 2000.0, 40);
  std::vector<double> values;
  for (int i = 0; i < grid.count; ++i) values.push_back(exponential_fourier(grid.node(i)));
  const SersicKTable table(grid, values);
  const LogTable reference(grid, values);
  double worst_value = 0, worst_table = 0, worst_reference = 0, worst_slope = 0;
  for (double q = 2e-5; q < 4000; q *= 1.00137) {
    double v, s, vp, sp, vm, sm;
    table.evaluate(q * q, &v, &s);
    if (q * q < table.w_hi) {  // beyond, both are power laws anchored at different nodes
      worst_value = std::max(worst_value, std::abs(v - reference(q)));
      worst_table = std::max(worst_table, std::abs(v - exponential_fourier(q)));
      worst_reference = std::max(worst_reference, std::abs(reference(q) - exponential_fourier(q)));
    } else {
      // The power law through the last nodes against the q^-3 asymptote of the closed form.
      EXPECT_LT(std::abs(v - exponential_fourier(q)), 1e-4 * exponential_fourier(q)) << "tail at q = " << q;
    }
    if (q < 0.03) continue;  // below, a difference of values 1 - O(w) is rounding only
    const double h = 1e-5 * q * q;
    table.evaluate(q * q + h, &vp, &sp);
    table.evaluate(q * q - h, &vm, &sm);
    // Skip the differences that straddle an interval's edge (the interpolant is C0 there).
    const auto interval = [&](double w) { return std::ilogb(w) * SersicKTable::kSubdivisions +
                                                 static_cast<int>((std::ldexp(w, -std::ilogb(w)) - 1) * SersicKTable::kSubdivisions); };
    if (interval(q * q + h) != interval(q * q - h) || q * q + h >= table.w_hi) continue;
    worst_slope = std::max(worst_slope, std::abs((vp - vm) / (2 * h) - s) / std::abs(s));
  }
  std::printf("table vs closed form %.2e (LogTable's own %.2e); table vs LogTable %.2e; slope vs FD: worst relative %.2e\n",
              worst_table, worst_reference, worst_value, worst_slope);
  EXPECT_LE(worst_table, 1.01 * worst_reference);
  EXPECT_LT(worst_reference, 1e-8);
  EXPECT_LT(worst_value, 0.1 * worst_reference);
  EXPECT_LT(worst_slope, 1e-6);
}

}  // namespace
}  // namespace stampede::kernels
