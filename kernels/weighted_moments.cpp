// Fixed-weight moments; see weighted_moments.hpp.
#include "kernels/weighted_moments.hpp"

#include <algorithm>
#include <cmath>

namespace stampede::kernels {
namespace {

// A stamp's weighted sums about its centroid (xc, yc), in sky offsets (du, dv) from it.
struct Sums {
  double s0 = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
};

// An axis-aligned J makes the weight separable, exp(-du^2 / 2s^2) exp(-dv^2 / 2s^2): each sum is
// a row's sums weighted by the row's factor, 2 x size exponentials per pass instead of size^2.
bool separable(const MomentsStamp& s) { return s.dudy == 0 && s.dvdx == 0; }

// Whether pixel (x, y) lies on the stamp (pixel centres at integers).
bool inside(const MomentsStamp& s, double x, double y) {
  return x >= -0.5 && x <= s.size - 0.5 && y >= -0.5 && y <= s.size - 0.5;
}

std::size_t scratch_size(const MomentsStamp& s) {
  return separable(s) ? 2 * static_cast<std::size_t>(s.size) : static_cast<std::size_t>(s.size) * s.size;
}

// Fills the stamp's weights into w (separable: row then column factors; else per pixel).
Sums weighted_sums(const MomentsStamp& st, double x, double y, double inv_two_s2, double* w) {
  const int size = st.size;
  Sums s;
  if (separable(st)) {
    double* gx = w;
    double* gy = w + size;
    for (int i = 0; i < size; ++i) {
      const double du = st.dudx * (i - x);
      gx[i] = std::exp(-du * du * inv_two_s2);
    }
    for (int j = 0; j < size; ++j) {
      const double dv = st.dvdy * (j - y);
      gy[j] = std::exp(-dv * dv * inv_two_s2);
    }
    for (int j = 0; j < size; ++j) {
      const double* row = st.image.data() + static_cast<std::size_t>(j) * size;
      double r0 = 0, r1 = 0, r2 = 0;
      for (int i = 0; i < size; ++i) {
        const double v = gx[i] * row[i], du = st.dudx * (i - x);
        r0 += v;
        r1 += v * du;
        r2 += v * du * du;
      }
      const double dv = st.dvdy * (j - y);
      s.s0 += gy[j] * r0;
      s.sx += gy[j] * r1;
      s.sy += gy[j] * dv * r0;
      s.sxx += gy[j] * r2;
      s.sxy += gy[j] * dv * r1;
      s.syy += gy[j] * dv * dv * r0;
    }
    return s;
  }
  for (int j = 0; j < size; ++j) {
    const double dy = j - y;
    const double* row = st.image.data() + static_cast<std::size_t>(j) * size;
    double* wrow = w + static_cast<std::size_t>(j) * size;
    for (int i = 0; i < size; ++i) {
      const double dx = i - x;
      const double du = st.dudx * dx + st.dudy * dy, dv = st.dvdx * dx + st.dvdy * dy;
      wrow[i] = std::exp(-(du * du + dv * dv) * inv_two_s2);
      const double v = wrow[i] * row[i];
      s.s0 += v;
      s.sx += v * du;
      s.sy += v * dv;
      s.sxx += v * du * du;
      s.sxy += v * du * dv;
      s.syy += v * dv * dv;
    }
  }
  return s;
}

// Sum over the stamp's pixels of d e / d I_p squared (times T^4) for e1 and e2, and of w^2, about
// the centroid: de/dI_p = w_p (q_p T - S q'_p) / T^2 with q = du^2 - dv^2 (e1) or 2 du dv (e2).
// With a covariance the same derivatives are kept as maps (maps: 3 x size^2) and the sums are
// a^T C a instead.
void error_sums(const MomentsStamp& st, double x, double y, const double* w, double ts, double sdiff, double sxy,
                double* v1, double* v2, double* w2, double* maps) {
  const int size = st.size;
  const std::size_t npix = static_cast<std::size_t>(size) * size;
  const bool sep = separable(st);
  if (sep && !maps) {
    // With wp = gx_i gy_j, du = du(i) and dv = dv(j), d1 = wp (A du^2 + B dv^2) (A = ts - sdiff,
    // B = -(ts + sdiff)) and d2 = 2 wp (ts du dv - sxy (du^2 + dv^2)): their squares' sums are
    // products of one-axis sums X_k = sum_i gx_i^2 du^k and Y_k = sum_j gy_j^2 dv^k, O(size), not
    // O(size^2).
    double xk[5] = {}, yk[5] = {};
    for (int i = 0; i < size; ++i) {
      const double du = st.dudx * (i - x), g2 = w[i] * w[i];
      xk[0] += g2, xk[1] += g2 * du, xk[2] += g2 * du * du, xk[3] += g2 * du * du * du, xk[4] += g2 * du * du * du * du;
    }
    for (int j = 0; j < size; ++j) {
      const double dv = st.dvdy * (j - y), g2 = w[size + j] * w[size + j];
      yk[0] += g2, yk[1] += g2 * dv, yk[2] += g2 * dv * dv, yk[3] += g2 * dv * dv * dv, yk[4] += g2 * dv * dv * dv * dv;
    }
    const double a = ts - sdiff, b = -(ts + sdiff);
    *v1 += a * a * xk[4] * yk[0] + 2 * a * b * xk[2] * yk[2] + b * b * xk[0] * yk[4];
    *v2 += 4 * (ts * ts * xk[2] * yk[2] + sxy * sxy * (xk[4] * yk[0] + xk[0] * yk[4] + 2 * xk[2] * yk[2]) -
                2 * ts * sxy * (xk[3] * yk[1] + xk[1] * yk[3]));
    *w2 += xk[0] * yk[0];
    return;
  }
  for (int j = 0; j < size; ++j) {
    const double dy = j - y;
    for (int i = 0; i < size; ++i) {
      const double dx = i - x;
      double du, dv, wp;
      if (sep) {
        du = st.dudx * dx, dv = st.dvdy * dy, wp = w[i] * w[size + j];
      } else {
        du = st.dudx * dx + st.dudy * dy, dv = st.dvdx * dx + st.dvdy * dy;
        wp = w[static_cast<std::size_t>(j) * size + i];
      }
      const double r2 = du * du + dv * dv;
      const double d1 = wp * ((du * du - dv * dv) * ts - sdiff * r2);
      const double d2 = wp * (2 * du * dv * ts - 2 * sxy * r2);
      if (maps) {
        const std::size_t p = static_cast<std::size_t>(j) * size + i;
        maps[p] = d1, maps[npix + p] = d2, maps[2 * npix + p] = wp;
        continue;
      }
      *v1 += d1 * d1;
      *v2 += d2 * d2;
      *w2 += wp * wp;
    }
  }
  if (!maps) return;
  PixelCovariance& c = *st.covariance;
  *v1 = c.variance({maps, npix});
  *v2 = c.variance({maps + npix, npix});
  *w2 = c.variance({maps + 2 * npix, npix});
}

// scratch: the stamps' weights (scratch_size each), then, when a stamp has a covariance, 3 x the
// largest such stamp's size^2 for its derivative maps.
WeightedMoments measure(std::span<const MomentsStamp> stamps, double fwhm, double* scratch, int centroid_iterations) {
  WeightedMoments m;
  const std::size_t n = stamps.size();
  const double sigma = fwhm / 2.3548200450309493;
  const double inv_two_s2 = 1 / (2 * sigma * sigma);
  // The stamps' averaging weights c_k / sum c, each over its flux scale: sums in the sky's flux.
  bool noise_free = false;
  double c_sum = 0;
  for (const MomentsStamp& s : stamps) noise_free = noise_free || !(s.variance > 0);
  auto c_of = [&](const MomentsStamp& s) {
    return noise_free ? 1.0 : s.flux_scale * s.flux_scale * std::abs(s.dudx * s.dvdy - s.dudy * s.dvdx) / s.variance;
  };
  for (const MomentsStamp& s : stamps) c_sum += c_of(s);
  // The centroid is carried as the first stamp's pixel (x1, y1); the others' follow through the sky.
  const MomentsStamp& first = stamps[0];
  const double det1 = first.dudx * first.dvdy - first.dudy * first.dvdx;
  double x1 = std::isnan(first.start_x) ? 0.5 * (first.size - 1) : first.start_x;
  double y1 = std::isnan(first.start_y) ? 0.5 * (first.size - 1) : first.start_y;
  double u = 0, v = 0;
  auto stamp_centroid = [&](std::size_t k, double* xk, double* yk) {
    if (k == 0) {
      *xk = x1, *yk = y1;
      return;
    }
    const MomentsStamp& s = stamps[k];
    const double d = s.dudx * s.dvdy - s.dudy * s.dvdx;
    *xk = s.x_ref + (s.dvdy * u - s.dudy * v) / d;
    *yk = s.y_ref + (-s.dvdx * u + s.dudx * v) / d;
  };
  Sums s;
  for (int it = 0;; ++it) {
    u = first.dudx * (x1 - first.x_ref) + first.dudy * (y1 - first.y_ref);
    v = first.dvdx * (x1 - first.x_ref) + first.dvdy * (y1 - first.y_ref);
    s = Sums();
    double* w = scratch;
    for (std::size_t k = 0; k < n; ++k) {
      double xk, yk;
      stamp_centroid(k, &xk, &yk);
      if (!inside(stamps[k], xk, yk)) return m;
      const Sums sk = weighted_sums(stamps[k], xk, yk, inv_two_s2, w);
      w += scratch_size(stamps[k]);
      const double f = c_of(stamps[k]) / c_sum / stamps[k].flux_scale;
      s.s0 += f * sk.s0, s.sx += f * sk.sx, s.sy += f * sk.sy;
      s.sxx += f * sk.sxx, s.sxy += f * sk.sxy, s.syy += f * sk.syy;
    }
    if (!(s.s0 > 0) || !std::isfinite(s.s0)) return m;
    if (it == centroid_iterations) break;
    // The weighted centroid m of a Gaussian of covariance C under a round weight of variance w
    // is P (C^-1 x0 + x / w), P = (C^-1 + I / w)^-1 the weighted covariance, so the centre is
    // x0 = x + w (w I - P)^-1 (m - x): a Gaussian's centre in one step, where the plain step
    // m - x only halves the offset for C = w. P is measured; the plain step where w I - P is not
    // safely positive.
    const double mx = s.sx / s.s0, my = s.sy / s.s0, ww = sigma * sigma;
    // P about the weighted centroid, not about x (the offset's own square would make the step
    // overshoot along it).
    const double pxx = s.sxx / s.s0 - mx * mx, pxy = s.sxy / s.s0 - mx * my, pyy = s.syy / s.s0 - my * my;
    const double ax = ww - pxx, axy = -pxy, ay = ww - pyy, det = ax * ay - axy * axy;
    double du = mx, dv = my;
    if (ax > 0.1 * ww && ay > 0.1 * ww && det > 0.01 * ww * ww) {
      du = ww * (ay * mx - axy * my) / det;
      dv = ww * (ax * my - axy * mx) / det;
    }
    // The sky step in the first stamp's pixels (every stamp's new centroid is checked above).
    x1 += (first.dvdy * du - first.dudy * dv) / det1;
    y1 += (-first.dvdx * du + first.dudx * dv) / det1;
  }
  const double ts = s.sxx + s.syy;
  if (!(ts > 0) || !std::isfinite(ts)) return m;
  m.x = u, m.y = v;
  m.flux = s.s0;
  m.t = ts / s.s0;
  m.e1 = (s.sxx - s.syy) / ts;
  m.e2 = 2 * s.sxy / ts;
  // A positive image under a positive weight has |e| < 1; noise beyond that is no shape.
  if (!(std::hypot(m.e1, m.e2) < 1)) return m;
  // Linear error propagation from each pixel's noise, the centroid held.
  double v1 = 0, v2 = 0, w2 = 0;
  const double* w = scratch;
  double* maps = scratch;
  for (const MomentsStamp& st : stamps) maps += scratch_size(st);
  for (std::size_t k = 0; k < n; ++k) {
    double xk, yk, a1 = 0, a2 = 0, aw = 0;
    stamp_centroid(k, &xk, &yk);
    const bool correlated = !noise_free && stamps[k].covariance;
    error_sums(stamps[k], xk, yk, w, ts, s.sxx - s.syy, s.sxy, &a1, &a2, &aw, correlated ? maps : nullptr);
    w += scratch_size(stamps[k]);
    const double f = c_of(stamps[k]) / c_sum / stamps[k].flux_scale;
    const double g = f * f * (noise_free ? 0.0 : correlated ? 1.0 : stamps[k].variance);
    v1 += g * a1, v2 += g * a2, w2 += g * aw;
  }
  m.e1_err = std::sqrt(v1) / (ts * ts);
  m.e2_err = std::sqrt(v2) / (ts * ts);
  m.snr = s.s0 / std::sqrt(w2);
  m.valid = true;
  return m;
}

bool usable(const MomentsStamp& s) {
  return s.size >= 1 && s.image.size() == static_cast<std::size_t>(s.size) * s.size && s.flux_scale > 0 &&
         s.dudx * s.dvdy - s.dudy * s.dvdx != 0;
}

}  // namespace

WeightedMoments weighted_moments(std::span<const MomentsStamp> stamps, double fwhm, std::vector<double>& scratch,
                                 int centroid_iterations) {
  if (stamps.empty() || !(fwhm > 0)) return {};
  std::size_t need = 0, maps = 0;
  for (const MomentsStamp& s : stamps) {
    if (!usable(s)) return {};
    need += scratch_size(s);
    if (s.covariance) maps = std::max(maps, 3 * static_cast<std::size_t>(s.size) * s.size);
  }
  need += maps;
  if (scratch.size() < need) scratch.resize(need);
  return measure(stamps, fwhm, scratch.data(), centroid_iterations);
}

WeightedMoments weighted_moments(std::span<const double> image, int size, double fwhm, double variance,
                                 std::span<double> scratch, int centroid_iterations, double start_x, double start_y) {
  MomentsStamp s;
  s.image = image;
  s.size = size;
  s.variance = variance;
  s.start_x = start_x, s.start_y = start_y;
  if (!usable(s) || !(fwhm > 0) || scratch.size() < scratch_size(s)) return {};
  return measure({&s, 1}, fwhm, scratch.data(), centroid_iterations);
}

}  // namespace stampede::kernels
