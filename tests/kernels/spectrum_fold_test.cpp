// Tests kernels/spectrum_fold: every instruction set against a direct std::complex evaluation of
// the alias sum (spectrum_fold.hpp), on random spectra and kernels, at the paper-default grid
// (240 sub-pixels, U = 5), at an odd upsampling (60, U = 3) and where a vector straddles the stored
// and the mirrored columns (84, U = 4: n/2 + 1 - M = 22 is not a multiple of the vector width).
#include "kernels/spectrum_fold.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace stampede::kernels {
namespace {

using Complex = std::complex<double>;

// out[ky mod M][jx] = sum_ky sum_rx X[ky][kx] K[ky][rx][jx], kx = jx + M rx; X at kx > n/2 is
// conj(X[-ky][n - kx]).
std::vector<Complex> direct_fold(int n, int u, const std::vector<Complex>& x, const std::vector<Complex>& k) {
  const int m = n / u, hn = n / 2 + 1, hm = m / 2 + 1;
  std::vector<Complex> out(static_cast<std::size_t>(m) * hm);
  for (int ky = 0; ky < n; ++ky)
    for (int rx = 0; rx < u; ++rx)
      for (int jx = 0; jx < hm; ++jx) {
        const int kx = jx + m * rx;
        const Complex a = kx < hn ? x[static_cast<std::size_t>(ky) * hn + kx]
                                  : std::conj(x[static_cast<std::size_t>((n - ky) % n) * hn + (n - kx)]);
        out[static_cast<std::size_t>(ky % m) * hm + jx] += a * k[(static_cast<std::size_t>(ky) * u + rx) * hm + jx];
      }
  return out;
}

TEST(SpectrumFold, EverySetMatchesTheDirectSum) {
  for (auto [n, u] : {std::pair{240, 5}, std::pair{60, 3}, std::pair{84, 4}}) {
    const int m = n / u, hn = n / 2 + 1, hm = m / 2 + 1;
    std::mt19937_64 rng(static_cast<unsigned>(n));
    std::normal_distribution<double> g;
    std::vector<Complex> x(static_cast<std::size_t>(n) * hn), k(static_cast<std::size_t>(n) * u * hm);
    for (auto& v : x) v = {g(rng), g(rng)};
    for (auto& v : k) v = {g(rng), g(rng)};
    const std::vector<Complex> expected = direct_fold(n, u, x, k);
    double scale = 0;  // the largest |term| bounds each sum's rounding, with the number of terms
    for (const auto& v : x) scale = std::max(scale, std::abs(v));
    double kmax = 0;
    for (const auto& v : k) kmax = std::max(kmax, std::abs(v));
    scale *= kmax;
    for (Isa isa : {Isa::kScalar, Isa::kSse42, Isa::kAvx2, Isa::kAvx512}) {
      const SpectrumFoldKernels* f = spectrum_fold_kernels_for(isa);
      if (!f) continue;
      std::vector<Complex> out(expected.size(), Complex(1e300, 1e300));  // must be overwritten
      f->fold(n, u, reinterpret_cast<const double*>(x.data()), reinterpret_cast<const double*>(k.data()),
              reinterpret_cast<double*>(out.data()));
      double worst = 0;
      for (std::size_t i = 0; i < out.size(); ++i) worst = std::max(worst, std::abs(out[i] - expected[i]));
      // n u terms per output value, each rounded at ~eps |term|: a random walk of them.
      const double bound = 4 * std::sqrt(double(n) * u) * std::numeric_limits<double>::epsilon() * scale;
      std::printf("%s n=%d u=%d: worst |fold - direct| = %.2g (bound %.2g)\n", f->name, n, u, worst, bound);
      EXPECT_LE(worst, bound) << f->name << " n " << n;
    }
  }
}

}  // namespace
}  // namespace stampede::kernels
