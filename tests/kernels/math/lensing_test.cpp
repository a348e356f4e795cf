// Tests kernels/math/lensing: the reduced-shear lensing formula e_obs = (e + g) / (1 + conj(g) e).
#include "kernels/math/lensing.hpp"

#include <gtest/gtest.h>

#include <complex>

namespace stampede::kernels {
namespace {

using C = std::complex<double>;

TEST(LensEllipticity, ZeroShearIsTheIdentity) {
  for (C e : {C(0, 0), C(0.3, -0.2), C(-0.7, 0.1), C(0.05, 0.9)}) EXPECT_EQ(lens_ellipticity(e, 0.0), e);
}

TEST(LensEllipticity, RoundSourceTakesTheShear) {
  for (C g : {C(0.02, 0.01), C(-0.05, 0.03), C(0.3, -0.4)}) EXPECT_EQ(lens_ellipticity(0.0, g), g);
}

TEST(LensEllipticity, HandComputedCase) {
  // e = 0.3 + 0.1i, g = 0.05 - 0.02i: conj(g) e = (0.05 + 0.02i)(0.3 + 0.1i) = 0.013 + 0.011i,
  // e + g = 0.35 + 0.08i; (0.35 + 0.08i) / (1.013 + 0.011i)
  //   = (0.35 * 1.013 + 0.08 * 0.011 + i (0.08 * 1.013 - 0.35 * 0.011)) / (1.013^2 + 0.011^2)
  //   = (0.35543 + 0.077190i) / 1.026290.
  const C got = lens_ellipticity(C(0.3, 0.1), C(0.05, -0.02));
  EXPECT_NEAR(got.real(), 0.35543 / 1.02629, 1e-15);
  EXPECT_NEAR(got.imag(), 0.07719 / 1.02629, 1e-15);
}

TEST(LensEllipticity, OppositeShearUndoesIt) {
  // Reduced shear composes as a Möbius map: lensing by g then by -g returns the source.
  const C e(0.4, -0.25), g(0.04, 0.03);
  const C back = lens_ellipticity(lens_ellipticity(e, g), -g);
  EXPECT_NEAR(back.real(), e.real(), 1e-15);
  EXPECT_NEAR(back.imag(), e.imag(), 1e-15);
}

}  // namespace
}  // namespace stampede::kernels
