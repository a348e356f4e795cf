// Every instruction-set build of the profile kernels against the scalar reference (the same source
// with double lanes), over a dense grid of shapes, indices, supersampling and region edges.
// Tolerances are multiples of machine epsilon times the image's peak |value|: the builds differ
// only in exp/pow rounding (xsimd's polynomials vs libm, ~1 ulp), amplified where terms cancel.
#include "kernels/profile_render.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "kernels/ellipse.hpp"
#include "kernels/sersic.hpp"
#include "support/image_compare.hpp"

namespace stampede::kernels {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

std::vector<Isa> vector_isas() {
  std::vector<Isa> out;
  for (Isa isa : {Isa::kSse42, Isa::kAvx2, Isa::kAvx512})
    if (profile_kernels_for(isa)) out.push_back(isa);
  return out;
}

SersicDerivativeBlock make_block(double n, double e1, double e2, double r, double x0, double y0, double u_floor) {
  SersicDerivativeBlock d;
  d.shape.x0 = x0;
  d.shape.y0 = y0;
  d.shape.q = ellipse_quadratic(e1, e2, r);
  d.shape.u_floor = u_floor;
  d.shape.b = sersic_b(n);
  d.shape.inv_2n = 0.5 / n;
  d.shape.root = sersic_root_for(n);
  d.amplitude = 3.0;
  ellipse_quadratic_derivatives(e1, e2, r, &d.dq_de1, &d.dq_de2);
  d.du_dr_over_u = -2.0 / r;
  return d;
}

// Worst |a - b| over the reference's peak, in epsilons.
double worst_in_peak_eps(const std::vector<double>& a, const std::vector<double>& b) {
  return testing::worst_over_peak(a, b) / kEps;
}

TEST(ProfileKernelsIsa, ScalarReferenceAndBestAreAvailable) {
  ASSERT_NE(profile_kernels_for(Isa::kScalar), nullptr);
  EXPECT_EQ(profile_kernels_for(Isa::kScalar)->lanes, 1);
  EXPECT_NE(profile_kernels_for(Isa::kBest), nullptr);
  std::printf("best: %s (%d doubles per vector)\n", profile_kernels().name, profile_kernels().lanes);
  Isa parsed;
  EXPECT_TRUE(parse_isa("avx2", &parsed));
  EXPECT_EQ(parsed, Isa::kAvx2);
  EXPECT_FALSE(parse_isa("avx3", &parsed));
}

TEST(ProfileKernelsIsa, EverySetMatchesTheScalarReference) {
  const ProfileKernels& ref = *profile_kernels_for(Isa::kScalar);
  const SubpixelGrid grid{37, -3.2, 0.2};  // odd size: every row has a vector tail
  const GridRegion regions[] = {{0, 37, 0, 37}, {11, 26, 13, 24}, {5, 6, 0, 37}};
  for (Isa isa : vector_isas()) {
    const ProfileKernels& k = *profile_kernels_for(isa);
    double worst_value = 0, worst_derivative = 0;
    int cases = 0;
    for (double n : {1.0, 4.0, 2.5})
      for (double e1 : {-0.6, 0.0, 0.35})
        for (double e2 : {-0.2, 0.5})
          for (double r : {0.3, 1.7})
            for (int ss : {1, 3, 7})
              for (const GridRegion& region : regions) {
                const SersicDerivativeBlock d = make_block(n, e1, e2, r, 0.37, 0.81, ss == 1 ? 0.01 : 0.0);
                const std::size_t npix = 37 * 37;
                std::vector<double> a(npix, 0.5), b(npix, 0.5);  // accumulate onto a non-zero image
                ref.accumulate_value(grid, region, ss, d.shape, 2.0, a.data());
                k.accumulate_value(grid, region, ss, d.shape, 2.0, b.data());
                worst_value = std::max(worst_value, worst_in_peak_eps(b, a));
                std::vector<std::vector<double>> da(6, std::vector<double>(npix, 0.25)), db = da;
                const bool overwrite = region.x_begin == 11;  // both modes
                ref.accumulate_derivatives(grid, region, ss, d, da[5].data(),
                                           {da[0].data(), da[1].data(), da[2].data(), da[3].data(), da[4].data()}, overwrite);
                k.accumulate_derivatives(grid, region, ss, d, db[5].data(),
                                         {db[0].data(), db[1].data(), db[2].data(), db[3].data(), db[4].data()}, overwrite);
                // The derivative sums cancel within a supersampled cell (the gradient is odd about the
                // centre), so their rounding grows with the ss^2 terms summed, not with the result.
                for (int p = 0; p < 6; ++p)
                  worst_derivative = std::max(worst_derivative, worst_in_peak_eps(db[p], da[p]) / (2 + ss * ss));
                ++cases;
              }
    std::printf("%s: %d cases, worst |simd - scalar| = %.1f eps x peak (values), %.1f eps x peak x (2 + ss^2) (derivatives)\n", k.name,
                cases, worst_value, worst_derivative);
    EXPECT_LE(worst_value, 16.0) << k.name;
    EXPECT_LE(worst_derivative, 64.0) << k.name;  // a wrong lane or tail is off by O(1), not 1e-13
  }
}

}  // namespace
}  // namespace stampede::kernels
