// Tests of the exact Fourier-space renderer: the GalSim reference stamps, its Jacobian against
// central differences, flux, the light wrapped by the period, and a noise-free fit through the
// Levenberg-Marquardt solver.
#include "engine/render/exact_renderer.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <utility>

#include "engine/solver/levenberg_marquardt.hpp"
#include "kernels/ellipse.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/math/sinc.hpp"
#include "kernels/psf_profile.hpp"
#include "kernels/sersic.hpp"
#include "support/image_compare.hpp"
#include "support/reference_data.hpp"

namespace stampede {
namespace {

PsfModel moffat(double beta, double fwhm, double e1 = 0.0, double e2 = 0.0) {
  PsfModel psf;
  psf.kind = PsfKind::kMoffat;
  psf.moffat = {beta, fwhm, e1, e2, 0.0};
  return psf;
}

// Everything one renderer needs, for a stamp size and a PSF.
struct ExactSetup {
  RenderOptions ro;
  ExactRenderOptions eo;
  std::unique_ptr<ExactRenderer> renderer;
  const kernels::KSpaceTerms* terms = nullptr;
  ExactSetup(int stamp, const PsfModel& psf, double tolerance = ExactRenderOptions{}.psf_tolerance, int period = 0,
             int wrap_rings = ExactRenderOptions{}.wrap_rings) {
    ro.stamp_size = stamp;
    eo.psf_tolerance = tolerance;
    eo.period = period;
    eo.wrap_rings = wrap_rings;
    ro.exact = eo;
    renderer = std::make_unique<ExactRenderer>(ro, ModelOptions{});
    std::string error;
    auto prepared = renderer->prepare_psf(psf, &error);
    if (!prepared) throw std::runtime_error(error);
    renderer->set_psf(prepared);
    terms = &renderer->psf()->terms();
  }
};

using testing::worst_over_peak;

TEST(ExactRenderer, DeVaucouleursTableBuildTime) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto table = de_vaucouleurs_k_table();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("n = 4 table: %d intervals up to q = %.0f, built (or found) in %.2f s\n", table->intervals, table->q_max(), s);
  // The interpolant against the quadrature between nodes, and F(0) = 1.
  double worst = 0;
  for (double q : {0.0, 3e-5, 0.01, 0.37, 1.0, 2.2, 7.7, 31.0, 140.0, 900.0}) {
    double v, slope;
    table->evaluate(q * q, &v, &slope);
    worst = std::max(worst, std::abs(v - kernels::sersic_fourier(4.0, q)));
  }
  std::printf("n = 4 table: worst |F_table - F_quadrature| = %.2e\n", worst);
  EXPECT_LT(worst, 1e-9);
}

// Must-show 1: every GalSim case to 1e-5 of its peak at the default tolerance.
TEST(ExactRenderer, MatchesGalSimReferenceCases) {
  const auto cases = testing::load_render_cases();
  ASSERT_EQ(cases.size(), 22u);
  for (double tolerance : {1e-5, 1e-6, 1e-7, 1e-8}) {
    std::map<std::vector<double>, std::unique_ptr<ExactSetup>> setups;
    double overall = 0, discs = 0;
    const bool is_default = tolerance == ExactRenderOptions{}.psf_tolerance;
    for (const auto& c : cases) {
      const std::vector<double> key = {double(c.stamp), c.psf_fwhm, c.psf_beta, c.psf_e1, c.psf_e2};
      auto& s = setups[key];
      if (!s) s = std::make_unique<ExactSetup>(c.stamp, testing::case_psf(c), tolerance);
      std::vector<double> image(c.image.size());
      ASSERT_EQ(s->renderer->render(testing::case_truth(c), image), RenderStatus::kOk);
      const double worst = worst_over_peak(image, c.image);
      if (is_default)
        std::printf("case %2d stamp %d N %d hlr %.2f bulge %.2f |e| %.2f: %lld terms, worst |diff|/peak %.2e\n", c.id,
                    c.stamp, s->renderer->period(), c.hlr, c.bulge_flux / (c.bulge_flux + c.disc_flux),
                    std::hypot(c.e1, c.e2), s->terms->entries() * kernels::kKBlock, worst);
      if (is_default) {
        EXPECT_LT(worst, 1e-5) << "case " << c.id;
      }
      overall = std::max(overall, worst);
      if (c.bulge_flux == 0) discs = std::max(discs, worst);
    }
    std::printf("tolerance %.0e: worst over all cases %.2e of the peak (discs alone %.2e)\n", tolerance, overall, discs);
  }
}

// The term list against its rule (exact_psf.hpp): an entry is a block of kKBlock columns at one
// alias pair, kept when any of its |PSF x pixel sinc| exceeds the tolerance. Recounted here from the
// transform itself: every kept entry holds a term above the tolerance, every lattice point above it
// (aliases one beyond the list's included) lies in a kept entry with its value, and the aliases stay
// within the list's cap (five pixel-frequency aliases at the PSF's stretch). A tighter tolerance
// keeps a superset. So entries <= terms above the tolerance <= kKBlock x entries.
TEST(ExactRenderer, TermCountsForTheFiducialPsf) {
  constexpr double kPi = std::numbers::pi;
  const double beta = 3.0, fwhm = 2.85, e1 = 0.0, e2 = 0.05;
  const double alpha = kernels::moffat_alpha(fwhm, beta);
  const kernels::EllipseQuadratic s2 = kernels::ellipse_quadratic(-e1, -e2, 1.0);
  const double e = std::hypot(e1, e2), stretch = std::sqrt((1 + e) / (1 - e));
  const int alias_cap = static_cast<int>(std::ceil(5 * stretch + 0.5));
  auto ppi = [&](double kx, double ky) {  // as build_kspace_terms evaluates it, before its k cut
    return kernels::moffat_fourier(beta, 0.0, std::sqrt(std::max(0.0, s2(kx, ky))) * alpha) * kernels::sinc(0.5 * kx) *
           kernels::sinc(0.5 * ky);
  };
  for (int stamp : {25, 39, 48}) {
    const int n = exact_period(stamp);
    long long previous_entries = 0, previous_above = 0;
    int previous_alias_max = 0;
    for (double tolerance : {1e-5, 1e-6, 1e-7, 1e-8}) {
      char trace[64];
      std::snprintf(trace, sizeof trace, "stamp %d, tolerance %.0e", stamp, tolerance);
      SCOPED_TRACE(trace);
      const auto terms = build_kspace_terms(moffat(beta, fwhm, e1, e2), n, tolerance);
      const int half = n / 2 + 1, stride = terms->row_stride, m_max = terms->alias_max;
      const int aliases = terms->aliases();
      const double dk = 2 * kPi / n, n2 = static_cast<double>(n) * n;
      ASSERT_EQ(terms->n, n);
      ASSERT_EQ(stride % kernels::kKBlock, 0);
      ASSERT_GE(stride, half);
      ASSERT_EQ(terms->blocks(), n * (stride / kernels::kKBlock));
      ASSERT_EQ(terms->block_begin.back(), terms->entries());
      EXPECT_LE(m_max, alias_cap);
      EXPECT_LE(terms->entries(), static_cast<long long>(terms->blocks()) * aliases * aliases);

      // Kept side: each entry's lanes are the transform's values (0 where the list cut them, which
      // must then be at most the tolerance), and one of them exceeds the tolerance.
      std::map<std::pair<int, int>, long long> kept;  // (kx index, ky index) -> entry
      for (long long i = 0; i < terms->entries(); ++i) {
        kept[{terms->entry_ix[i], terms->entry_iy[i]}] = i;
        double largest = 0;
        for (int l = 0; l < kernels::kKBlock; ++l) {
          const double lane = terms->ppi[i * kernels::kKBlock + l] * n2;
          const int jx = terms->entry_ix[i] % stride + l;
          if (jx >= half) {
            EXPECT_EQ(lane, 0.0) << "padding column " << jx;
            continue;
          }
          const double v = ppi(terms->kx_values[terms->entry_ix[i] + l], terms->ky_values[terms->entry_iy[i]]);
          if (lane == 0.0)
            EXPECT_LE(std::abs(v), tolerance);
          else
            EXPECT_NEAR(lane, v, 1e-12 * std::abs(v));
          largest = std::max(largest, std::abs(lane));
        }
        EXPECT_GT(largest, tolerance) << "entry " << i << " holds no term above the tolerance";
      }

      // Dropped side: every lattice point of the half-spectrum above the tolerance, over one more
      // alias than the list has, is in a kept entry. The Moffat transform falls monotonically in
      // x = |S k| alpha (x^nu K_nu(x) does) and |sinc| <= 1, so points beyond x_tol need no
      // evaluation.
      double lo = 0, hi = 1;
      while (kernels::moffat_fourier(beta, 0.0, hi) > tolerance) hi *= 2;
      for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        if (kernels::moffat_fourier(beta, 0.0, mid) > tolerance)
          lo = mid;
        else
          hi = mid;
      }
      const double x_tol = hi;  // the transform is at most the tolerance from here on
      long long above = 0, dropped = 0;
      std::string first_dropped;
      for (int my = -m_max - 1; my <= m_max + 1; ++my)
        for (int jy = 0; jy < n; ++jy) {
          const double ky = 2 * kPi * my + dk * (jy <= n / 2 ? jy : jy - n);
          for (int mx = -m_max - 1; mx <= m_max + 1; ++mx)
            for (int jx = 0; jx < half; ++jx) {
              const double kx = 2 * kPi * mx + dk * jx;
              if (std::sqrt(std::max(0.0, s2(kx, ky))) * alpha >= x_tol) continue;
              const double v = ppi(kx, ky);
              if (!(std::abs(v) > tolerance)) continue;
              ++above;
              const bool in_list = std::abs(mx) <= m_max && std::abs(my) <= m_max &&
                                   kept.count({(mx + m_max) * stride + jx / kernels::kKBlock * kernels::kKBlock,
                                               (my + m_max) * n + jy}) == 1;
              if (!in_list && dropped++ == 0)
                first_dropped = "alias (" + std::to_string(mx) + ", " + std::to_string(my) + "), bin (" +
                                std::to_string(jx) + ", " + std::to_string(jy) + "), |PPi| " +
                                std::to_string(std::abs(v));
            }
        }
      EXPECT_EQ(dropped, 0) << "terms above the tolerance dropped, the first at " << first_dropped;
      EXPECT_LE(terms->entries(), above);
      EXPECT_LE(above, terms->entries() * kernels::kKBlock);
      // A tighter tolerance keeps every term a looser one kept.
      EXPECT_GE(terms->entries(), previous_entries);
      EXPECT_GE(above, previous_above);
      EXPECT_GE(m_max, previous_alias_max);
      previous_entries = terms->entries(), previous_above = above, previous_alias_max = m_max;
      std::printf("stamp %d N %d tolerance %.0e: %lld entries = %lld terms (%d blocks of %d), %lld above the "
                  "tolerance, aliases -%d..%d\n",
                  stamp, n, tolerance, terms->entries(), terms->entries() * kernels::kKBlock, terms->blocks(),
                  kernels::kKBlock, above, m_max, m_max);
    }
  }
}

// Must-show 2: the analytic Jacobian equals central differences of render() to 1e-6 relative, for
// every free parameter, at random sets with |e| near the mirror, radii inside the softening region
// and centres off the stamp centre.
TEST(ExactRenderer, JacobianMatchesFiniteDifferences) {
  ExactSetup s(25, moffat(3.0, 2.85, 0.0, 0.05));
  ExactRenderer& renderer = *s.renderer;
  const int npix = 25 * 25;
  const std::array<Param, 7> free = {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA, Param::kDiscA};
  std::vector<double> model(npix), plus(npix), minus(npix), again(npix);
  std::vector<std::vector<double>> jac(7, std::vector<double>(npix));
  std::array<double*, 7> cols;
  for (int k = 0; k < 7; ++k) cols[k] = jac[k].data();
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double transition = renderer.galaxy_model().softening_transition();
  double worst_relative = 0;
  int tested = 0;
  for (int set = 0; set < 24; ++set) {
    ParamVector p = ParameterSet::default_values();
    p[index(Param::kX0)] = 12.0 + (u(rng) - 0.5) * 6.0;
    p[index(Param::kY0)] = 12.0 + (u(rng) - 0.5) * 6.0;
    double emag = 0.9 * u(rng);
    if (set % 4 == 1) emag = u(rng) < 0.5 ? 0.93 + 0.019 * u(rng) : 0.951 + 0.02 * u(rng);  // either side of the mirror
    const double theta = M_PI * u(rng);
    p[index(Param::kE1)] = emag * std::cos(2 * theta);
    p[index(Param::kE2)] = emag * std::sin(2 * theta);
    double r = 0.5 + 2.5 * u(rng);
    if (set % 4 == 2) r = transition * (0.2 + 0.7 * u(rng));  // inside the softening region
    if (set % 4 == 3) r = 0.1 + 0.3 * u(rng);                 // small, beyond the softening
    p[index(Param::kRadius)] = r;
    p[index(Param::kBulgeA)] = 500.0 * u(rng);
    p[index(Param::kDiscA)] = 50.0 * u(rng);
    ASSERT_EQ(renderer.render_with_jacobian(p, free, model, cols), RenderStatus::kOk);
    ASSERT_EQ(renderer.render(p, again), RenderStatus::kOk);
    double peak = 0;
    for (double v : model) peak = std::max(peak, std::abs(v));
    EXPECT_LT(worst_over_peak(again, model), 1e-13) << "render and render_with_jacobian disagree, set " << set;
    for (int k = 0; k < 7; ++k) {
      const int i = index(free[k]);
      const double h = (i <= 1) ? 1e-5 : (i <= 3) ? 1e-6 : (i == 4) ? 1e-6 * std::max(r, transition) : 1e-4 * std::max(1.0, p[i]);
      ParamVector pp = p, pm = p;
      pp[i] += h;
      pm[i] -= h;
      ASSERT_EQ(renderer.render(pp, plus), RenderStatus::kOk);
      ASSERT_EQ(renderer.render(pm, minus), RenderStatus::kOk);
      double max_fd = 0, max_diff = 0;
      for (int q = 0; q < npix; ++q) {
        const double fd = (plus[q] - minus[q]) / (2 * h);
        max_fd = std::max(max_fd, std::abs(fd));
        max_diff = std::max(max_diff, std::abs(fd - jac[k][q]));
      }
      // 1e-6 of the column's largest entry, plus the rounding of a central difference of images
      // of size ~peak (a few eps * peak / h).
      const double tol = 1e-6 * max_fd + 2e-14 * peak / h;
      EXPECT_LE(max_diff, tol) << "set " << set << " parameter " << param_name(free[k]) << " |e|=" << emag << " r=" << r
                               << " max|fd|=" << max_fd;
      worst_relative = std::max(worst_relative, max_diff / max_fd);
      ++tested;
    }
  }
  EXPECT_EQ(tested, 24 * 7);
  std::printf("Jacobian: worst max|J - FD| / max|FD| over %d columns = %.2e\n", tested, worst_relative);
}

// Must-show: the stamp's sum is the analytic flux for a galaxy well inside a large stamp.
TEST(ExactRenderer, StampSumIsTheAnalyticFlux) {
  // beta = 4.5: the PSF's light beyond 47 px is 5e-9 (beta = 3 leaves 1e-5 there).
  ExactSetup s(96, moffat(4.5, 2.5, 0.0, 0.05));
  std::vector<double> image(96 * 96);
  for (double bulge : {0.0, 1.0}) {
    ParamVector p = ParameterSet::default_values();
    p[index(Param::kX0)] = 47.3;
    p[index(Param::kY0)] = 47.8;
    p[index(Param::kE1)] = 0.2;
    p[index(Param::kE2)] = -0.1;
    p[index(Param::kRadius)] = bulge > 0 ? 0.6 : 2.0;
    p[index(Param::kBulgeA)] = bulge * 3000;
    p[index(Param::kDiscA)] = (1 - bulge) * 40;
    ASSERT_EQ(s.renderer->render(p, image), RenderStatus::kOk);
    double sum = 0;
    for (double v : image) sum += v;
    double fb, fd;
    s.renderer->galaxy_model().fluxes(p, &fb, &fd);
    // The stamp misses the light beyond it: a disc with r_e = 2 has ~1e-12 beyond 47 px, a de
    // Vaucouleurs bulge with r_e = 0.6 ~1e-4 (its light beyond 80 r_e, 1 - P(8, b_4 80^(1/4))).
    std::printf("%s: stamp sum / analytic flux - 1 = %.2e\n", bulge > 0 ? "bulge r_e 0.6" : "disc r_e 2", sum / (fb + fd) - 1);
    EXPECT_NEAR(sum / (fb + fd), 1.0, bulge > 0 ? 2e-4 : 1e-7);
  }
}

// The light wrapped onto the stamp by the period: |render at N - render at 2N| / peak (the wrap
// at 2N is ~10x smaller again), per component and radius, for the fiducial PSF and 39-pixel
// stamp, with the copies' light subtracted (the default) and without (wrap_rings = 0).
TEST(ExactRenderer, WrappedLight) {
  const int n = exact_period(39), wide_n = kernels::fft_friendly_size(2 * n);
  const PsfModel psf = moffat(3.0, 2.85, 0.0, 0.05);
  const double tol = ExactRenderOptions{}.psf_tolerance;
  ExactSetup corrected(39, psf, tol, n), raw(39, psf, tol, n, 0), wide(39, psf, tol, wide_n);
  std::vector<double> a(39 * 39), b(39 * 39), c(39 * 39);
  for (double bulge : {1.0, 0.0})
    for (double r : {0.5, 1.0, 2.0, 3.0, 5.0, 8.0}) {
      double worst = 0, worst_raw = 0;
      for (double offset : {0.0, 3.0})
        for (double e : {0.3, 0.7}) {
          ParamVector p = ParameterSet::default_values();
          p[index(Param::kX0)] = 19.0 + offset;
          p[index(Param::kY0)] = 19.0 - offset;
          p[index(Param::kE1)] = e;
          p[index(Param::kE2)] = 0.0;
          p[index(Param::kRadius)] = r;
          p[index(Param::kBulgeA)] = bulge;
          p[index(Param::kDiscA)] = 1 - bulge;
          ASSERT_EQ(corrected.renderer->render(p, a), RenderStatus::kOk);
          ASSERT_EQ(raw.renderer->render(p, c), RenderStatus::kOk);
          ASSERT_EQ(wide.renderer->render(p, b), RenderStatus::kOk);
          worst = std::max(worst, worst_over_peak(a, b));
          worst_raw = std::max(worst_raw, worst_over_peak(c, b));
        }
      std::printf("N %d, %s r_e %.1f |e| <= 0.7: wrapped light %.2e of the peak subtracted, %.2e left\n", n,
                  bulge > 0 ? "bulge" : "disc ", r, worst_raw, worst);
      // Left over: the far wings' blur beyond second order (the PSF's second moment, 3.9 px^2 per
      // axis for Moffat beta = 3, against the wing's width across the major axis) and the
      // nodes' interpolation, slowest for |e| = 0.7 (its complex singularities lie close to the
      // stamp along the minor axis). Measured at N = 96, 12 nodes: bulges 3.7e-6 (r_e 3), 2.7e-5
      // (r_e 8), discs 3.8e-8 (r_e 3), 3.8e-5 (r_e 8) of the peak.
      EXPECT_LT(worst, 0.05 * worst_raw + 1e-7) << (bulge > 0 ? "bulge" : "disc") << " r_e " << r;
      if (r <= 3.0) {
        EXPECT_LT(worst, 5e-6) << (bulge > 0 ? "bulge" : "disc") << " r_e " << r;
      }
    }
}

// A noise-free fit of one GalSim case with the Levenberg-Marquardt solver over this renderer
// (test-only harness: the Fitter is wired to the upsampled renderer), unit weights, the paper's
// seven free parameters from a perturbed start: e is recovered to 1e-5.
class ExactFitProblem : public LeastSquaresProblem {
 public:
  ExactFitProblem(ExactRenderer& r, const std::vector<double>& data, const ParamVector& fixed)
      : r_(r), data_(data), p_(fixed), model_(data.size()), jac_(7, std::vector<double>(data.size())) {
    for (int k = 0; k < 7; ++k) cols_[k] = jac_[k].data();
  }
  int num_pixels() const override { return static_cast<int>(data_.size()); }
  bool chi2(const LmVector& x, double* c) override {
    if (r_.render(full(x), model_) != RenderStatus::kOk) return false;
    *c = 0;
    for (std::size_t i = 0; i < data_.size(); ++i) *c += (data_[i] - model_[i]) * (data_[i] - model_[i]);
    return true;
  }
  bool normal_equations(const LmVector& x, double* c, LmMatrix* alpha, LmVector* beta) override {
    if (r_.render_with_jacobian(full(x), kFree, model_, cols_) != RenderStatus::kOk) return false;
    *c = 0;
    alpha->setZero(7, 7);
    beta->setZero(7);
    for (std::size_t i = 0; i < data_.size(); ++i) {
      const double d = data_[i] - model_[i];
      *c += d * d;
      for (int a = 0; a < 7; ++a) {
        (*beta)(a) += jac_[a][i] * d;
        for (int b = 0; b <= a; ++b) (*alpha)(a, b) += jac_[a][i] * jac_[b][i];
      }
    }
    for (int a = 0; a < 7; ++a)
      for (int b = 0; b < a; ++b) (*alpha)(b, a) = (*alpha)(a, b);
    return true;
  }
  ParamVector full(const LmVector& x) const {
    ParamVector p = p_;
    for (int k = 0; k < 7; ++k) p[index(kFree[k])] = x(k);
    return p;
  }
  static constexpr std::array<Param, 7> kFree = {Param::kX0, Param::kY0, Param::kE1, Param::kE2,
                                                 Param::kRadius, Param::kBulgeA, Param::kDiscA};

 private:
  ExactRenderer& r_;
  const std::vector<double>& data_;
  ParamVector p_;
  std::vector<double> model_;
  std::vector<std::vector<double>> jac_;
  std::array<double*, 7> cols_;
};

TEST(ExactRenderer, NoiseFreeFitRecoversEllipticity) {
  const auto cases = testing::load_render_cases();
  for (int id : {2, 9, 13, 16, 20}) {
    const testing::RenderCase& c = cases[static_cast<std::size_t>(id)];
    ASSERT_EQ(c.id, id);
    ExactSetup s(c.stamp, testing::case_psf(c));
    const ParamVector truth = testing::case_truth(c);
    ExactFitProblem problem(*s.renderer, c.image, truth);
    LmVector x0(7);
    for (int k = 0; k < 7; ++k) x0(k) = truth[index(ExactFitProblem::kFree[k])];
    x0(0) += 0.3, x0(1) -= 0.2, x0(2) += 0.05, x0(3) -= 0.04, x0(4) *= 1.15, x0(5) *= 0.8, x0(6) *= 1.2;
    LmOptions lm;
    lm.eps4 = 0;  // noise-free: run to machine precision (no progress) or the iteration limit
    lm.max_iterations = 40;
    const LmSummary r = levenberg_marquardt(problem, x0, lm);
    const double de1 = r.x(2) - c.e1, de2 = r.x(3) - c.e2;
    std::printf("case %d: %s after %d iterations, e - e_true = (%.1e, %.1e), r / r_true - 1 = %.1e\n", id,
                ToString(r.reason), r.iterations, de1, de2, r.x(4) / c.hlr - 1);
    EXPECT_LT(std::abs(de1), 1e-5) << "case " << id;
    EXPECT_LT(std::abs(de2), 1e-5) << "case " << id;
  }
}

}  // namespace
}  // namespace stampede
