// Variable projection for a model linear in two of its parameters (Golub & Pereyra 1973; the
// Jacobian of Kaufman 1975): m = a0 phi0 + a1 phi1 with phi0, phi1 depending on the others. At
// given non-linear parameters the amplitudes are the weighted least-squares solution
// a = G^-1 h, G = Phi^T W Phi, h = Phi^T W d; the solver then sees only the non-linear
// parameters, with the model's derivative at those amplitudes projected W-orthogonally to phi0
// and phi1. The residual d - m is then W-orthogonal to both, so the gradient J^T W r is exact.
#pragma once

#include <cstddef>

namespace stampede {

// a = G^-1 h and G's inverse. G's eigenvalues are compared: a direction whose eigenvalue is below
// 1e-12 of the other's (phi0 and phi1 indistinguishable on the weighted pixels) gets no amplitude
// and no projection (the pseudo-inverse), so a degenerate pair gives finite amplitudes.
struct LinearAmplitudes {
  double a[2] = {0, 0};
  double ginv[2][2] = {{0, 0}, {0, 0}};
};
// g: G row-major (g[1] = g[2]); false when G is not positive (no weighted pixel sees either
// image) or a value is not finite.
bool solve_linear_amplitudes(const double g[4], const double h[2], LinearAmplitudes* out);

// out[i] = column[i] - c0 phi0[i] - c1 phi1[i], (c0, c1) = G^-1 Phi^T W column: the part of
// `column` W-orthogonal to phi0 and phi1. `out` may be `column`.
void project_out(const LinearAmplitudes& la, const double* weight, const double* phi0, const double* phi1,
                 const double* column, double* out, std::size_t n);

}  // namespace stampede
