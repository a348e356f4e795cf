// Pre-PSF Gaussian moments; see prepsf_moments.hpp.
#include "kernels/prepsf_moments.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stampede::kernels {

double dft_frequency(int i, int n) {
  const int m = i <= n / 2 ? i : i - n;
  return 2 * std::numbers::pi * m / n;
}

PrepsfMoments prepsf_moments(std::span<const double> image, int size, double xc, double yc, double fwhm,
                             std::span<const double> psf_k, double variance,
                             std::vector<std::complex<double>>& scratch) {
  PrepsfMoments m;
  const std::size_t n = static_cast<std::size_t>(size), npix = n * n;
  if (size < 1 || image.size() != npix || psf_k.size() != npix || !(fwhm > 0) || !std::isfinite(xc) ||
      !std::isfinite(yc))
    return m;
  // scratch: the n roots of unity, the phase factors along x and y, then the rows' transforms.
  if (scratch.size() < 3 * n + npix) scratch.resize(3 * n + npix);
  std::complex<double>* root = scratch.data();
  std::complex<double>* phase_x = root + n;
  std::complex<double>* phase_y = phase_x + n;
  std::complex<double>* rows = phase_y + n;
  for (std::size_t q = 0; q < n; ++q) root[q] = std::polar(1.0, -2 * std::numbers::pi * q / n);
  for (int i = 0; i < size; ++i) {
    const double k = dft_frequency(i, size);
    // e^{i k c}: the transform about the weight's centre (the DFT's is about pixel 0).
    phase_x[i] = std::polar(1.0, k * xc), phase_y[i] = std::polar(1.0, k * yc);
  }
  // The rows' DFTs along x: rows[j * n + i] = sum_x I(x, j) e^{-i kx(i) x}. Separable, 2 n^3, no
  // plan: a stamp's side varies with its detection (33 to 255), mostly near the smallest.
  for (std::size_t j = 0; j < n; ++j) {
    const double* row = image.data() + j * n;
    for (std::size_t i = 0; i < n; ++i) {
      std::complex<double> s = 0;
      std::size_t q = 0;  // (i x) mod n
      for (std::size_t x = 0; x < n; ++x) {
        s += row[x] * root[q];
        q += i;
        if (q >= n) q -= n;
      }
      rows[j * n + i] = s;
    }
  }
  // The weight w = exp(-r^2 / 2 s^2) has w~ = 2 pi s^2 exp(-s^2 k^2 / 2); x^2 w has
  // -d^2 w~ / dkx^2 = (s^2 - s^4 kx^2) w~, xy w has -s^4 kx ky w~. Each moment is then
  // (1 / n^2) sum_k f~(k) G~(k) (Parseval; f~ real and even), G~ = I~ e^{ikc} / P~.
  const double s2 = std::pow(fwhm / 2.3548200450309493, 2), s4 = s2 * s2;
  double s0 = 0, sxx = 0, syy = 0, sxy = 0;
  // Noise sums: sum over k of the products of the maps' transforms over P~^2 (white noise: the
  // variance of sum_x a(x) I(x) is variance / n^2 sum_k |a~(k)|^2).
  double n00 = 0, nxx = 0, nyy = 0, nxy2 = 0, nxx_yy = 0, nxyxx = 0, nxyyy = 0;
  for (std::size_t jy = 0; jy < n; ++jy) {
    const double ky = dft_frequency(static_cast<int>(jy), size);
    for (std::size_t ix = 0; ix < n; ++ix) {
      const double kx = dft_frequency(static_cast<int>(ix), size);
      const double w = 2 * std::numbers::pi * s2 * std::exp(-0.5 * s2 * (kx * kx + ky * ky));
      // No weight left at this k (e^-34.5; callers may leave psf_k unset beyond it).
      if (w < 1e-15 * 2 * std::numbers::pi * s2) continue;
      const double p = psf_k[jy * n + ix];
      if (!(p > 0) || !std::isfinite(p)) return m;
      // I~(kx, ky) = sum_j rows[j][kx] e^{-i ky j}.
      std::complex<double> t = 0;
      std::size_t q = 0;
      for (std::size_t j = 0; j < n; ++j) {
        t += rows[j * n + ix] * root[q];
        q += jy;
        if (q >= n) q -= n;
      }
      const double g = std::real(t * phase_x[ix] * phase_y[jy]) / p;
      const double fxx = (s2 - s4 * kx * kx) * w, fyy = (s2 - s4 * ky * ky) * w, fxy = -s4 * kx * ky * w;
      s0 += w * g, sxx += fxx * g, syy += fyy * g, sxy += fxy * g;
      const double ip2 = 1 / (p * p);
      n00 += w * w * ip2;
      nxx += fxx * fxx * ip2, nyy += fyy * fyy * ip2, nxx_yy += fxx * fyy * ip2;
      nxy2 += fxy * fxy * ip2, nxyxx += fxy * fxx * ip2, nxyyy += fxy * fyy * ip2;
    }
  }
  const double norm = 1.0 / static_cast<double>(npix);
  s0 *= norm, sxx *= norm, syy *= norm, sxy *= norm;
  const double ts = sxx + syy;
  if (!(s0 > 0) || !(ts > 0) || !std::isfinite(s0) || !std::isfinite(ts)) return m;
  m.flux = s0;
  m.t = ts / s0;
  m.e1 = (sxx - syy) / ts;
  m.e2 = 2 * sxy / ts;
  // A pre-PSF Gaussian moment can be negative with noise (the deconvolution amplifies it); beyond
  // |e| = 1 it is no shape.
  if (!(std::hypot(m.e1, m.e2) < 1)) return m;
  // de1 = [(dSxx - dSyy) Ts - D (dSxx + dSyy)] / Ts^2 = [a dSxx - b dSyy] / Ts^2 with a = Ts - D,
  // b = Ts + D (D = Sxx - Syy); de2 = [2 dSxy Ts - 2 Sxy (dSxx + dSyy)] / Ts^2. The centre held.
  const double v = variance * norm, d = sxx - syy, a = ts - d, b = ts + d;
  const double var1 = v * (a * a * nxx + b * b * nyy - 2 * a * b * nxx_yy);
  const double c = 2 * ts, e = 2 * sxy;
  const double var2 = v * (c * c * nxy2 + e * e * (nxx + nyy + 2 * nxx_yy) - 2 * c * e * (nxyxx + nxyyy));
  m.e1_err = std::sqrt(std::max(var1, 0.0)) / (ts * ts);
  m.e2_err = std::sqrt(std::max(var2, 0.0)) / (ts * ts);
  m.snr = s0 / std::sqrt(v * n00);
  m.valid = true;
  return m;
}

}  // namespace stampede::kernels
