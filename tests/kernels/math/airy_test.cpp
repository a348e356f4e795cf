// Tests kernels/math/airy: the Airy disc's intensity is half its peak at half the FWHM constant.
#include "kernels/math/airy.hpp"

#include <gtest/gtest.h>
#include <math.h>  // j1 (glibc)

#include <numbers>

namespace stampede::kernels {
namespace {

double airy_intensity(double x_over_lambda_over_d) {
  const double t = std::numbers::pi * x_over_lambda_over_d;
  const double a = 2 * ::j1(t) / t;
  return a * a;
}

TEST(AiryFwhm, HalfMaximumAtHalfTheConstant) {
  const double r = 0.5 * kAiryFwhmOverLambdaOverD;
  EXPECT_NEAR(airy_intensity(r), 0.5, 1e-14);
  // The slope there is ~-1.3 per lambda/D, so a constant off by 1e-12 would miss by ~1e-12.
  EXPECT_GT(airy_intensity(r - 1e-9), 0.5);
  EXPECT_LT(airy_intensity(r + 1e-9), 0.5);
}

}  // namespace
}  // namespace stampede::kernels
