// Tests for metacalibration on cutouts (engine/metacal/metacal_fitter, an object's epochs with
// their WCS): on noise-free cutouts with random WCS Jacobians and PSFs the response is the sky's
// (the derivative of the reduced-shear transformation at the galaxy's e, in (u, v)); cutouts with
// masked pixels are left out, an object that cannot be calibrated is a flagged row that says why,
// and with weighted moments (wmom) R is the moments' own response to a shear of the galaxy on the
// sky; wmom's and bd's errors and S/N match the scatter over noise; an object's row depends on it
// alone, and a cutout in its pixel grid is weighed as a stamp where nothing is masked.
#include "engine/metacal/metacal_fitter.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <complex>
#include <cstdio>
#include <random>
#include <vector>

#include "engine/sim/sim_renderer.hpp"
#include "kernels/math/lensing.hpp"
#include "support/sky_epochs.hpp"

namespace stampede {
namespace {

constexpr int kBox = 48;
constexpr std::uint32_t kFailure = 1u << 30;

FitterOptions options() {
  FitterOptions o;
  o.renderer = RendererKind::kExact;
  return o;
}

MetacalOptions metacal(bool fixnoise) {
  MetacalOptions m;
  m.enabled = true;
  m.fixnoise = fixnoise;
  return m;
}

struct Cutout {
  PixelFrame frame;
  PsfModel psf;
  std::vector<double> pixels, weight;
};

using testing::random_frame;

// An exponential disc of (e1, e2) and half-light radius r (arcsec) at the frame's reference.
std::vector<Cutout> cutouts(double e1, double e2, double r, std::uint32_t seed, int n = 4) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Cutout> out(n);
  for (Cutout& c : out) {
    c.frame = random_frame(rng);
    c.psf.kind = PsfKind::kMoffat;
    c.psf.moffat = {3.0, (0.95 + 0.1 * u(rng)) / 0.263, 0.03 * u(rng), 0.03 * u(rng), 0.0};
    const testing::PixelEllipse q = testing::sky_to_pixel(e1, e2, r, 0, 0, c.frame);
    const SimComponent disc{1.0, 1000.0, q.radius, q.e1, q.e2, q.x, q.y};
    c.pixels.resize(kBox * kBox);
    SimWorkspace ws;
    SimRenderer(c.psf, SimRenderer::Options{}).render({&disc, 1}, kBox, c.pixels, ws);
    c.weight.assign(kBox * kBox, 1.0);
  }
  return out;
}

std::vector<Observation> epochs(const std::vector<Cutout>& cs) {
  std::vector<Observation> out;
  for (const Cutout& c : cs)
    out.push_back({.pixels = c.pixels, .weight = c.weight, .box_size = kBox, .frame = c.frame, .psf_model = &c.psf});
  return out;
}

// The response of e to a reduced shear g at g = 0, e' = (e + g) / (1 + g* e) to first order:
// e' = e + g - e^2 g*, so R = [[1 - e1^2 + e2^2, -2 e1 e2], [-2 e1 e2, 1 + e1^2 - e2^2]].
TEST(MetacalFitterCutouts, NoiseFreeResponseIsTheSkysShearResponse) {
  MetacalOptions bd = metacal(false);
  bd.model = MetacalModel::kBulgeDisc;  // a fit of the disc: its R is the reduced-shear transformation's
  MetacalFitter fitter(options(), bd);
  for (const auto& [e1, e2] : {std::pair{0.3, -0.2}, std::pair{-0.1, 0.45}}) {
    const std::vector<Cutout> cs = cutouts(e1, e2, 0.6, 7);
    FitResult noshear;
    MetacalRecord rec;
    std::uint32_t flags = 0;
    std::string problem;
    fitter.fit(epochs(cs), 1, kFailure, &noshear, &rec, &flags, &problem);
    ASSERT_EQ(flags, 0u) << problem;
    ASSERT_EQ(noshear.status, FitStatus::kOk);
    EXPECT_EQ(fitter.epochs_used(), 4);
    const double r11 = 1 - e1 * e1 + e2 * e2, r12 = -2 * e1 * e2, r22 = 1 + e1 * e1 - e2 * e2;
    const double de = std::max(std::abs(noshear.params[index(Param::kE1)] - e1), std::abs(noshear.params[index(Param::kE2)] - e2));
    const double dr = std::max({std::abs(rec.r11 - r11), std::abs(rec.r12 - r12), std::abs(rec.r21 - r12), std::abs(rec.r22 - r22)});
    std::printf("e (%+.2f, %+.2f): max |e - e_true| %.2e, max |R - R_true| %.2e (R11 %.6f, R22 %.6f); Gamma %.3f\"\n", e1,
                e2, de, dr, rec.r11, rec.r22, fitter.gamma_fwhm());
    // The bulge + disc model fits the reconvolved disc exactly but for the images' floors (~1e-5
    // of the peak): e measured within 1e-6; R within 4e-5, the central difference's step^2 term
    // (step 0.01) included.
    EXPECT_NEAR(noshear.params[index(Param::kE1)], e1, 5e-6);
    EXPECT_NEAR(noshear.params[index(Param::kE2)], e2, 5e-6);
    EXPECT_NEAR(rec.r11, r11, 1e-4);
    EXPECT_NEAR(rec.r12, r12, 1e-4);
    EXPECT_NEAR(rec.r21, r12, 1e-4);
    EXPECT_NEAR(rec.r22, r22, 1e-4);
    EXPECT_GT(fitter.gamma_fwhm(), 1.0);  // arcsec: wider than every PSF (0.85-1.05")
    EXPECT_LT(fitter.gamma_fwhm(), 1.3);
  }
}

TEST(MetacalFitterCutouts, CutoutsWithMaskedPixelsAreLeftOut) {
  MetacalFitter fitter(options(), metacal(true));
  std::vector<Cutout> cs = cutouts(0.2, 0.1, 0.6, 11);
  cs[1].weight[100] = 0;
  FitResult noshear;
  MetacalRecord rec;
  std::uint32_t flags = 0;
  std::string problem;
  fitter.fit(epochs(cs), 2, kFailure, &noshear, &rec, &flags, &problem);
  EXPECT_EQ(flags, 0u) << problem;
  EXPECT_EQ(fitter.epochs_used(), 3);
  EXPECT_TRUE(std::isfinite(rec.r11));
  // Every cutout masked somewhere: all are used, masked pixels zeroed, and the row flagged.
  for (Cutout& c : cs) c.weight[200] = 0;
  flags = 0, problem.clear();
  fitter.fit(epochs(cs), 2, kFailure, &noshear, &rec, &flags, &problem);
  EXPECT_EQ(flags & kFailure, kFailure);
  EXPECT_EQ(fitter.epochs_used(), 4);
  EXPECT_NE(problem.find("every cutout has masked pixels"), std::string::npos) << problem;
}

TEST(MetacalFitterCutouts, APsfItCannotDeconvolveIsAFlaggedRowNamingTheCutout) {
  MetacalFitter fitter(options(), metacal(true));
  std::vector<Cutout> cs = cutouts(0.2, 0.1, 0.6, 13, 2);
  cs[1].psf.kind = PsfKind::kAiry;
  FitResult noshear;
  MetacalRecord rec;
  std::uint32_t flags = 0;
  std::string problem;
  fitter.fit(epochs(cs), 3, kFailure, &noshear, &rec, &flags, &problem);
  EXPECT_EQ(flags & kFailure, kFailure);
  EXPECT_EQ(noshear.status, FitStatus::kPsfFailure);
  EXPECT_NE(problem.find("cutout 1"), std::string::npos) << problem;
  EXPECT_TRUE(std::isnan(rec.r11));
  EXPECT_TRUE(std::isnan(fitter.gamma_fwhm()));
}

// metacal_model = wmom on cutouts: the response metacal measures is the moments' true response to
// a shear of the galaxy on the sky, the derivative of the noshear e of cutouts drawn of the
// galaxy sheared by +-step (same frames, PSFs and so Gamma).
TEST(MetacalFitterCutouts, WeightedMomentsResponseIsTheirResponseToASkyShear) {
  MetacalOptions mo = metacal(false);
  mo.model = MetacalModel::kWeightedMoments;
  MetacalFitter fitter(options(), mo);
  const double e1 = 0.3, e2 = -0.2, step = mo.step;
  auto measure = [&](double g1, double g2, MetacalRecord* rec) {
    const std::complex<double> e = kernels::lens_ellipticity({e1, e2}, {g1, g2});
    const std::vector<Cutout> cs = cutouts(e.real(), e.imag(), 0.6, 7);
    FitResult noshear;
    MetacalRecord r;
    std::uint32_t flags = 0;
    std::string problem;
    fitter.fit(epochs(cs), 1, kFailure, &noshear, rec ? rec : &r, &flags, &problem);
    EXPECT_EQ(flags, 0u) << problem;
    EXPECT_EQ(noshear.status, FitStatus::kOk);
    EXPECT_EQ(fitter.epochs_used(), 4);
    return std::pair{noshear.params[index(Param::kE1)], noshear.params[index(Param::kE2)]};
  };
  MetacalRecord rec;
  measure(0, 0, &rec);
  const auto p1 = measure(step, 0, nullptr), m1 = measure(-step, 0, nullptr);
  const auto p2 = measure(0, step, nullptr), m2 = measure(0, -step, nullptr);
  const double r11 = (p1.first - m1.first) / (2 * step), r21 = (p1.second - m1.second) / (2 * step);
  const double r12 = (p2.first - m2.first) / (2 * step), r22 = (p2.second - m2.second) / (2 * step);
  std::printf("wmom on 4 cutouts: R metacal [[%.8f %.8f] [%.8f %.8f]], sheared galaxy [[%.8f %.8f] [%.8f %.8f]]; weight "
              "%.3f\"\n", rec.r11, rec.r12, rec.r21, rec.r22, r11, r12, r21, r22, fitter.weight_fwhm());
  EXPECT_GT(rec.r11, 0.2);  // a weighted-moments response, well below 1 for a PSF-sized weight
  // Both are central differences at the same step, of the same estimator on the same Gamma: they
  // agree to ~2e-7 (the images' floors), where a wrong frame or weight would be off at 1e-2.
  EXPECT_NEAR(rec.r11, r11, 2e-6);
  EXPECT_NEAR(rec.r12, r12, 2e-6);
  EXPECT_NEAR(rec.r21, r21, 2e-6);
  EXPECT_NEAR(rec.r22, r22, 2e-6);
}

// The scatter over noise realisations against the stated errors and S/N: sd(e1)/err, sd(e2)/err and
// the flux's measured S/N over the stated one, for a disc seen in four cutouts at S/N ~30; the
// same for e's robust sd (1.4826 median absolute deviation), and the realisations whose e1 or e2
// lies beyond 4 stated errors of the mean.
struct ScatterRatios {
  double e1 = NAN, e2 = NAN, snr = NAN, stated_snr = NAN, e1_robust = NAN, e2_robust = NAN;
  int beyond_4 = 0;
};

double robust_sd(std::vector<double> v) {
  auto median = [](std::vector<double>& x) {
    std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
    return x[x.size() / 2];
  };
  const double m = median(v);
  for (double& x : v) x = std::abs(x - m);
  return 1.4826 * median(v);
}
ScatterRatios scatter_over_noise(MetacalModel model, double dilation, int n) {
  const std::vector<Cutout> clean = cutouts(0.2, -0.1, 0.5, 11);
  // S/N ~30 over the four cutouts: sigma = sqrt(sum over cutouts of sum I^2) / 30.
  double power = 0;
  for (const Cutout& c : clean)
    for (double v : c.pixels) power += v * v;
  const double sigma = std::sqrt(power) / 30;
  MetacalOptions mo = metacal(true);
  mo.model = model;
  mo.psf_dilation = dilation;
  MetacalFitter fitter(options(), mo);
  std::vector<Cutout> noisy = clean;
  for (Cutout& c : noisy) c.weight.assign(kBox * kBox, 1 / (sigma * sigma));
  double s1 = 0, s11 = 0, s2 = 0, s22 = 0, sf = 0, sff = 0, err1 = 0, err2 = 0, snr = 0;
  int used = 0;
  std::vector<double> v1, v2;
  for (int k = 0; k < n; ++k) {
    std::mt19937 rng(4303 + k);
    std::normal_distribution<double> z(0, sigma);
    for (std::size_t c = 0; c < noisy.size(); ++c)
      for (std::size_t i = 0; i < noisy[c].pixels.size(); ++i) noisy[c].pixels[i] = clean[c].pixels[i] + z(rng);
    FitResult r;
    MetacalRecord rec;
    std::uint32_t flags = 0;
    std::string problem;
    fitter.fit(epochs(noisy), k, kFailure, &r, &rec, &flags, &problem);
    if (r.status != FitStatus::kOk) continue;
    const double e1 = r.params[index(Param::kE1)], e2 = r.params[index(Param::kE2)];
    s1 += e1, s11 += e1 * e1, s2 += e2, s22 += e2 * e2, sf += r.flux, sff += r.flux * r.flux;
    err1 += r.e1_err, err2 += r.e2_err, snr += r.snr;
    v1.push_back(e1), v2.push_back(e2);
    ++used;
  }
  EXPECT_GT(used, 0.99 * n);
  auto sd = [&](double s, double ss) { return std::sqrt((ss - s * s / used) / (used - 1)); };
  ScatterRatios out{sd(s1, s11) / (err1 / used), sd(s2, s22) / (err2 / used), (sf / used) / sd(sf, sff) / (snr / used),
                    snr / used, robust_sd(v1) / (err1 / used), robust_sd(v2) / (err2 / used)};
  for (int k = 0; k < used; ++k)
    out.beyond_4 += std::abs(v1[k] - s1 / used) > 4 * err1 / used || std::abs(v2[k] - s2 / used) > 4 * err2 / used;
  return out;
}

// Issue 43 item 3 on four cutouts (random WCS and PSFs, each with its own weight map): the
// noshear row's e errors and S/N against the scatter over independent noise realisations (the
// cutouts' noise and the fixnoise fields drawn afresh), with the default Gamma and a 1.5x one.
// Before, they took the images' noise as white: sd / error ~1.3 and ~4. 800 realisations measure a
// standard deviation to ~2.5 %; the bound is issue 43's 0.9 .. 1.1.
TEST(MetacalFitterCutouts, WmomErrorsAndSnrMatchTheScatterOverNoise) {
  for (double dilation : {0.0, 1.5}) {
    const ScatterRatios r = scatter_over_noise(MetacalModel::kWeightedMoments, dilation, 800);
    std::printf("4 cutouts, wmom, dilation %.1f: sd(e1)/err %.3f, sd(e2)/err %.3f, S/N measured/stated %.3f (stated %.1f)\n",
                dilation, r.e1, r.e2, r.snr, r.stated_snr);
    EXPECT_NEAR(r.e1, 1.0, 0.1) << dilation;
    EXPECT_NEAR(r.e2, 1.0, 0.1) << dilation;
    EXPECT_NEAR(r.snr, 1.0, 0.1) << dilation;
  }
}

// The same for the bd fit, whose errors are its curvature's scaled by equivalent linear estimators
// (metacal_noise.hpp), chosen on single stamps: across cutouts with their own frames and PSFs they
// match the core of the scatter (its robust sd). The plain sd is not asserted: a few realisations
// of this nonlinear fit land far out (heavy tails no single error describes), nor is the flux's
// S/N, which the bd model's matched-filter snr does not state for a disc this small against the
// PSF (both measured in docs/metacal.md, "4-epoch MEDS tiles by noise pairs").
TEST(MetacalFitterCutouts, BdErrorsMatchTheCoreOfTheScatterOverNoise) {
  const ScatterRatios r = scatter_over_noise(MetacalModel::kBulgeDisc, 0.0, 300);
  std::printf("4 cutouts, bd: robust sd(e1)/err %.3f, sd(e2)/err %.3f (sd %.3f, %.3f), beyond 4 errors %d of 300, "
              "flux S/N measured/stated %.3f (stated %.1f)\n",
              r.e1_robust, r.e2_robust, r.e1, r.e2, r.beyond_4, r.snr, r.stated_snr);
  EXPECT_NEAR(r.e1_robust, 1.0, 0.1);
  EXPECT_NEAR(r.e2_robust, 1.0, 0.1);
}


// A double's bits: equal for the same value, NaN included (wmom leaves the model's parameters NaN).
std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

void expect_same_rows(const FitResult& a, const MetacalRecord& ra, const FitResult& b, const MetacalRecord& rb) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.flags, b.flags);
  for (int p = 0; p < kNumParams; ++p) EXPECT_EQ(bits(a.params[p]), bits(b.params[p])) << "parameter " << p;
  EXPECT_EQ(bits(a.snr), bits(b.snr));
  EXPECT_EQ(bits(a.e1_err), bits(b.e1_err));
  EXPECT_EQ(bits(ra.r11), bits(rb.r11));
  EXPECT_EQ(bits(ra.r12), bits(rb.r12));
  EXPECT_EQ(bits(ra.r21), bits(rb.r21));
  EXPECT_EQ(bits(ra.r22), bits(rb.r22));
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(bits(ra.e1[k]), bits(rb.e1[k])) << "sheared image " << k;
    EXPECT_EQ(bits(ra.e2[k]), bits(rb.e2[k])) << "sheared image " << k;
  }
}

// A grid stamp is one epoch in its pixel grid weighed uniformly (StampFitter), a cutout by its
// data's mask: the two rules differ only at masked pixels, so on a clean cutout in its pixel grid
// they give the same rows bit for bit (noshear fit, R and the sheared fits), for the model fit and
// for weighted moments, with and without fixnoise.
TEST(MetacalFitterCutouts, OneCleanCutoutInItsPixelGridIsWeighedAsAStamp) {
  const std::vector<Cutout> clean = cutouts(0.2, -0.1, 0.6, 17, 1);
  Cutout stamp = clean[0];
  stamp.frame = PixelFrame{};  // the pixel grid, positions from its origin as a grid stamp's
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  const double sigma = 2.0;
  Cutout noisy = stamp;
  for (double& v : noisy.pixels) v += sigma * normal(rng);
  noisy.weight.assign(noisy.weight.size(), 1 / (sigma * sigma));
  for (MetacalModel model : {MetacalModel::kBulgeDisc, MetacalModel::kWeightedMoments})
    for (const Cutout* c : {&stamp, &noisy}) {
      const bool with_noise = c == &noisy;
      MetacalOptions mo = metacal(with_noise);
      mo.model = model;
      SCOPED_TRACE(::testing::Message() << "model " << static_cast<int>(model) << (with_noise ? ", noisy" : ", weight 1"));
      const Observation one{
          .pixels = c->pixels, .weight = c->weight, .box_size = kBox, .frame = c->frame, .psf_model = &c->psf};
      FitResult fits[2];
      MetacalRecord records[2];
      std::uint32_t flags[2] = {0, 0};
      std::string problems[2];
      const MetacalFitter::ImageWeight rules[2] = {MetacalFitter::ImageWeight::kUniform, MetacalFitter::ImageWeight::kDataMask};
      for (int i = 0; i < 2; ++i) {
        MetacalFitter fitter(options(), mo, FftPlanning::kEstimate, rules[i]);
        fitter.fit({&one, 1}, 9, kFailure, &fits[i], &records[i], &flags[i], &problems[i]);
      }
      ASSERT_EQ(fits[0].status, FitStatus::kOk) << problems[0];
      EXPECT_EQ(flags[0], 0u);
      EXPECT_EQ(flags[1], flags[0]) << problems[1];
      expect_same_rows(fits[0], records[0], fits[1], records[1]);
    }
}

// The fitter keeps Gamma while the epochs' PSFs and frames are the last object's: an object's row
// is the same whatever was fitted before it (so any thread count and batch gives the same table).
TEST(MetacalFitterCutouts, AnObjectsRowDependsOnItAlone) {
  for (MetacalModel model : {MetacalModel::kBulgeDisc, MetacalModel::kWeightedMoments}) {
    MetacalOptions mo = metacal(true);
    mo.model = model;
    std::vector<Cutout> a = cutouts(0.2, 0.1, 0.6, 21), b = cutouts(-0.1, 0.3, 0.7, 22);
    for (std::vector<Cutout>* cs : {&a, &b})
      for (Cutout& c : *cs) c.weight.assign(c.weight.size(), 4.0);
    FitResult first, again, fresh, other;
    MetacalRecord first_rec, again_rec, fresh_rec, other_rec;
    std::uint32_t flags = 0;
    std::string problem;
    MetacalFitter fitter(options(), mo);
    fitter.fit(epochs(a), 5, kFailure, &first, &first_rec, &flags, &problem);
    fitter.fit(epochs(b), 6, kFailure, &other, &other_rec, &flags, &problem);
    fitter.fit(epochs(a), 5, kFailure, &again, &again_rec, &flags, &problem);
    fitter.fit(epochs(a), 5, kFailure, &again, &again_rec, &flags, &problem);  // Gamma kept
    MetacalFitter(options(), mo).fit(epochs(a), 5, kFailure, &fresh, &fresh_rec, &flags, &problem);
    ASSERT_EQ(first.status, FitStatus::kOk) << problem;
    EXPECT_EQ(flags, 0u) << problem;
    EXPECT_NE(bits(first_rec.r11), bits(other_rec.r11));
    expect_same_rows(first, first_rec, again, again_rec);
    expect_same_rows(first, first_rec, fresh, fresh_rec);
  }
}

}  // namespace
}  // namespace stampede
