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

// The separable Gaussian sums at a set of pixels only (those still to fill), each exactly as a
// convolution of the whole cell would give it (the same terms in the same order): a row pass
// (along x) over the rows within reach of a point in each column, then a column pass (along y) at
// the points. Outside the cell counts as zero.
class SparseConvolution {
 public:
  // The points: pixel indices y * side + x, and each column's lowest and highest point row.
  void set_points(std::span<const std::size_t> points, int side) {
    points_ = points, side_ = side;
    ylo_.assign(static_cast<std::size_t>(side), side), yhi_.assign(static_cast<std::size_t>(side), -1);
    for (const std::size_t p : points) {
      const int x = static_cast<int>(p % static_cast<std::size_t>(side)), y = static_cast<int>(p / static_cast<std::size_t>(side));
      ylo_[static_cast<std::size_t>(x)] = std::min(ylo_[static_cast<std::size_t>(x)], y);
      yhi_[static_cast<std::size_t>(x)] = std::max(yhi_[static_cast<std::size_t>(x)], y);
    }
  }
  // rows = `in` convolved along x with kx, where a column pass of half-width `half` will read it.
  void row_pass(std::span<const double> in, std::span<const double> kx, int half, std::vector<double>* rows) const {
    const int hx = static_cast<int>(kx.size()) / 2, side = side_;
    const auto n = static_cast<std::size_t>(side);
    rows->resize(n * n);
    for (int x = 0; x < side; ++x) {
      if (yhi_[static_cast<std::size_t>(x)] < 0) continue;
      const int y0 = std::max(0, ylo_[static_cast<std::size_t>(x)] - half);
      const int y1 = std::min(side - 1, yhi_[static_cast<std::size_t>(x)] + half);
      const int k0 = std::max(-hx, -x), k1 = std::min(hx, side - 1 - x);
      for (int y = y0; y <= y1; ++y) {
        double s = 0;
        for (int k = k0; k <= k1; ++k)
          s += kx[static_cast<std::size_t>(k + hx)] * in[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x + k)];
        (*rows)[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x)] = s;
      }
    }
  }
  // out[p] = rows convolved along y with ky, at the points only.
  void column_pass(const std::vector<double>& rows, std::span<const double> ky, std::vector<double>* out) const {
    const int half = static_cast<int>(ky.size()) / 2, side = side_;
    const auto n = static_cast<std::size_t>(side);
    out->resize(n * n);
    for (const std::size_t p : points_) {
      const int x = static_cast<int>(p % n), y = static_cast<int>(p / n);
      double s = 0;
      for (int k = std::max(-half, -y); k <= std::min(half, side - 1 - y); ++k)
        s += ky[static_cast<std::size_t>(k + half)] * rows[static_cast<std::size_t>(y + k) * n + static_cast<std::size_t>(x)];
      (*out)[p] = s;
    }
  }

 private:
  std::span<const std::size_t> points_;
  int side_ = 0;
  std::vector<int> ylo_, yhi_;
};

}  // namespace

long long fill_masked_pixels(std::span<const std::uint8_t> mask, int side, std::span<const std::span<double>> planes,
                             MaskFillScratch* scratch) {
  const auto npix = static_cast<std::size_t>(side) * static_cast<std::size_t>(side);
  MaskFillScratch& s = *scratch;
  s.pending.clear();
  for (std::size_t p = 0; p < npix; ++p)
    if (mask[p]) s.pending.push_back(p);
  const auto masked = static_cast<long long>(s.pending.size()), unmasked = static_cast<long long>(npix) - masked;
  if (masked == 0) return 0;
  std::vector<double>(&k)[3] = s.kernel;  // G, G x, G x^2 (G normalised)
  std::vector<double>(&m)[6] = s.share;   // the unmasked pixels' sums of G, G dx, G dy, G dx^2, G dx dy, G dy^2
  std::vector<double>(&t)[3] = s.fit;     // a plane's sums of G v, G v dx, G v dy over them
  std::vector<double>(&rows)[3] = s.rows;  // row passes with G, G x, G x^2
  SparseConvolution at;
  s.values.resize(npix);
  for (double sigma = 1; !s.pending.empty() && unmasked > 0 && sigma <= 64; sigma *= 2) {
    const int half = static_cast<int>(std::ceil(3 * sigma));
    for (auto& v : k) v.resize(static_cast<std::size_t>(2 * half + 1));
    double total = 0;
    for (int d = -half; d <= half; ++d) total += std::exp(-0.5 * d * d / (sigma * sigma));
    for (int d = -half; d <= half; ++d) {
      const double g = std::exp(-0.5 * d * d / (sigma * sigma)) / total;
      const auto i = static_cast<std::size_t>(d + half);
      k[0][i] = g, k[1][i] = g * d, k[2][i] = g * d * d;
    }
    for (std::size_t p = 0; p < npix; ++p) s.values[p] = mask[p] ? 0.0 : 1.0;
    // The unmasked share of the Gaussian at every pixel still to fill: those with a quarter fill now.
    at.set_points(s.pending, side);
    at.row_pass(s.values, k[0], half, &rows[0]);
    at.column_pass(rows[0], k[0], &m[0]);
    s.now.clear(), s.later.clear();
    for (const std::size_t p : s.pending) (m[0][p] >= 0.25 ? s.now : s.later).push_back(p);
    s.pending.swap(s.later);
    if (s.now.empty()) continue;
    at.set_points(s.now, side);  // rows[0] holds the pending pixels' rows, a superset of these
    at.row_pass(s.values, k[1], half, &rows[1]);
    at.row_pass(s.values, k[2], half, &rows[2]);
    at.column_pass(rows[1], k[0], &m[1]);
    at.column_pass(rows[0], k[1], &m[2]);
    at.column_pass(rows[2], k[0], &m[3]);
    at.column_pass(rows[1], k[1], &m[4]);
    at.column_pass(rows[0], k[2], &m[5]);
    for (const std::span<double> plane : planes) {
      for (std::size_t p = 0; p < npix; ++p) s.values[p] = mask[p] ? 0.0 : plane[p];
      at.row_pass(s.values, k[0], half, &rows[0]);
      at.row_pass(s.values, k[1], half, &rows[1]);
      at.column_pass(rows[0], k[0], &t[0]);
      at.column_pass(rows[1], k[0], &t[1]);
      at.column_pass(rows[0], k[1], &t[2]);
      for (const std::size_t p : s.now) {
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
  }
  if (!s.pending.empty())
    for (const std::span<double> plane : planes) {
      double mean = 0;
      for (std::size_t p = 0; p < npix; ++p)
        if (!mask[p]) mean += plane[p];
      mean = unmasked > 0 ? mean / static_cast<double>(unmasked) : 0.0;
      for (const std::size_t p : s.pending) plane[p] = mean;
    }
  return masked;
}

}  // namespace stampede::kernels
