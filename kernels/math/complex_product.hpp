// Elementwise products of complex arrays, written on their real and imaginary parts: std::complex's
// operator* checks every result for NaN (C99 Annex G) and does not vectorise; these give the same
// values for finite inputs. T: double or float.
#pragma once
#include <complex>
#include <cstddef>

namespace stampede::kernels {

// out[i] = a[i] * b[i]; out may be a.
template <class T>
inline void complex_product(const std::complex<T>* a, const std::complex<T>* b, std::complex<T>* out, std::size_t n) {
  const T* x = reinterpret_cast<const T*>(a);
  const T* y = reinterpret_cast<const T*>(b);
  T* z = reinterpret_cast<T*>(out);
  for (std::size_t i = 0; i < n; ++i) {
    const T xr = x[2 * i], xi = x[2 * i + 1], yr = y[2 * i], yi = y[2 * i + 1];
    z[2 * i] = xr * yr - xi * yi;
    z[2 * i + 1] = xr * yi + xi * yr;
  }
}

// a[i] *= b[i].
template <class T>
inline void complex_scale(std::complex<T>* a, const std::complex<T>* b, std::size_t n) {
  complex_product(a, b, a, n);
}

}  // namespace stampede::kernels
