// A single-precision prototype, measured beside the double render it would replace (one of the
// cheaper renders weighed in docs/performance.md, "The floor of a fit that ends on the exact
// model"): the exact renderer's Jacobian term loop (7 spectra) and its pruned inverse (column c2c +
// stamp-row c2r) in float, 16 AVX-512 lanes (two alias entries of one spectrum block per vector),
// against the double kernels and fftw plans the renderer uses. Fiducial PSF (Moffat beta 3, FWHM
// 2.85, e = (0, 0.05)), N = 96, 39-pixel stamp; a bulge + disc galaxy (r = 2 px, e = (0.3, -0.2)).
//   BM_JacobianTermsDouble / BM_JacobianTermsFloat     the term loop alone
//   BM_JacobianInverseDouble / BM_JacobianInverseFloat  the seven inverses alone
// The error counter `worst_over_peak`: max |float - double| over the seven stamps, over each
// stamp's own peak (the model image's error is the first number reported, for the 1e-6 budget).
// Built only where the compiler targets AVX-512 (the prototype's lane layout).
#include <benchmark/benchmark.h>
#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <vector>
#include <xsimd/xsimd.hpp>

#include "engine/model/psf_model.hpp"
#include "engine/render/exact_psf.hpp"
#include "engine/render/exact_renderer.hpp"
#include "engine/sim/great08_sim.hpp"
#include "kernels/aligned_vector.hpp"
#include "kernels/kspace_render.hpp"
#include "kernels/sersic.hpp"

namespace {

using namespace stampede;
using kernels::kKBlock;
using F = xsimd::batch<float, xsimd::avx512f>;
using I = xsimd::batch<std::int32_t, xsimd::avx512f>;
constexpr int kImages = kernels::kNumKSpaceImages;
constexpr int kStamp = 39;
constexpr double kPi = std::numbers::pi;

// The term list regrouped for 16 float lanes: per spectrum block, its entries in pairs (an odd
// count padded with a zero-PSF entry), lanes 0-7 the first entry's, 8-15 the second's.
struct FloatTerms {
  std::vector<std::int32_t> block_begin;  // pair ranges per block
  kernels::AlignedVector<float> kx, ky, ppi;  // 16 per pair
  std::vector<std::int32_t> alias0, alias1;   // per pair
};

FloatTerms to_float(const kernels::KSpaceTerms& t) {
  FloatTerms f;
  f.block_begin.push_back(0);
  int pairs = 0;
  for (int b = 0; b < t.blocks(); ++b) {
    for (int e = t.block_begin[b]; e < t.block_begin[b + 1]; e += 2) {
      for (int h = 0; h < 2; ++h) {
        const int ee = e + h;
        const bool real = ee < t.block_begin[b + 1];
        const int src = real ? ee : e;
        for (int l = 0; l < kKBlock; ++l) {
          f.kx.push_back(static_cast<float>(t.kx_values[t.entry_ix[src] + l]));
          f.ky.push_back(static_cast<float>(t.ky_values[t.entry_iy[src]]));
          f.ppi.push_back(real ? static_cast<float>(t.ppi[static_cast<std::size_t>(src) * kKBlock + l]) : 0.0f);
        }
        (h == 0 ? f.alias0 : f.alias1).push_back(t.entry_alias[src]);
      }
      ++pairs;
    }
    f.block_begin.push_back(pairs);
  }
  return f;
}

// The de Vaucouleurs table in float: the same intervals (an octave of w in 16 by the leading
// mantissa bits), so the coefficients carry over and only the index's exponent bias changes.
struct FloatTable {
  std::int32_t index_base = 0;
  float w_lo = 0, w_last = 0, c2 = 0;
  kernels::AlignedVector<float> coefficients;
};

FloatTable to_float(const kernels::SersicKTable& t) {
  FloatTable f;
  // double index: (biased exponent 1023) << 4 | top 4 mantissa bits; float: (bias 127) << 4 | same.
  f.index_base = static_cast<std::int32_t>(t.index_base - (1023 - 127) * 16);
  f.w_lo = static_cast<float>(t.w_lo);
  f.w_last = static_cast<float>(t.w_last);
  f.c2 = static_cast<float>(t.c2);
  f.coefficients.assign(t.coefficients.size(), 0.0f);
  for (std::size_t i = 0; i < t.coefficients.size(); ++i) f.coefficients[i] = static_cast<float>(t.coefficients[i]);
  return f;
}

struct FloatModel {
  float b[9], d[9];  // wxx wxy wyy, e1xx e1xy e1yy, e2xx e2xy e2yy
  float bflux, dflux, bfpa, dfpa, dlnr;
  std::vector<float> bin_x_re, bin_x_im, bin_y_re, bin_y_im, alias_re, alias_im;
};

inline F form(const float* c, F kxx, F kxy, F kyy) { return F(c[0]) * kxx + F(2.0f * c[1]) * kxy + F(c[2]) * kyy; }

// The float twin of the double kernels' Jacobian pass (bulge tabulated, disc exponential; the
// table's tail beyond w_last is clamped, which the galaxy here never reaches at |k| <= 7).
void float_jacobian(const FloatTerms& t, const FloatTable& tab, const FloatModel& m, int row_stride,
                    float* const* re_out, float* const* im_out) {
  const float b1 = static_cast<float>(kernels::sersic_b(1.0)), inv_b2 = 1.0f / (b1 * b1);
  const auto lo_mask = xsimd::batch_bool_constant<F, true, true, true, true, true, true, true, true,
                                                  false, false, false, false, false, false, false, false>();
  const int per_row = row_stride / kKBlock;
  const int blocks = static_cast<int>(t.block_begin.size()) - 1;
  for (int b = 0; b < blocks; ++b) {
    F ar[kImages], ai[kImages];
    for (int k = 0; k < kImages; ++k) ar[k] = ai[k] = F(0.0f);
    for (int p = t.block_begin[b]; p < t.block_begin[b + 1]; ++p) {
      const std::size_t o = static_cast<std::size_t>(p) * 16;
      const F kx = F::load_aligned(t.kx.data() + o), ky = F::load_aligned(t.ky.data() + o);
      const F ppi = F::load_aligned(t.ppi.data() + o);
      const F cr = xsimd::select(lo_mask, F(m.alias_re[t.alias0[p]]), F(m.alias_re[t.alias1[p]]));
      const F ci = xsimd::select(lo_mask, F(m.alias_im[t.alias0[p]]), F(m.alias_im[t.alias1[p]]));
      const F kxx = kx * kx, kxy = kx * ky, kyy = ky * ky;
      const F wb = form(m.b, kxx, kxy, kyy), wd = form(m.d, kxx, kxy, kyy);
      // Bulge: the table's polynomial, indexed from the float's bits.
      const F ws = xsimd::min(xsimd::max(wb, F(tab.w_lo)), F(tab.w_last));
      const I bits = xsimd::bitwise_cast<I>(ws);
      const I idx = ((bits >> 19) - I(tab.index_base)) << 3;
      const F u = xsimd::bitwise_cast<F>(((bits << 4) & I(0x007FFFFF)) | I(0x3F800000)) - F(1.0f);
      const F inv = xsimd::bitwise_cast<F>(I(0x7F000000) - (bits & I(0x7F800000)));
      const float* c = tab.coefficients.data();
      const F c5 = F::gather(c + 5, idx), c4 = F::gather(c + 4, idx), c3 = F::gather(c + 3, idx);
      const F c2 = F::gather(c + 2, idx), c1 = F::gather(c + 1, idx), c0 = F::gather(c, idx);
      F fbv = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0;
      F fbs = ((((F(5.0f) * c5 * u + F(4.0f) * c4) * u + F(3.0f) * c3) * u + F(2.0f) * c2) * u + c1) * (F(16.0f) * inv);
      const auto small = wb < F(tab.w_lo);
      fbv = xsimd::select(small, F(1.0f) - F(tab.c2) * wb, fbv);
      fbs = xsimd::select(small, F(-tab.c2), fbs);
      // Disc: the exponential in closed form.
      const F tt = F(1.0f) + wd * F(inv_b2);
      const F r = F(1.0f) / xsimd::sqrt(tt);
      const F r2 = r * r;
      const F fdv = r2 * r, fds = F(-1.5f * inv_b2) * fdv * r2;
      const F vb = fbv * ppi, vd = fdv * ppi;
      auto add = [&](int k, F w) {
        ar[k] = xsimd::fma(w, cr, ar[k]);
        ai[k] = xsimd::fma(w, ci, ai[k]);
      };
      add(kernels::kKBulge, F(m.bfpa) * vb);
      add(kernels::kKDisc, F(m.dfpa) * vd);
      const F g = F(m.bflux) * vb + F(m.dflux) * vd;
      add(kernels::kKX0, g * kx);
      add(kernels::kKY0, g * ky);
      const F sb = F(m.bflux) * fbs * ppi, sd = F(m.dflux) * fds * ppi;
      add(kernels::kKE1, sb * form(m.b + 3, kxx, kxy, kyy) + sd * form(m.d + 3, kxx, kxy, kyy));
      add(kernels::kKE2, sb * form(m.b + 6, kxx, kxy, kyy) + sd * form(m.d + 6, kxx, kxy, kyy));
      add(kernels::kKRadius, F(2.0f * m.dlnr) * (g + sb * wb + sd * wd));
    }
    const std::size_t row = static_cast<std::size_t>(b / per_row);
    const std::size_t col = static_cast<std::size_t>(b % per_row) * kKBlock;
    const std::size_t o = row * row_stride + col;
    using F8 = xsimd::batch<float, xsimd::avx2>;
    const F8 bxr = F8::load_unaligned(m.bin_x_re.data() + col), bxi = F8::load_unaligned(m.bin_x_im.data() + col);
    const F8 byr(m.bin_y_re[row]), byi(m.bin_y_im[row]);
    const F8 pr = bxr * byr - bxi * byi, pi = bxr * byi + bxi * byr;
    for (int k = 0; k < kImages; ++k) {
      alignas(64) float lr[16], li[16];
      ar[k].store_aligned(lr);
      ai[k].store_aligned(li);
      const F8 sr = F8::load_aligned(lr) + F8::load_aligned(lr + 8), si = F8::load_aligned(li) + F8::load_aligned(li + 8);
      F8 xr = sr * pr - si * pi, xi = sr * pi + si * pr;
      if (k == kernels::kKX0 || k == kernels::kKY0) {
        const F8 tmp = xr;
        xr = xi;
        xi = -tmp;
      }
      xr.store_unaligned(re_out[k] + o);
      xi.store_unaligned(im_out[k] + o);
    }
  }
}

// One shared set-up: the PSF's terms, the galaxy's transform parameters in both precisions, the
// double and float spectra, plans and stamps.
struct Setup {
  std::shared_ptr<const ExactPsf> psf;
  std::shared_ptr<const kernels::SersicKTable> table;
  kernels::KSpaceModel model;
  FloatTerms fterms;
  FloatTable ftable;
  FloatModel fmodel;
  int n = 0, row_stride = 0, half = 0;
  std::vector<double> bin_x_re, bin_x_im, bin_y_re, bin_y_im, alias_re, alias_im;
  std::vector<kernels::AlignedVector<double>> dre, dim;
  std::vector<kernels::AlignedVector<float>> fre, fim;
  fftw_complex* dc = nullptr;
  fftw_complex* dc2 = nullptr;
  fftwf_complex* fc = nullptr;
  fftwf_complex* fc2 = nullptr;
  std::vector<double> dgrid;
  std::vector<float> fgrid;
  fftw_plan dcol{}, drow{};
  fftwf_plan fcol{}, frow{};
};

void fill_component(double r, double e1, double e2, double flux, const kernels::SersicKTable* table,
                    kernels::KSpaceComponent* c) {
  // A sheared circle: W = r^2 S^T S with S the shear matrix of (e1, e2) (|e| < 1), derivatives by
  // central differences of the same form (any smooth forms do for the timing and the precision).
  auto w_of = [&](double a, double b, double* xx, double* xy, double* yy) {
    const double g = std::hypot(a, b), s = std::sqrt(1 - g * g);
    const double m00 = (1 + a) / s, m01 = b / s, m11 = (1 - a) / s;
    *xx = r * r * (m00 * m00 + m01 * m01);
    *xy = r * r * (m00 * m01 + m01 * m11);
    *yy = r * r * (m01 * m01 + m11 * m11);
  };
  w_of(e1, e2, &c->wxx, &c->wxy, &c->wyy);
  const double h = 1e-6;
  double p[3], q[3];
  w_of(e1 + h, e2, p, p + 1, p + 2);
  w_of(e1 - h, e2, q, q + 1, q + 2);
  c->e1xx = (p[0] - q[0]) / (2 * h);
  c->e1xy = (p[1] - q[1]) / (2 * h);
  c->e1yy = (p[2] - q[2]) / (2 * h);
  w_of(e1, e2 + h, p, p + 1, p + 2);
  w_of(e1, e2 - h, q, q + 1, q + 2);
  c->e2xx = (p[0] - q[0]) / (2 * h);
  c->e2xy = (p[1] - q[1]) / (2 * h);
  c->e2yy = (p[2] - q[2]) / (2 * h);
  c->table = table;
  c->flux = flux;
  c->flux_per_amplitude = 1.0;
}

Setup& setup() {
  static Setup s = [] {
    Setup s;
    s.n = exact_period(kStamp);
    std::string err;
    s.psf = build_exact_psf(Great08SimOptions::default_psf(), s.n, 1e-7, &err);
    const kernels::KSpaceTerms& t = s.psf->terms();
    s.row_stride = t.row_stride;
    s.half = s.n / 2 + 1;
    s.table = de_vaucouleurs_k_table();
    fill_component(2.0 * 1.4, 0.3, -0.2, 0.3, s.table.get(), &s.model.bulge);  // r_e: im3shape's bulge/disc radius ratio
    fill_component(2.0, 0.3, -0.2, 0.7, nullptr, &s.model.disc);
    s.model.dlnr = 0.5;
    const double x0 = 19.3, y0 = 18.8, dk = 2 * kPi / s.n;
    s.bin_x_re.resize(s.row_stride);
    s.bin_x_im.resize(s.row_stride);
    for (int j = 0; j < s.row_stride; ++j) {
      s.bin_x_re[j] = std::cos(-dk * j * x0);
      s.bin_x_im[j] = std::sin(-dk * j * x0);
    }
    s.bin_y_re.resize(s.n);
    s.bin_y_im.resize(s.n);
    for (int j = 0; j < s.n; ++j) {
      const int f = j <= s.n / 2 ? j : j - s.n;
      s.bin_y_re[j] = std::cos(-dk * f * y0);
      s.bin_y_im[j] = std::sin(-dk * f * y0);
    }
    const int a = t.aliases();
    for (int ax = 0; ax < a; ++ax)
      for (int ay = 0; ay < a; ++ay) {
        const double ph = -2 * kPi * ((ax - t.alias_max) * x0 + (ay - t.alias_max) * y0);
        s.alias_re.push_back(std::cos(ph));
        s.alias_im.push_back(std::sin(ph));
      }
    s.model.bin_phase_x_re = s.bin_x_re.data();
    s.model.bin_phase_x_im = s.bin_x_im.data();
    s.model.bin_phase_y_re = s.bin_y_re.data();
    s.model.bin_phase_y_im = s.bin_y_im.data();
    s.model.alias_phase_re = s.alias_re.data();
    s.model.alias_phase_im = s.alias_im.data();
    s.fterms = to_float(t);
    s.ftable = to_float(*s.table);
    auto copy9 = [](const kernels::KSpaceComponent& c, float* o) {
      const double v[9] = {c.wxx, c.wxy, c.wyy, c.e1xx, c.e1xy, c.e1yy, c.e2xx, c.e2xy, c.e2yy};
      for (int i = 0; i < 9; ++i) o[i] = static_cast<float>(v[i]);
    };
    copy9(s.model.bulge, s.fmodel.b);
    copy9(s.model.disc, s.fmodel.d);
    s.fmodel.bflux = static_cast<float>(s.model.bulge.flux);
    s.fmodel.dflux = static_cast<float>(s.model.disc.flux);
    s.fmodel.bfpa = s.fmodel.dfpa = 1.0f;
    s.fmodel.dlnr = static_cast<float>(s.model.dlnr);
    auto tf = [](const std::vector<double>& v) { return std::vector<float>(v.begin(), v.end()); };
    s.fmodel.bin_x_re = tf(s.bin_x_re);
    s.fmodel.bin_x_im = tf(s.bin_x_im);
    s.fmodel.bin_y_re = tf(s.bin_y_re);
    s.fmodel.bin_y_im = tf(s.bin_y_im);
    s.fmodel.alias_re = tf(s.alias_re);
    s.fmodel.alias_im = tf(s.alias_im);
    const std::size_t spectrum = static_cast<std::size_t>(s.n) * s.row_stride;
    s.dre.assign(kImages, kernels::AlignedVector<double>(spectrum, 0.0));
    s.dim.assign(kImages, kernels::AlignedVector<double>(spectrum, 0.0));
    s.fre.assign(kImages, kernels::AlignedVector<float>(spectrum, 0.0f));
    s.fim.assign(kImages, kernels::AlignedVector<float>(spectrum, 0.0f));
    s.dc = fftw_alloc_complex(static_cast<std::size_t>(s.n) * s.half);
    s.fc = fftwf_alloc_complex(static_cast<std::size_t>(s.n) * s.half);
    s.dgrid.assign(static_cast<std::size_t>(kStamp) * s.n, 0.0);
    s.fgrid.assign(static_cast<std::size_t>(kStamp) * s.n, 0.0f);
    const unsigned flags = FFTW_ESTIMATE | FFTW_DESTROY_INPUT;
    // The renderer's inverse: transposed interleaved spectrum, contiguous column c2c out of place,
    // then the stamp rows' c2r.
    s.dc2 = fftw_alloc_complex(static_cast<std::size_t>(s.n) * s.half);
    s.fc2 = fftwf_alloc_complex(static_cast<std::size_t>(s.n) * s.half);
    s.dcol = fftw_plan_many_dft(1, &s.n, s.half, s.dc, nullptr, 1, s.n, s.dc2, nullptr, 1, s.n, FFTW_BACKWARD, flags);
    s.drow = fftw_plan_many_dft_c2r(1, &s.n, kStamp, s.dc2, nullptr, s.n, 1, s.dgrid.data(), nullptr, 1, s.n, flags);
    s.fcol = fftwf_plan_many_dft(1, &s.n, s.half, s.fc, nullptr, 1, s.n, s.fc2, nullptr, 1, s.n, FFTW_BACKWARD, flags);
    s.frow = fftwf_plan_many_dft_c2r(1, &s.n, kStamp, s.fc2, nullptr, s.n, 1, s.fgrid.data(), nullptr, 1, s.n, flags);
    return s;
  }();
  return s;
}

void double_terms(Setup& s) {
  kernels::KSpaceSpectra out;
  for (int k = 0; k < kImages; ++k) {
    out.re[k] = s.dre[k].data();
    out.im[k] = s.dim[k].data();
  }
  kernels::kspace_kernels().accumulate_jacobian(s.psf->terms(), s.model, out);
}

void float_terms(Setup& s) {
  float* re[kImages];
  float* im[kImages];
  for (int k = 0; k < kImages; ++k) {
    re[k] = s.fre[k].data();
    im[k] = s.fim[k].data();
  }
  float_jacobian(s.fterms, s.ftable, s.fmodel, s.row_stride, re, im);
}

template <class Real, class Complex>
void interleave(const Real* re, const Real* im, int n, int row_stride, int half, Complex* c) {
  for (int jy = 0; jy < n; ++jy)
    for (int jx = 0; jx < half; ++jx) {
      c[jx * n + jy][0] = re[static_cast<std::size_t>(jy) * row_stride + jx];
      c[jx * n + jy][1] = im[static_cast<std::size_t>(jy) * row_stride + jx];
    }
}

void double_inverse(Setup& s, int k, double* stamp) {
  interleave(s.dre[k].data(), s.dim[k].data(), s.n, s.row_stride, s.half, s.dc);
  fftw_execute(s.dcol);
  fftw_execute(s.drow);
  for (int y = 0; y < kStamp; ++y) std::copy_n(s.dgrid.data() + y * s.n, kStamp, stamp + y * kStamp);
}

void float_inverse(Setup& s, int k, float* stamp) {
  interleave(s.fre[k].data(), s.fim[k].data(), s.n, s.row_stride, s.half, s.fc);
  fftwf_execute(s.fcol);
  fftwf_execute(s.frow);
  for (int y = 0; y < kStamp; ++y) std::copy_n(s.fgrid.data() + y * s.n, kStamp, stamp + y * kStamp);
}

// Worst |float - double| / peak over the seven stamps (each over its own peak), and the model's.
void report_error(benchmark::State& state, Setup& s) {
  double_terms(s);
  float_terms(s);
  std::vector<double> d(kStamp * kStamp);
  std::vector<float> f(kStamp * kStamp);
  double worst = 0, model_worst = 0;
  std::vector<double> model_d(kStamp * kStamp, 0.0), model_f(kStamp * kStamp, 0.0);
  for (int k = 0; k < kImages; ++k) {
    double_inverse(s, k, d.data());
    float_inverse(s, k, f.data());
    double peak = 0, diff = 0;
    for (int i = 0; i < kStamp * kStamp; ++i) {
      peak = std::max(peak, std::abs(d[i]));
      diff = std::max(diff, std::abs(d[i] - f[i]));
    }
    worst = std::max(worst, diff / peak);
    const double a = k == kernels::kKBulge ? s.model.bulge.flux : k == kernels::kKDisc ? s.model.disc.flux : 0.0;
    for (int i = 0; i < kStamp * kStamp; ++i) {
      model_d[i] += a * d[i];
      model_f[i] += a * f[i];
    }
  }
  double peak = 0, diff = 0;
  for (int i = 0; i < kStamp * kStamp; ++i) {
    peak = std::max(peak, std::abs(model_d[i]));
    diff = std::max(diff, std::abs(model_d[i] - model_f[i]));
  }
  model_worst = diff / peak;
  state.counters["model_worst_over_peak"] = model_worst;
  state.counters["worst_over_peak"] = worst;
  state.counters["terms"] = static_cast<double>(s.psf->terms().entries() * kKBlock);
}

void BM_JacobianTermsDouble(benchmark::State& state) {
  Setup& s = setup();
  for (auto _ : state) {
    double_terms(s);
    benchmark::DoNotOptimize(s.dre[0].data());
  }
  report_error(state, s);
}
void BM_JacobianTermsFloat(benchmark::State& state) {
  Setup& s = setup();
  for (auto _ : state) {
    float_terms(s);
    benchmark::DoNotOptimize(s.fre[0].data());
  }
  report_error(state, s);
}
void BM_JacobianInverseDouble(benchmark::State& state) {
  Setup& s = setup();
  double_terms(s);
  std::vector<double> stamp(kStamp * kStamp);
  for (auto _ : state)
    for (int k = 0; k < kImages; ++k) {
      double_inverse(s, k, stamp.data());
      benchmark::DoNotOptimize(stamp.data());
    }
}
void BM_JacobianInverseFloat(benchmark::State& state) {
  Setup& s = setup();
  float_terms(s);
  std::vector<float> stamp(kStamp * kStamp);
  for (auto _ : state)
    for (int k = 0; k < kImages; ++k) {
      float_inverse(s, k, stamp.data());
      benchmark::DoNotOptimize(stamp.data());
    }
}
// The per-render term cut: the fraction of the term list's entries whose largest lane still has
// |G PPi| above the list's own tolerance (1e-7 of PPi(0)) for a galaxy of unit flux (bulge
// fraction 0.3, bulge r_e 1.4 x the disc's, e = (0.3, -0.2)), disc radius range(0) / 10 pixels.
// Counters: kept (fraction of entries), kept_lane_terms.
void BM_TermCutFraction(benchmark::State& state) {
  Setup& s = setup();
  const double r = state.range(0) / 10.0, tolerance = 1e-7;
  kernels::KSpaceComponent b, d;
  fill_component(1.4 * r, 0.3, -0.2, 0.3, s.table.get(), &b);
  fill_component(r, 0.3, -0.2, 0.7, nullptr, &d);
  const kernels::KSpaceTerms& t = s.psf->terms();
  const double b1 = kernels::sersic_b(1.0), inv_b2 = 1.0 / (b1 * b1), n2 = double(t.n) * t.n;
  long long kept = 0;
  for (auto _ : state) {
    kept = 0;
    for (long long e = 0; e < t.entries(); ++e) {
      const double ky = t.ky_values[t.entry_iy[e]];
      double largest = 0;
      for (int l = 0; l < kKBlock; ++l) {
        const double kx = t.kx_values[t.entry_ix[e] + l];
        const double wb = b.wxx * kx * kx + 2 * b.wxy * kx * ky + b.wyy * ky * ky;
        const double wd = d.wxx * kx * kx + 2 * d.wxy * kx * ky + d.wyy * ky * ky;
        double fb = 0, slope = 0;
        s.table->evaluate(wb, &fb, &slope);
        const double fd = std::pow(1 + wd * inv_b2, -1.5);
        largest = std::max(largest, std::abs(t.ppi[e * kKBlock + l] * n2) * (0.3 * std::abs(fb) + 0.7 * fd));
      }
      kept += largest > tolerance;
    }
    benchmark::DoNotOptimize(kept);
  }
  state.counters["kept"] = double(kept) / double(t.entries());
}
BENCHMARK(BM_TermCutFraction)->ArgName("r10")->Arg(3)->Arg(5)->Arg(10)->Arg(20)->Arg(30)->Arg(50)->Iterations(1)->Unit(benchmark::kMillisecond);

BENCHMARK(BM_JacobianTermsDouble)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_JacobianTermsFloat)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_JacobianInverseDouble)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_JacobianInverseFloat)->Unit(benchmark::kMicrosecond);

}  // namespace

int main(int argc, char** argv) {
  // Compiled for AVX-512: on another CPU say so instead of dying of an illegal instruction.
  if (!__builtin_cpu_supports("avx512f")) {
    std::fprintf(stderr, "bench_render_precision: this CPU has no AVX-512F (the prototype's lane layout)\n");
    return 0;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
