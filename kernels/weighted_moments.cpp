// Fixed-weight moments; see weighted_moments.hpp.
#include "kernels/weighted_moments.hpp"

#include <cmath>

namespace stampede::kernels {
namespace {

// The weight is separable, exp(-dx^2 / 2s^2) exp(-dy^2 / 2s^2): each sum is a row's sums weighted
// by the row's factor, 2 x size exponentials per pass instead of size^2.
struct Sums {
  double s0 = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
};

Sums weighted_sums(std::span<const double> image, int size, double x, double y, double inv_two_s2, double* gx,
                   double* gy) {
  for (int i = 0; i < size; ++i) gx[i] = std::exp(-(i - x) * (i - x) * inv_two_s2);
  for (int j = 0; j < size; ++j) gy[j] = std::exp(-(j - y) * (j - y) * inv_two_s2);
  Sums s;
  for (int j = 0; j < size; ++j) {
    const double* row = image.data() + static_cast<std::size_t>(j) * size;
    double r0 = 0, r1 = 0, r2 = 0;
    for (int i = 0; i < size; ++i) {
      const double v = gx[i] * row[i], dx = i - x;
      r0 += v;
      r1 += v * dx;
      r2 += v * dx * dx;
    }
    const double dy = j - y;
    s.s0 += gy[j] * r0;
    s.sx += gy[j] * r1;
    s.sy += gy[j] * dy * r0;
    s.sxx += gy[j] * r2;
    s.sxy += gy[j] * dy * r1;
    s.syy += gy[j] * dy * dy * r0;
  }
  return s;
}

}  // namespace

WeightedMoments weighted_moments(std::span<const double> image, int size, double fwhm, double variance,
                                 std::span<double> scratch, int centroid_iterations) {
  WeightedMoments m;
  if (size < 1 || image.size() != static_cast<std::size_t>(size) * size || !(fwhm > 0) ||
      scratch.size() < 2 * static_cast<std::size_t>(size))
    return m;
  const double sigma = fwhm / 2.3548200450309493;
  const double inv_two_s2 = 1 / (2 * sigma * sigma);
  double* gx = scratch.data();
  double* gy = gx + size;
  double x = 0.5 * (size - 1), y = 0.5 * (size - 1);
  Sums s;
  for (int it = 0;; ++it) {
    s = weighted_sums(image, size, x, y, inv_two_s2, gx, gy);
    if (!(s.s0 > 0) || !std::isfinite(s.s0)) return m;
    if (it == centroid_iterations) break;
    // The weighted centroid m of a Gaussian of covariance C under a round weight of variance w
    // is P (C^-1 x0 + x / w), P = (C^-1 + I / w)^-1 the weighted covariance, so the centre is
    // x0 = x + w (w I - P)^-1 (m - x): a Gaussian's centre in one step, where the plain step
    // m - x only halves the offset for C = w. P is measured; the plain step where w I - P is not
    // safely positive.
    const double mx = s.sx / s.s0, my = s.sy / s.s0, w = sigma * sigma;
    // P about the weighted centroid, not about x (the offset's own square would make the step
    // overshoot along it).
    const double pxx = s.sxx / s.s0 - mx * mx, pxy = s.sxy / s.s0 - mx * my, pyy = s.syy / s.s0 - my * my;
    const double ax = w - pxx, axy = -pxy, ay = w - pyy, det = ax * ay - axy * axy;
    double dx = mx, dy = my;
    if (ax > 0.1 * w && ay > 0.1 * w && det > 0.01 * w * w) {
      dx = w * (ay * mx - axy * my) / det;
      dy = w * (ax * my - axy * mx) / det;
    }
    x += dx;
    y += dy;
    if (!(x >= -0.5 && x <= size - 0.5 && y >= -0.5 && y <= size - 0.5)) return m;
  }
  const double ts = s.sxx + s.syy;
  if (!(ts > 0) || !std::isfinite(ts)) return m;
  m.x = x, m.y = y;
  m.flux = s.s0;
  m.t = ts / s.s0;
  m.e1 = (s.sxx - s.syy) / ts;
  m.e2 = 2 * s.sxy / ts;
  // A positive image under a positive weight has |e| < 1; noise beyond that is no shape.
  if (!(std::hypot(m.e1, m.e2) < 1)) return m;
  // Linear error propagation from each pixel's noise (the centroid held): de/dI_p = w_p (q_p T -
  // S q'_p) / T^2 with q = dx^2 - dy^2 (e1) or 2 dx dy (e2).
  double v1 = 0, v2 = 0, w2 = 0;
  for (int j = 0; j < size; ++j) {
    const double dy = j - y;
    for (int i = 0; i < size; ++i) {
      const double dx = i - x, w = gx[i] * gy[j], r2 = dx * dx + dy * dy;
      const double d1 = w * ((dx * dx - dy * dy) * ts - (s.sxx - s.syy) * r2);
      const double d2 = w * (2 * dx * dy * ts - 2 * s.sxy * r2);
      v1 += d1 * d1;
      v2 += d2 * d2;
      w2 += w * w;
    }
  }
  m.e1_err = std::sqrt(variance * v1) / (ts * ts);
  m.e2_err = std::sqrt(variance * v2) / (ts * ts);
  m.snr = s.s0 / std::sqrt(variance * w2);
  m.valid = true;
  return m;
}

}  // namespace stampede::kernels
