// The pixel-integrated samples of an analytic PSF (engine/model/pixelated_psf): unit flux, centred
// on the middle pixel, each sample the pixel's mean.
#include "engine/model/pixelated_psf.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

namespace stampede {
namespace {

TEST(PixelatedPsf, SamplesHoldTheFluxAboutTheMiddlePixel) {
  const PsfModel psf = PsfModel::Gaussian({3.0, 0.1, -0.05});
  const int n = 31;
  std::vector<double> out(n * n);
  pixelated_psf(psf, n, 5, out);
  EXPECT_NEAR(std::accumulate(out.begin(), out.end(), 0.0), 1.0, 1e-6);  // the 5 x 5 midpoint rule: ~1e-7
  double sx = 0, sy = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) sx += (x - 15) * out[y * n + x], sy += (y - 15) * out[y * n + x];
  EXPECT_NEAR(sx, 0.0, 1e-12);
  EXPECT_NEAR(sy, 0.0, 1e-12);
  // A pixel 3.6 sigma out against its mean by a finer rule: the 5 x 5 midpoint rule is 0.36 % low
  // there (its error is the profile's curvature over the sub-pixel, h^2 / 24 f'').
  double fine = 0;
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 40; ++i) fine += psf.x_value(3 - 0.5 + (i + 0.5) / 40, -2 - 0.5 + (j + 0.5) / 40);
  EXPECT_NEAR(out[(15 - 2) * n + 15 + 3] / (fine / 1600), 1.0, 5e-3);
  // sub = 1: the point value at the pixel's centre.
  pixelated_psf(psf, n, 1, out);
  EXPECT_EQ(out[(15 - 2) * n + 15 + 3], psf.x_value(3, -2));
}

}  // namespace
}  // namespace stampede
