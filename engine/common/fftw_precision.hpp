// FFTW's API for one floating-point precision (fftw_* for double, fftwf_* for float), so that a
// class written once over `Real` plans and runs either. Plans are kept as void* by their owners;
// every planner call is made under fftw_planner_mutex() by the caller.
#pragma once

#include <fftw3.h>

#include <complex>

namespace stampede {

template <class Real>
struct Fftw;

template <>
struct Fftw<double> {
  using Complex = fftw_complex;
  using Plan = fftw_plan;
  static Complex* c(std::complex<double>* p) { return reinterpret_cast<Complex*>(p); }
  static Plan r2c_2d(int n0, int n1, double* in, Complex* out, unsigned f) { return fftw_plan_dft_r2c_2d(n0, n1, in, out, f); }
  static Plan c2r_2d(int n0, int n1, Complex* in, double* out, unsigned f) { return fftw_plan_dft_c2r_2d(n0, n1, in, out, f); }
  static Plan dft_1d(int n, Complex* in, Complex* out, int sign, unsigned f) { return fftw_plan_dft_1d(n, in, out, sign, f); }
  static Plan many_r2c(int rank, const int* n, int howmany, double* in, int istride, int idist, Complex* out, int ostride,
                       int odist, unsigned f) {
    return fftw_plan_many_dft_r2c(rank, n, howmany, in, nullptr, istride, idist, out, nullptr, ostride, odist, f);
  }
  static Plan many_c2r(int rank, const int* n, int howmany, Complex* in, int istride, int idist, double* out, int ostride,
                       int odist, unsigned f) {
    return fftw_plan_many_dft_c2r(rank, n, howmany, in, nullptr, istride, idist, out, nullptr, ostride, odist, f);
  }
  static Plan many_c2c(int rank, const int* n, int howmany, Complex* in, int istride, int idist, Complex* out, int ostride,
                       int odist, int sign, unsigned f) {
    return fftw_plan_many_dft(rank, n, howmany, in, nullptr, istride, idist, out, nullptr, ostride, odist, sign, f);
  }
  static void execute(void* p) { fftw_execute(static_cast<Plan>(p)); }
  static void execute_r2c(void* p, double* in, Complex* out) { fftw_execute_dft_r2c(static_cast<Plan>(p), in, out); }
  static void execute_c2r(void* p, Complex* in, double* out) { fftw_execute_dft_c2r(static_cast<Plan>(p), in, out); }
  static void execute_c2c(void* p, Complex* in, Complex* out) { fftw_execute_dft(static_cast<Plan>(p), in, out); }
  static void destroy(void* p) { fftw_destroy_plan(static_cast<Plan>(p)); }
};

template <>
struct Fftw<float> {
  using Complex = fftwf_complex;
  using Plan = fftwf_plan;
  static Complex* c(std::complex<float>* p) { return reinterpret_cast<Complex*>(p); }
  static Plan r2c_2d(int n0, int n1, float* in, Complex* out, unsigned f) { return fftwf_plan_dft_r2c_2d(n0, n1, in, out, f); }
  static Plan c2r_2d(int n0, int n1, Complex* in, float* out, unsigned f) { return fftwf_plan_dft_c2r_2d(n0, n1, in, out, f); }
  static Plan dft_1d(int n, Complex* in, Complex* out, int sign, unsigned f) { return fftwf_plan_dft_1d(n, in, out, sign, f); }
  static Plan many_r2c(int rank, const int* n, int howmany, float* in, int istride, int idist, Complex* out, int ostride,
                       int odist, unsigned f) {
    return fftwf_plan_many_dft_r2c(rank, n, howmany, in, nullptr, istride, idist, out, nullptr, ostride, odist, f);
  }
  static Plan many_c2r(int rank, const int* n, int howmany, Complex* in, int istride, int idist, float* out, int ostride,
                       int odist, unsigned f) {
    return fftwf_plan_many_dft_c2r(rank, n, howmany, in, nullptr, istride, idist, out, nullptr, ostride, odist, f);
  }
  static Plan many_c2c(int rank, const int* n, int howmany, Complex* in, int istride, int idist, Complex* out, int ostride,
                       int odist, int sign, unsigned f) {
    return fftwf_plan_many_dft(rank, n, howmany, in, nullptr, istride, idist, out, nullptr, ostride, odist, sign, f);
  }
  static void execute(void* p) { fftwf_execute(static_cast<Plan>(p)); }
  static void execute_r2c(void* p, float* in, Complex* out) { fftwf_execute_dft_r2c(static_cast<Plan>(p), in, out); }
  static void execute_c2r(void* p, Complex* in, float* out) { fftwf_execute_dft_c2r(static_cast<Plan>(p), in, out); }
  static void execute_c2c(void* p, Complex* in, Complex* out) { fftwf_execute_dft(static_cast<Plan>(p), in, out); }
  static void destroy(void* p) { fftwf_destroy_plan(static_cast<Plan>(p)); }
};

}  // namespace stampede
