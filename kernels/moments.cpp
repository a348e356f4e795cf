// Adaptive moments; see moments.hpp.
#include "kernels/moments.hpp"

#include <cmath>

namespace stampede::kernels {

void covariance_ellipticity(double xx, double xy, double yy, double* e1, double* e2) {
  const double t = xx + yy;
  const double chi1 = (xx - yy) / t;
  const double chi2 = 2.0 * xy / t;
  const double chi_sq = chi1 * chi1 + chi2 * chi2;
  const double k = 1.0 / (1.0 + std::sqrt(std::max(0.0, 1.0 - chi_sq)));
  *e1 = chi1 * k;
  *e2 = chi2 * k;
}

ImageMoments adaptive_moments(std::span<const double> image, std::span<const double> mask_weight, int size) {
  ImageMoments m;
  double flux = 0, pos = 0, sx = 0, sy = 0;
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i) {
      const int k = j * size + i;
      if (mask_weight[k] == 0.0 || !std::isfinite(image[k])) continue;
      flux += image[k];
      if (image[k] > 0) {
        pos += image[k];
        sx += image[k] * i;
        sy += image[k] * j;
      }
    }
  m.flux = flux;
  if (!(pos > 0.0) || !std::isfinite(pos)) return m;
  double x = sx / pos, y = sy / pos;
  double xx = 4.0, xy = 0.0, yy = 4.0;  // 2-pixel sigma to begin with
  constexpr int kMaxIterations = 60;
  for (int it = 1; it <= kMaxIterations; ++it) {
    const double det = xx * yy - xy * xy;
    if (!(det > 0.0)) return m;
    const double ixx = yy / det, ixy = -xy / det, iyy = xx / det;
    double s0 = 0, s1x = 0, s1y = 0, s2xx = 0, s2xy = 0, s2yy = 0;
    for (int j = 0; j < size; ++j) {
      const double dy = j - y;
      for (int i = 0; i < size; ++i) {
        const int k = j * size + i;
        if (mask_weight[k] == 0.0 || !std::isfinite(image[k])) continue;
        const double dx = i - x;
        const double w = std::exp(-0.5 * (ixx * dx * dx + 2.0 * ixy * dx * dy + iyy * dy * dy)) * image[k];
        s0 += w;
        s1x += w * dx;
        s1y += w * dy;
        s2xx += w * dx * dx;
        s2xy += w * dx * dy;
        s2yy += w * dy * dy;
      }
    }
    if (!(s0 > 0.0)) return m;
    const double nxx = 2.0 * s2xx / s0, nxy = 2.0 * s2xy / s0, nyy = 2.0 * s2yy / s0;
    const double shift = std::abs(s1x / s0) + std::abs(s1y / s0);
    x += s1x / s0;
    y += s1y / s0;
    const double change = std::abs(nxx - xx) + std::abs(nyy - yy) + std::abs(nxy - xy);
    xx = nxx;
    xy = nxy;
    yy = nyy;
    m.iterations = it;
    if (!std::isfinite(x + y + xx + xy + yy) || x < -1 || y < -1 || x > size || y > size) return m;
    if (change < 1e-6 * (xx + yy) && shift < 1e-6) break;
  }
  if (!(xx > 0 && yy > 0 && xx * yy - xy * xy > 0)) return m;
  m.x = x;
  m.y = y;
  m.xx = xx;
  m.xy = xy;
  m.yy = yy;
  m.valid = true;
  return m;
}

}  // namespace stampede::kernels
