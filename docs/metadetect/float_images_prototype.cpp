// Experiment (docs/metadetect.md, "What S/N 20 cells need"; not built by CMake): a metadetection
// cell's five metacal images with fixnoise in single precision, the same operations as
// MetacalImageSet / MetacalImager / ChirpResampler do for a cell (1p/1m by Bluestein, 2p/2m by three
// shears, the chirps and phase recurrences in double, stored as float), timed against the engine's
// double path in one process and compared. Build after the Release build in build/:
//   g++ -std=c++20 -O3 -DNDEBUG -I. -I/usr/include/eigen3 docs/metadetect/float_images_prototype.cpp \
//     build/engine/libstampede_engine.a build/kernels/libstampede_kernels.a -lfftw3 -lfftw3f -ltbb \
//     -o /tmp/float_images && /tmp/float_images
#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <vector>

#include "engine/common/random_stream.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metacal/metacal_imager.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/metacal_type.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
#include "engine/sim/cell_sim.hpp"
#include "kernels/math/fft_size.hpp"

using namespace stampede;
using cf = std::complex<float>;

struct FloatImager {
  int s, m, h, off, l;
  float *pad, *hbuf, *grid, *tr;
  cf *spec, *work, *rows, *cw;
  fftwf_plan fwd2, bwd2, rf, rb, cfwd, cbwd;
  std::vector<cf> filt[5];
  std::array<double, 4> inv[5];
  std::vector<float> scratch, scratch_t;
  std::vector<cf> phases;
  struct Ch { double a, b; std::vector<cf> pre, kernel, post; };
  std::vector<Ch> cache;
  FloatImager(int s_, int m_, const MetacalFilters& f) : s(s_), m(m_), h(m_ / 2 + 1), off((m_ - s_) / 2) {
    l = kernels::fft_friendly_size(m / 2 + s);
    pad = fftwf_alloc_real(m * m); hbuf = fftwf_alloc_real(m * m); grid = fftwf_alloc_real(m * m); tr = fftwf_alloc_real(m * m);
    spec = (cf*)fftwf_alloc_complex(m * h); work = (cf*)fftwf_alloc_complex(m * h); rows = (cf*)fftwf_alloc_complex(m * h);
    cw = (cf*)fftwf_alloc_complex(l);
    fwd2 = fftwf_plan_dft_r2c_2d(m, m, pad, (fftwf_complex*)spec, FFTW_ESTIMATE);
    bwd2 = fftwf_plan_dft_c2r_2d(m, m, (fftwf_complex*)work, hbuf, FFTW_ESTIMATE | FFTW_DESTROY_INPUT);
    int n[1] = {m};
    rf = fftwf_plan_many_dft_r2c(1, n, m, grid, nullptr, 1, m, (fftwf_complex*)rows, nullptr, 1, h, FFTW_ESTIMATE);
    rb = fftwf_plan_many_dft_c2r(1, n, m, (fftwf_complex*)rows, nullptr, 1, h, grid, nullptr, 1, m, FFTW_ESTIMATE | FFTW_DESTROY_INPUT);
    cfwd = fftwf_plan_dft_1d(l, (fftwf_complex*)cw, (fftwf_complex*)cw, FFTW_FORWARD, FFTW_ESTIMATE);
    cbwd = fftwf_plan_dft_1d(l, (fftwf_complex*)cw, (fftwf_complex*)cw, FFTW_BACKWARD, FFTW_ESTIMATE);
    std::fill(pad, pad + m * m, 0.f);
    for (int t = 0; t < 5; ++t) {
      const std::complex<double>* p = f.filter(kMetacalTypes[t]);
      filt[t].assign(p, p + static_cast<std::size_t>(m) * h);
      inv[t] = f.inverse_shear(kMetacalTypes[t]);
    }
    scratch.resize(static_cast<std::size_t>(m) * s); scratch_t.resize(static_cast<std::size_t>(m) * s);
    phases.resize(h);
  }
  static void transpose(const float* in, float* out, int r, int c) {
    for (int r0 = 0; r0 < r; r0 += 16)
      for (int c0 = 0; c0 < c; c0 += 16)
        for (int i = r0; i < std::min(r, r0 + 16); ++i)
          for (int j = c0; j < std::min(c, c0 + 16); ++j) out[static_cast<std::size_t>(j) * r + i] = in[static_cast<std::size_t>(i) * c + j];
  }
  static void cmul(const cf* a, const cf* b, cf* o, int n) {
    const float* x = (const float*)a; const float* y = (const float*)b; float* z = (float*)o;
    for (int i = 0; i < n; ++i) { float xr = x[2*i], xi = x[2*i+1], yr = y[2*i], yi = y[2*i+1]; z[2*i] = xr*yr - xi*yi; z[2*i+1] = xr*yi + xi*yr; }
  }
  const Ch& chirps(double a, double b) {
    for (auto& c : cache) if (c.a == a && c.b == b) return c;
    Ch c; c.a = a; c.b = b;
    const double k = 2 * std::numbers::pi / m;
    c.pre.resize(h);
    for (int q = 0; q < h; ++q) c.pre[q] = std::polar((q == 0 || q == m / 2 ? 1.0 : 2.0) / m, k * (q * a + 0.5 * b * q * q));
    std::vector<std::complex<double>> w(l);
    for (int j = -(h - 1); j < s; ++j) w[(j + l) % l] = std::polar(1.0, -k * 0.5 * b * j * j);
    fftw_plan p = fftw_plan_dft_1d(l, (fftw_complex*)w.data(), (fftw_complex*)w.data(), FFTW_FORWARD, FFTW_ESTIMATE);
    fftw_execute(p); fftw_destroy_plan(p);
    c.kernel.assign(w.begin(), w.end());
    c.post.resize(s);
    for (int j = 0; j < s; ++j) c.post[j] = std::polar(1.0 / l, k * 0.5 * b * j * j);
    cache.push_back(c);
    return cache.back();
  }
  void resample(const cf* rws, int n, double a, double b, float* out, int stride) {
    const Ch& c = chirps(a, b);
    for (int r = 0; r < n; ++r) {
      cmul(rws + static_cast<std::size_t>(r) * h, c.pre.data(), cw, h);
      std::fill(cw + h, cw + l, cf(0, 0));
      fftwf_execute(cfwd);
      cmul(cw, c.kernel.data(), cw, l);
      fftwf_execute(cbwd);
      float* o = out + static_cast<std::size_t>(r) * stride;
      const float* wd = (const float*)cw; const float* pd = (const float*)c.post.data();
      for (int j = 0; j < s; ++j) o[j] = wd[2*j] * pd[2*j] - wd[2*j+1] * pd[2*j+1];
    }
  }
  void scaled(double b0, double b1, double cx, double cy, float* out) {
    fftwf_execute_dft_r2c(rf, hbuf, (fftwf_complex*)rows);
    resample(rows, m, cx + b0 * (off - cx), b0, scratch.data(), s);
    transpose(scratch.data(), grid, m, s);
    fftwf_execute_dft_r2c(rf, grid, (fftwf_complex*)rows);
    resample(rows, s, cy + b1 * (off - cy), b1, scratch_t.data(), s);
    transpose(scratch_t.data(), out, s, s);
  }
  template <class Sh> void shift_rows(float* g, Sh sh) {
    fftwf_execute_dft_r2c(rf, g, (fftwf_complex*)rows);
    const float inv_m = 1.0f / m;
    for (int r = 0; r < m; ++r) {
      const double t = sh(r);
      cf* row = rows + static_cast<std::size_t>(r) * h;
      const std::complex<double> step = std::polar(1.0, 2 * std::numbers::pi * t / m);
      // phases in double recurrence, stored as float
      std::complex<double> ph(inv_m, 0);
      for (int q = 0; q < m / 2; ++q) { phases[q] = cf(ph); ph *= step; }
      cmul(row, phases.data(), row, m / 2);
      row[m / 2] *= static_cast<float>(inv_m * std::cos(std::numbers::pi * t));
    }
    fftwf_execute_dft_c2r(rb, (fftwf_complex*)rows, g);
  }
  void sheared(double a, double b, double cx, double cy, float* out) {
    const double sv = (a - 1) / b;
    auto centred = [&](int i, double c) { double d = i - c; if (d >= 0.5 * m) d -= m; if (d < -0.5 * m) d += m; return d; };
    std::copy_n(hbuf, m * m, grid);
    shift_rows(grid, [&](int r) { return sv * centred(r, cy); });
    transpose(grid, tr, m, m);
    shift_rows(tr, [&](int c) { return b * centred(c, cx); });
    transpose(tr, grid, m, m);
    shift_rows(grid, [&](int r) { return sv * centred(r, cy); });
    for (int y = 0; y < s; ++y) std::copy_n(grid + static_cast<std::size_t>(off + y) * m + off, s, out + static_cast<std::size_t>(y) * s);
  }
  void make_images(const float* stamp, float* out) {
    for (int y = 0; y < s; ++y) std::copy_n(stamp + static_cast<std::size_t>(y) * s, s, pad + static_cast<std::size_t>(off + y) * m + off);
    fftwf_execute(fwd2);
    const double c = 0.5 * (s - 1), cx = off + c, cy = off + c;
    const std::size_t npix = static_cast<std::size_t>(s) * s;
    for (int t = 0; t < 5; ++t) {
      cmul(spec, filt[t].data(), work, m * h);
      fftwf_execute(bwd2);
      float* img = out + t * npix;
      const auto& b = inv[t];
      if (t == 0) { for (int y = 0; y < s; ++y) std::copy_n(hbuf + static_cast<std::size_t>(off + y) * m + off, s, img + static_cast<std::size_t>(y) * s); }
      else if (b[1] == 0 && b[2] == 0) scaled(b[0], b[3], cx, cy, img);
      else sheared(b[0], b[1], cx, cy, img);
    }
  }
};

int main() {
  CellSimOptions so;
  const CellSimulator sim(so);
  auto ws = sim.make_workspace();
  const SimCell cell = sim.simulate(0, *ws);
  const int s = so.size;
  auto img = std::make_shared<PsfImage>();
  img->nx = img->ny = so.psf_size;
  img->pixels = sim.bands()[0].psf;
  const PsfModel psf = PsfModel::Image(img);
  const double sigma = sim.bands()[0].noise_sigma;
  std::vector<double> weight(cell.bands[0].image.size(), 1 / (sigma * sigma));
  const int m = MetacalImager::padded_size(s, 16);
  MetacalImageSet set(s, FftPlanning::kEstimate, m);
  MetacalOptions mo;
  mo.enabled = true;
  std::string err;
  auto filters = reconvolution_filters(psf, mo, set.period(), &err);
  const std::size_t npix = static_cast<std::size_t>(s) * s;
  std::vector<double> out(5 * npix), noise(npix);
  RandomStream rs({7, 1, 2});
  for (auto& v : noise) v = sigma * rs.normal();
  double var = 0;
  // double: the engine's path, with the noise plane as fixnoise's field.
  auto run_double = [&] { set.make(cell.bands[0].image, weight, WeightKind::kInverseVariance, 0.0, *filters, mo, RandomStream({1, 1, 1}), out, &var, 1.0, nullptr, noise); };
  FloatImager fi(s, m, *filters);
  std::vector<float> stamp(cell.bands[0].image.begin(), cell.bands[0].image.end()), rot(npix), fout(5 * npix), fnoise(5 * npix);
  auto run_float = [&] {
    fi.make_images(stamp.data(), fout.data());
    for (int y = 0; y < s; ++y) for (int x = 0; x < s; ++x) rot[static_cast<std::size_t>(x) * s + (s - 1 - y)] = static_cast<float>(noise[static_cast<std::size_t>(y) * s + x]);
    fi.make_images(rot.data(), fnoise.data());
    for (int t = 0; t < 5; ++t)
      for (int y = 0; y < s; ++y) for (int x = 0; x < s; ++x) fout[t * npix + static_cast<std::size_t>(y) * s + x] += fnoise[t * npix + static_cast<std::size_t>(x) * s + (s - 1 - y)];
  };
  run_double(); run_float();
  double peak = 0, diff = 0;
  for (std::size_t i = 0; i < out.size(); ++i) peak = std::max(peak, std::abs(out[i])), diff = std::max(diff, std::abs(out[i] - fout[i]));
  std::printf("max |double - float| = %.3g of the images' peak %.3g (%.2e relative), noise sigma %.3g\n", diff, peak, diff / peak, sigma);
  for (int rep = 0; rep < 3; ++rep) {
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < 20; ++i) run_double();
    auto t1 = std::chrono::steady_clock::now();
    for (int i = 0; i < 20; ++i) run_float();
    auto t2 = std::chrono::steady_clock::now();
    std::printf("double %.2f ms  float %.2f ms per cell's five images with fixnoise\n",
                std::chrono::duration<double, std::milli>(t1 - t0).count() / 20, std::chrono::duration<double, std::milli>(t2 - t1).count() / 20);
  }
}
