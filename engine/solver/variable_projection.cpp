// Variable projection; see variable_projection.hpp.
#include "engine/solver/variable_projection.hpp"

#include <cmath>

namespace stampede {

bool solve_linear_amplitudes(const double g[4], const double h[2], LinearAmplitudes* out) {
  const double g00 = g[0], g01 = g[1], g11 = g[3];
  const double half_trace = 0.5 * (g00 + g11), spread = std::hypot(0.5 * (g00 - g11), g01);
  const double l1 = half_trace + spread, l2 = half_trace - spread;
  if (!(l1 > 0) || !std::isfinite(l1) || !std::isfinite(h[0]) || !std::isfinite(h[1])) return false;
  if (l2 > 1e-12 * l1) {
    const double det = g00 * g11 - g01 * g01;
    out->ginv[0][0] = g11 / det;
    out->ginv[0][1] = out->ginv[1][0] = -g01 / det;
    out->ginv[1][1] = g00 / det;
  } else {
    // Rank one: v v^T / l1, v the unit eigenvector of l1, from whichever of the two forms
    // (l1 - g11, g01) and (g01, l1 - g00) is larger (the other may vanish).
    double v0 = l1 - g11, v1 = g01;
    if (std::abs(g01) + std::abs(l1 - g00) > std::abs(v0) + std::abs(v1)) v0 = g01, v1 = l1 - g00;
    const double norm = std::hypot(v0, v1);
    if (norm > 0) {
      v0 /= norm;
      v1 /= norm;
    } else {  // G = l1 I to rounding: any direction
      v0 = 1;
      v1 = 0;
    }
    out->ginv[0][0] = v0 * v0 / l1;
    out->ginv[0][1] = out->ginv[1][0] = v0 * v1 / l1;
    out->ginv[1][1] = v1 * v1 / l1;
  }
  out->a[0] = out->ginv[0][0] * h[0] + out->ginv[0][1] * h[1];
  out->a[1] = out->ginv[1][0] * h[0] + out->ginv[1][1] * h[1];
  return std::isfinite(out->a[0]) && std::isfinite(out->a[1]);
}

void project_out(const LinearAmplitudes& la, const double* weight, const double* phi0, const double* phi1,
                 const double* column, double* out, std::size_t n) {
  double t0 = 0, t1 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double wc = weight[i] * column[i];
    t0 += wc * phi0[i];
    t1 += wc * phi1[i];
  }
  const double c0 = la.ginv[0][0] * t0 + la.ginv[0][1] * t1, c1 = la.ginv[1][0] * t0 + la.ginv[1][1] * t1;
  for (std::size_t i = 0; i < n; ++i) out[i] = column[i] - c0 * phi0[i] - c1 * phi1[i];
}

}  // namespace stampede
