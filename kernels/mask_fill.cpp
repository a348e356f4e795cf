// Mask symmetrisation and masked-pixel filling; see mask_fill.hpp.
#include "kernels/mask_fill.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace stampede::kernels {

void symmetrise_mask(std::span<std::uint8_t> mask, int side, std::vector<std::uint8_t>* turned) {
  turned->assign(mask.begin(), mask.end());
  const auto n = static_cast<std::size_t>(side);
  // Each masked pixel's three quarter turns about the centre: (x, y) -> (side - 1 - y, x) -> ...
  for (std::size_t y = 0; y < n; ++y)
    for (std::size_t x = 0; x < n; ++x)
      if ((*turned)[y * n + x]) {
        mask[x * n + (n - 1 - y)] = 1;
        mask[(n - 1 - y) * n + (n - 1 - x)] = 1;
        mask[(n - 1 - x) * n + y] = 1;
      }
}

namespace {

// out = in convolved with kx along x and ky along y (odd, centred: entry k + half weighs the pixel
// k away), zero outside the cell.
void convolve(std::span<const double> in, int side, std::span<const double> kx, std::span<const double> ky,
              std::vector<double>* rows, std::vector<double>* out) {
  const int half = static_cast<int>(kx.size()) / 2;
  const auto n = static_cast<std::size_t>(side);
  rows->assign(n * n, 0.0);
  out->assign(n * n, 0.0);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      double s = 0;
      for (int k = std::max(-half, -x); k <= std::min(half, side - 1 - x); ++k)
        s += kx[static_cast<std::size_t>(k + half)] * in[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x + k)];
      (*rows)[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x)] = s;
    }
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      double s = 0;
      for (int k = std::max(-half, -y); k <= std::min(half, side - 1 - y); ++k)
        s += ky[static_cast<std::size_t>(k + half)] * (*rows)[static_cast<std::size_t>(y + k) * n + static_cast<std::size_t>(x)];
      (*out)[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x)] = s;
    }
}

}  // namespace

long long fill_masked_pixels(std::span<const std::uint8_t> mask, int side, std::span<const std::span<double>> planes,
                             MaskFillScratch* scratch) {
  const auto npix = static_cast<std::size_t>(side) * static_cast<std::size_t>(side);
  MaskFillScratch& s = *scratch;
  s.pending.assign(mask.begin(), mask.end());
  long long left = 0;
  for (std::uint8_t m : mask) left += m != 0;
  const long long masked = left, unmasked = static_cast<long long>(npix) - masked;
  if (masked == 0) return 0;
  std::vector<double>(&k)[3] = s.kernel;  // G, G x, G x^2 (G normalised)
  std::vector<double>(&m)[6] = s.share;   // the unmasked pixels' sums of G, G dx, G dy, G dx^2, G dx dy, G dy^2
  std::vector<double>(&t)[3] = s.fit;     // a plane's sums of G v, G v dx, G v dy over them
  for (double sigma = 1; left > 0 && unmasked > 0 && sigma <= 64; sigma *= 2) {
    const int half = static_cast<int>(std::ceil(3 * sigma));
    for (auto& v : k) v.resize(static_cast<std::size_t>(2 * half + 1));
    double total = 0;
    for (int d = -half; d <= half; ++d) total += std::exp(-0.5 * d * d / (sigma * sigma));
    for (int d = -half; d <= half; ++d) {
      const double g = std::exp(-0.5 * d * d / (sigma * sigma)) / total;
      const auto i = static_cast<std::size_t>(d + half);
      k[0][i] = g, k[1][i] = g * d, k[2][i] = g * d * d;
    }
    s.values.resize(npix);
    for (std::size_t p = 0; p < npix; ++p) s.values[p] = mask[p] ? 0.0 : 1.0;
    convolve(s.values, side, k[0], k[0], &s.rows, &m[0]);
    s.now.assign(npix, 0);
    long long now = 0;
    for (std::size_t p = 0; p < npix; ++p)
      if (s.pending[p] && m[0][p] >= 0.25) s.now[p] = 1, ++now;
    if (now == 0) continue;
    convolve(s.values, side, k[1], k[0], &s.rows, &m[1]);
    convolve(s.values, side, k[0], k[1], &s.rows, &m[2]);
    convolve(s.values, side, k[2], k[0], &s.rows, &m[3]);
    convolve(s.values, side, k[1], k[1], &s.rows, &m[4]);
    convolve(s.values, side, k[0], k[2], &s.rows, &m[5]);
    for (const std::span<double> plane : planes) {
      for (std::size_t p = 0; p < npix; ++p) s.values[p] = mask[p] ? 0.0 : plane[p];
      convolve(s.values, side, k[0], k[0], &s.rows, &t[0]);
      convolve(s.values, side, k[1], k[0], &s.rows, &t[1]);
      convolve(s.values, side, k[0], k[1], &s.rows, &t[2]);
      for (std::size_t p = 0; p < npix; ++p) {
        if (!s.now[p]) continue;
        // [m0 mx my; mx mxx mxy; my mxy myy] (a b c) = (t0 tx ty): a by Cramer's rule.
        const double m0 = m[0][p], mx = m[1][p], my = m[2][p], mxx = m[3][p], mxy = m[4][p], myy = m[5][p];
        const double c00 = mxx * myy - mxy * mxy, c01 = mx * myy - mxy * my, c02 = mx * mxy - mxx * my;
        const double det = m0 * c00 - mx * c01 + my * c02;
        // Unmasked pixels on a line (or nearly): the plane is not determined; their mean.
        if (!(det > 1e-6 * m0 * m0 * m0 * sigma * sigma * sigma * sigma)) {
          plane[p] = t[0][p] / m0;
          continue;
        }
        plane[p] = (t[0][p] * c00 - t[1][p] * (mx * myy - my * mxy) + t[2][p] * (mx * mxy - my * mxx)) / det;
      }
    }
    for (std::size_t p = 0; p < npix; ++p)
      if (s.now[p]) s.pending[p] = 0;
    left -= now;
  }
  if (left > 0)
    for (const std::span<double> plane : planes) {
      double mean = 0;
      for (std::size_t p = 0; p < npix; ++p)
        if (!mask[p]) mean += plane[p];
      mean = unmasked > 0 ? mean / static_cast<double>(unmasked) : 0.0;
      for (std::size_t p = 0; p < npix; ++p)
        if (s.pending[p]) plane[p] = mean;
    }
  return masked;
}

}  // namespace stampede::kernels
