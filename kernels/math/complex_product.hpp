// Elementwise products of complex arrays, written on their real and imaginary parts: std::complex's
// operator* checks every result for NaN (C99 Annex G) and does not vectorise; these give the same
// values for finite inputs.
#pragma once
#include <complex>
#include <cstddef>

namespace stampede::kernels {

// out[i] = a[i] * b[i]; out may be a.
inline void complex_product(const std::complex<double>* a, const std::complex<double>* b, std::complex<double>* out,
                            std::size_t n) {
  const double* x = reinterpret_cast<const double*>(a);
  const double* y = reinterpret_cast<const double*>(b);
  double* z = reinterpret_cast<double*>(out);
  for (std::size_t i = 0; i < n; ++i) {
    const double xr = x[2 * i], xi = x[2 * i + 1], yr = y[2 * i], yi = y[2 * i + 1];
    z[2 * i] = xr * yr - xi * yi;
    z[2 * i + 1] = xr * yi + xi * yr;
  }
}

// a[i] *= b[i].
inline void complex_scale(std::complex<double>* a, const std::complex<double>* b, std::size_t n) {
  complex_product(a, b, a, n);
}

}  // namespace stampede::kernels
