// PSF models: the one kind name/parse pair, validation, and the invariants of their real- and
// Fourier-space values (unit flux, k(0) = 1, k_value the transform of x_value).
#include "engine/model/psf_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <memory>
#include <utility>
#include <vector>

namespace stampede {
namespace {

TEST(PsfKind, NamesParseBack) {
  for (PsfKind k : {PsfKind::kMoffat, PsfKind::kAiry, PsfKind::kImage}) {
    PsfKind parsed;
    ASSERT_TRUE(parse_psf_kind(psf_kind_name(k), &parsed));
    EXPECT_EQ(parsed, k);
  }
  PsfKind k;
  EXPECT_TRUE(parse_psf_kind("AIRY", &k));
  EXPECT_EQ(k, PsfKind::kAiry);
  EXPECT_FALSE(parse_psf_kind("moffat_catalog", &k));  // a source of Moffats, not a kind
  // The Gaussian is metacalibration's reconvolution PSF, named but not an input PSF.
  EXPECT_STREQ(psf_kind_name(PsfKind::kGaussian), "gaussian");
  EXPECT_FALSE(parse_psf_kind("gaussian", &k));
}

// The direct Fourier sums at ks[i] of x_value sampled on a grid of half-width `half` pixels (the
// flux at k = 0).
std::vector<std::complex<double>> sampled_transform(const PsfModel& m, double half, double step,
                                                    const std::vector<std::pair<double, double>>& ks) {
  std::vector<std::complex<double>> out(ks.size());
  const int n = static_cast<int>(std::round(half / step));
  for (int j = -n; j <= n; ++j)
    for (int i = -n; i <= n; ++i) {
      const double x = i * step, y = j * step, v = m.x_value(x, y) * step * step;
      for (std::size_t q = 0; q < ks.size(); ++q) out[q] += v * std::polar(1.0, -(ks[q].first * x + ks[q].second * y));
    }
  return out;
}

TEST(PsfModel, AnalyticValuesAreConsistent) {
  const PsfModel moffat = PsfModel::Moffat({3.5, 2.5, 0.1, -0.05, 0.0});
  const PsfModel truncated = PsfModel::Moffat({3.0, 2.5, 0.0, 0.08, 5.0});
  const PsfModel airy = PsfModel::Airy({2.0, 0.0});
  const PsfModel gaussian = PsfModel::Gaussian({3.0, 0.12, -0.07});
  // On a grid fine against the profiles (step 0.1 px: the aliases at 2 pi / step are negligible),
  // 80 px wide. Tolerances: the untruncated Moffat loses ~1e-6 beyond 40 px; the truncated one's
  // edge is a step, which a grid sums to O(step) of the light there (1.2e-4 measured); an Airy
  // disc's r^-3 wings leave ~2L/(pi^2 R) = 1.0e-2 outside R = 40 px (the square holds a little
  // more), so its flux is bracketed and its transform, smooth, compared to 2e-3.
  const struct {
    const PsfModel* model;
    const char* what;
    double tol;
  } cases[] = {{&moffat, "moffat", 1e-5}, {&truncated, "truncated moffat", 3e-4}, {&airy, "airy", 2e-3},
               {&gaussian, "gaussian", 1e-9}};
  const std::vector<std::pair<double, double>> ks = {{0.0, 0.0}, {0.4, 0.0}, {0.3, -0.5}, {0.0, 0.9}};
  for (const auto& c : cases) {
    const PsfModel& m = *c.model;
    EXPECT_NEAR(std::abs(m.k_value(0, 0)), 1.0, 1e-9) << c.what;
    const auto sums = sampled_transform(m, 40.0, 0.1, ks);
    const double flux = sums[0].real();
    if (&m == &airy) {
      EXPECT_GT(flux, 1.0 - 2.0 * 2.0 / (M_PI * M_PI * 40.0)) << c.what;
      EXPECT_LT(flux, 1.0) << c.what;
    } else {
      EXPECT_NEAR(flux, 1.0, c.tol) << c.what;
    }
    for (std::size_t q = 1; q < ks.size(); ++q)
      EXPECT_NEAR(std::abs(sums[q] - m.k_value(ks[q].first, ks[q].second)), 0.0, c.tol)
          << c.what << " at (" << ks[q].first << ", " << ks[q].second << ")";
  }
  EXPECT_TRUE(std::isnan(PsfModel::Airy({2.0, 0.3}).k_value(0.1, 0).real()));  // no obscured transform
  EXPECT_EQ(moffat.fwhm(), 2.5);
  EXPECT_EQ(moffat.e1(), 0.1);
  EXPECT_EQ(airy.e2(), 0.0);
  EXPECT_EQ(gaussian.fwhm(), 3.0);
  EXPECT_EQ(gaussian.e1(), 0.12);
  EXPECT_TRUE(gaussian == PsfModel::Gaussian({3.0, 0.12, -0.07}));
  EXPECT_FALSE(gaussian == PsfModel::Gaussian({3.0, 0.12, 0.07}));
  // Half the peak at half the FWHM from the centre (round).
  const PsfModel round = PsfModel::Gaussian({3.0, 0.0, 0.0});
  EXPECT_NEAR(round.x_value(1.5, 0) / round.x_value(0, 0), 0.5, 1e-4);
  std::string why;
  EXPECT_FALSE(PsfModel::Gaussian({0.0, 0.0, 0.0}).IsValid(&why));
  EXPECT_FALSE(PsfModel::Gaussian({2.0, 0.8, 0.7}).IsValid(&why));
}

TEST(PsfModel, ImageTransformMatchesItsSamples) {
  // A point-sampled Moffat, oversampled 3x: its transform is the analytic one below Nyquist.
  const PsfModel moffat = PsfModel::Moffat({3.0, 2.85, 0.0, 0.0, 0.0});
  auto img = std::make_shared<PsfImage>();
  img->nx = img->ny = 121;
  img->oversampling = 3;
  img->pixel_integrated = false;
  for (int j = 0; j < 121; ++j)
    for (int i = 0; i < 121; ++i) img->pixels.push_back(moffat.x_value((i - 60) / 3.0, (j - 60) / 3.0));
  const PsfModel image = PsfModel::Image(img);
  EXPECT_NEAR(image.k_value(0, 0).real(), 1.0, 1e-12);
  EXPECT_NEAR(std::abs(image.k_value(0.7, -0.4) - moffat.k_value(0.7, -0.4)), 0.0, 2e-3);
  EXPECT_EQ(image.k_value(3.2 * M_PI, 0), std::complex<double>(0.0));  // beyond its Nyquist frequency
  EXPECT_TRUE(std::isnan(image.x_value(0, 0)));
  EXPECT_TRUE(std::isnan(image.fwhm()));
  EXPECT_TRUE(image == PsfModel::Image(img));
  EXPECT_FALSE(image == PsfModel::Image(std::make_shared<PsfImage>(*img)));
}

TEST(PsfModel, InvalidModelsNameTheOption) {
  std::string why;
  EXPECT_FALSE(PsfModel::Moffat({0.8, 2.5, 0, 0, 0}).IsValid(&why));
  EXPECT_NE(why.find("psf_beta = 0.8"), std::string::npos) << why;
  EXPECT_FALSE(PsfModel::Airy({2.0, 1.0}).IsValid(&why));
  EXPECT_NE(why.find("airy_obscuration = 1"), std::string::npos) << why;
  EXPECT_FALSE(PsfModel::Image(nullptr).IsValid(&why));
  EXPECT_NE(why.find("needs a PSF image"), std::string::npos) << why;
}

}  // namespace
}  // namespace stampede
