// A galaxy in (u, v) arcsec as seen in a cutout's pixels, worked out from the real-space quadratic
// form (kernels/ellipse: q = N / ((1 - s) r^2), N = [[1 + s - 2 e1, -2 e2], [., 1 + s + 2 e1]],
// det q = r^-4) and not through PixelFrame's own code, so tests of the frame path compare against
// an independent derivation: Q_pix(dx) = Q_sky(J dx), centre x_ref + J^-1 (u0, v0).
#pragma once

#include <cmath>

#include "engine/model/pixel_frame.hpp"

namespace stampede::testing {

struct PixelEllipse {
  double e1 = 0, e2 = 0, radius = 0;  // reduced shear; circularised radius in pixels
  double x = 0, y = 0;                // centre in the cutout
};

inline PixelEllipse sky_to_pixel(double e1, double e2, double radius, double u0, double v0, const PixelFrame& f) {
  const double s = e1 * e1 + e2 * e2, k = 1 / ((1 - s) * radius * radius);
  const double Q[2][2] = {{(1 + s - 2 * e1) * k, -2 * e2 * k}, {-2 * e2 * k, (1 + s + 2 * e1) * k}};
  const double J[2][2] = {{f.dudx, f.dudy}, {f.dvdx, f.dvdy}};
  double P[2][2];  // J^T Q J
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      P[i][j] = 0;
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b) P[i][j] += J[a][i] * Q[a][b] * J[b][j];
    }
  PixelEllipse out;
  const double det = P[0][0] * P[1][1] - P[0][1] * P[0][1];
  out.radius = std::pow(det, -0.25);
  const double r2 = out.radius * out.radius;
  const double t = (P[0][0] + P[1][1]) * r2 / 2;  // (1 + s') / (1 - s')
  const double sp = (t - 1) / (t + 1);
  out.e1 = (P[1][1] - P[0][0]) * r2 * (1 - sp) / 4;
  out.e2 = -P[0][1] * r2 * (1 - sp) / 2;
  const double jd = J[0][0] * J[1][1] - J[0][1] * J[1][0];
  out.x = f.x_ref + (J[1][1] * u0 - J[0][1] * v0) / jd;
  out.y = f.y_ref + (-J[1][0] * u0 + J[0][0] * v0) / jd;
  return out;
}

}  // namespace stampede::testing
