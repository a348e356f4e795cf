// Elliptical radius quadratic form and its derivatives; see ellipse.hpp.
#include "kernels/ellipse.hpp"

namespace stampede::kernels {

EllipseQuadratic ellipse_quadratic(double e1, double e2, double r) {
  const double s = e1 * e1 + e2 * e2;
  const double k = 1.0 / ((1.0 - s) * r * r);
  return {(1.0 + s - 2.0 * e1) * k, -2.0 * e2 * k, (1.0 + s + 2.0 * e1) * k};
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
