// The quadratic form of an elliptical radius under an area-preserving shear.
//
// Conventions (../shared/data/README.md): ellipticity e = (a-b)/(a+b) (reduced-shear form),
// e1 = |e| cos 2theta, e2 = |e| sin 2theta, theta from +x towards +y; the radius r is the
// circularised radius sqrt(a b). The squared scaled distance of an offset (dx, dy) is
//   u = (xx dx^2 + 2 xy dx dy + yy dy^2),
//   xx = (1 + |e|^2 - 2 e1) / ((1 - |e|^2) r^2),  yy = (1 + |e|^2 + 2 e1) / ((1 - |e|^2) r^2),
//   xy = -2 e2 / ((1 - |e|^2) r^2),
// so u = 1 on the ellipse with semi-axes a = r sqrt((1+|e|)/(1-|e|)), b = r^2 / a.
#pragma once

namespace stampede::kernels {

struct EllipseQuadratic {
  double xx = 0.0;
  double xy = 0.0;
  double yy = 0.0;

  double operator()(double dx, double dy) const { return xx * dx * dx + 2.0 * xy * dx * dy + yy * dy * dy; }
};

// Requires |e| < 1 and r > 0.
EllipseQuadratic ellipse_quadratic(double e1, double e2, double r);

// The inverse of ellipse_quadratic: e1, e2 and r of a positive-definite form. False otherwise.
bool ellipse_parameters(const EllipseQuadratic& q, double* e1, double* e2, double* r);

// Partial derivatives of ellipse_quadratic(e1, e2, r) with respect to e1 and e2 at fixed r.
void ellipse_quadratic_derivatives(double e1, double e2, double r, EllipseQuadratic* d_e1,
                                   EllipseQuadratic* d_e2);

}  // namespace stampede::kernels
