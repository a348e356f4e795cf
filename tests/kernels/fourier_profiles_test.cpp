// Fourier transforms of the simulator's profiles: closed forms against quadrature, tables against
// the functions they tabulate, and the small-k limit set by the second moment.
#include "kernels/fourier_profiles.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "kernels/sersic.hpp"

namespace stampede::kernels {
namespace {

TEST(FourierProfiles, SersicQuadratureReproducesTheExponentialClosedForm) {
  for (double q = 1e-3; q < 300; q *= 1.37) EXPECT_NEAR(sersic_fourier(1.0, q), exponential_fourier(q), 1e-12) << q;
}

TEST(FourierProfiles, SmallWavenumberLimitIsTheSecondMoment) {
  // F(q) = 1 - q^2 <r^2> / 4 + O(q^4) for a unit-flux radial profile (J0(x) = 1 - x^2/4 + ...).
  for (double n : {1.0, 2.0, 4.0}) {
    const double q = 1e-3;
    EXPECT_NEAR((1 - sersic_fourier(n, q)) / (q * q), sersic_mean_r2(n) / 4, 1e-4 * sersic_mean_r2(n)) << n;
  }
  EXPECT_NEAR(sersic_mean_r2(1.0), 6 / std::pow(sersic_b(1.0), 2), 1e-12);  // Gamma(4) / Gamma(2) / b^2
}

TEST(FourierProfiles, DeVaucouleursIsPositiveAndDecreasing) {
  double previous = 1.0;
  for (double q = 0.01; q < 300; q *= 1.5) {
    const double f = sersic_fourier(4.0, q);
    EXPECT_GT(f, 0.0) << q;
    EXPECT_LT(f, previous) << q;
    previous = f;
  }
}

TEST(FourierProfiles, TableInterpolatesToBetterThan1e9) {
  const LogGrid grid = LogGrid::covering(1e-4, 300, 40);
  const LogTable table([](double q) { return sersic_fourier(4.0, q); }, grid);
  const LogTable exp_table([](double q) { return exponential_fourier(q); }, grid);
  double worst = 0, worst_exp = 0;
  for (double q = 2e-5; q < 290; q *= 1.0731) {  // off the nodes, below q_min included
    worst = std::max(worst, std::abs(table(q) - sersic_fourier(4.0, q)));
    worst_exp = std::max(worst_exp, std::abs(exp_table(q) - exponential_fourier(q)));
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_LT(worst_exp, 2e-8);  // the exponential turns over within one decade: the hardest case
  EXPECT_GE(table.q_max(), 300.0);
}

TEST(FourierProfiles, MoffatClosedFormMatchesQuadrature) {
  // A truncation far out in the wings leaves the transform unchanged to (1 + T^2)^(1 - beta).
  for (double beta : {2.5, 3.0, 4.5})
    for (double x : {0.0, 0.3, 1.0, 2.5, 6.0})
      EXPECT_NEAR(moffat_fourier(beta, 0.0, x), moffat_fourier(beta, 2000.0, x), 2e-7) << beta << " " << x;
}

TEST(FourierProfiles, AiryTransferFunctionIsTheOverlapOfTwoPupils) {
  // OTF(s) = overlap area of two unit discs whose centres are 2 s apart, over pi: counted on a grid.
  constexpr int kN = 1000;
  for (double s : {0.1, 0.4, 0.75}) {
    long long inside = 0, both = 0;
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        const double x = -1 + 2 * (i + 0.5) / kN, y = -1 + 2 * (j + 0.5) / kN;
        if (x * x + y * y > 1) continue;
        ++inside;
        if ((x - 2 * s) * (x - 2 * s) + y * y <= 1) ++both;
      }
    EXPECT_NEAR(airy_fourier(s), static_cast<double>(both) / inside, 2e-3) << s;
  }
  EXPECT_EQ(airy_fourier(1.0), 0.0);
  EXPECT_DOUBLE_EQ(airy_fourier(0.0), 1.0);
}

}  // namespace
}  // namespace stampede::kernels
