// Elliptical radius quadratic form and its derivatives; see ellipse.hpp.
#include "kernels/ellipse.hpp"

#include <cmath>

namespace stampede::kernels {

EllipseQuadratic ellipse_quadratic(double e1, double e2, double r) {
  const double s = e1 * e1 + e2 * e2;
  const double k = 1.0 / ((1.0 - s) * r * r);
  return {(1.0 + s - 2.0 * e1) * k, -2.0 * e2 * k, (1.0 + s + 2.0 * e1) * k};
}

bool ellipse_parameters(const EllipseQuadratic& q, double* e1, double* e2, double* r) {
  // det q = r^-4; with q' = q r^2: trace q' = 2 (1 + s) / (1 - s), q'yy - q'xx = 4 e1 / (1 - s),
  // q'xy = -2 e2 / (1 - s).
  const double det = q.xx * q.yy - q.xy * q.xy;
  if (!(det > 0) || !(q.xx > 0) || !std::isfinite(det)) return false;
  const double r2 = 1.0 / std::sqrt(det);
  const double t = 0.5 * (q.xx + q.yy) * r2;  // (1 + s) / (1 - s) >= 1
  const double one_minus_s = 2.0 / (t + 1.0);
  *e1 = 0.25 * (q.yy - q.xx) * r2 * one_minus_s;
  *e2 = -0.5 * q.xy * r2 * one_minus_s;
  *r = std::sqrt(r2);
  return true;
}

void ellipse_quadratic_derivatives(double e1, double e2, double r, EllipseQuadratic* d_e1,
                                   EllipseQuadratic* d_e2) {
  // q = N / ((1 - s) r^2) with s = |e|^2: dq/de = (dN/de) k + N * 2 e k / (1 - s).
  const double s = e1 * e1 + e2 * e2;
  const double k = 1.0 / ((1.0 - s) * r * r);
  const double nxx = 1.0 + s - 2.0 * e1;
  const double nxy = -2.0 * e2;
  const double nyy = 1.0 + s + 2.0 * e1;
  const double g1 = 2.0 * e1 * k / (1.0 - s);
  const double g2 = 2.0 * e2 * k / (1.0 - s);
  *d_e1 = {(2.0 * e1 - 2.0) * k + nxx * g1, nxy * g1, (2.0 * e1 + 2.0) * k + nyy * g1};
  *d_e2 = {2.0 * e2 * k + nxx * g2, -2.0 * k + nxy * g2, 2.0 * e2 * k + nyy * g2};
}

}  // namespace stampede::kernels
