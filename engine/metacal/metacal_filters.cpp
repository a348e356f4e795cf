// Metacalibration's Fourier-space filters; see metacal_filters.hpp.
#include "engine/metacal/metacal_filters.hpp"

#include <cmath>
#include <deque>
#include <numbers>
#include <optional>
#include <sstream>

#include "kernels/ellipse.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/psf_profile.hpp"

namespace stampede {
namespace {

// sin(k/2) / (k/2). For |k| <= 4 (every k the filters sample: the Nyquist square sheared by the
// step through a cutout's frame) by its Taylor series in (k/2)^2 to the (k/2)^24 term (the next is
// below 1e-18), cheaper than libm's sin and a division; beyond, by them.
double sinc_half(double k) {
  const double x = 0.5 * k;
  if (std::abs(k) > 4.0) return std::sin(x) / x;
  // (-1)^n / (2n + 1)!, n = 0 .. 12.
  constexpr double kC[13] = {1.0,
                             -1.0 / 6,
                             1.0 / 120,
                             -1.0 / 5040,
                             1.0 / 362880,
                             -1.0 / 39916800,
                             1.0 / 6227020800.0,
                             -1.0 / 1307674368000.0,
                             1.0 / 355687428096000.0,
                             -1.0 / 121645100408832000.0,
                             1.0 / 51090942171709440000.0,
                             -1.0 / 25852016738884976640000.0,
                             1.0 / 15511210043330985984000000.0};
  const double y = x * x;
  double sum = kC[12];
  for (int n = 11; n >= 0; --n) sum = sum * y + kC[n];
  return sum;
}

// PSF x pixel at (kx, ky) radians per pixel.
std::complex<double> with_pixel(const PsfModel& p, double kx, double ky) {
  return p.k_value(kx, ky) * (sinc_half(kx) * sinc_half(ky));
}

// A^-1 of the sky's shear g in the frame's pixels: J^-1 A^-1 J (a galaxy G(J x) sheared on the sky
// is G(A^-1 J x) = G(J (J^-1 A^-1 J) x)). The identity frame keeps A^-1 exactly.
std::array<double, 4> pixel_inverse_shear(const std::array<double, 2>& g, const PixelFrame& frame) {
  const auto b = inverse_shear_matrix(g[0], g[1]);
  if (frame.unit_jacobian()) return b;
  double ji[2][2];
  frame.inverse(ji);
  const double j[2][2] = {{frame.dudx, frame.dudy}, {frame.dvdx, frame.dvdy}};
  const double bm[2][2] = {{b[0], b[1]}, {b[2], b[3]}};
  double bj[2][2], out[2][2];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) bj[r][c] = bm[r][0] * j[0][c] + bm[r][1] * j[1][c];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) out[r][c] = ji[r][0] * bj[0][c] + ji[r][1] * bj[1][c];
  return {out[0][0], out[0][1], out[1][0], out[1][1]};
}

// Gamma's transform (of 1 at k = 0) below which its filter's gain is clipped, not checked.
constexpr double kNegligibleGamma = 1e-4;

// The arrays of destroyed filters and observed PSFs, kept per thread for the next ones: a MEDS
// object builds a set per cutout, and fresh arrays each time made the heap grow and shrink by
// megabytes per object, a page fault per 4 KB (docs/metacal.md).
template <class T>
class ArrayPool {
 public:
  static std::vector<T> take(std::size_t n) {
    std::vector<T> v;
    if (Arrays* a = arrays(); a && !a->free.empty()) {
      v = std::move(a->free.back());
      a->free.pop_back();
    }
    v.resize(n);
    return v;
  }
  static void give(std::vector<T>& v) {
    if (Arrays* a = arrays(); a && a->free.size() < kKept && v.capacity() > 0) a->free.push_back(std::move(v));
  }

 private:
  static constexpr std::size_t kKept = 64;  // a few objects' worth of cutouts
  struct Arrays {
    Arrays() { free.reserve(kKept); }
    ~Arrays() { gone() = true; }
    std::vector<std::vector<T>> free;
  };
  // Filters destroyed after this thread's pool (a static's, at exit) free their arrays themselves.
  static bool& gone() {
    thread_local bool g = false;  // trivially destructible: readable to the thread's end
    return g;
  }
  static Arrays* arrays() {
    if (gone()) return nullptr;
    thread_local Arrays a;
    return &a;
  }
};
using SpectrumPool = ArrayPool<std::complex<double>>;

// A Moffat's transform (times the pixel's) as PsfModel::k_value gives it, its radial function
// tabulated (kernels::LogTable, ~1e-12 relative): the filters evaluate ~5 M^2 / 2 transforms per
// build, which the Bessel function K made the bulk of a metacal fit's cost.
class MoffatTransform {
 public:
  explicit MoffatTransform(const kernels::MoffatProfile& m)
      : alpha_(kernels::moffat_alpha(m.fwhm, m.beta)), q_(kernels::ellipse_quadratic(m.e1, m.e2, 1.0)) {
    const double t = m.truncation > 0 ? m.truncation / alpha_ : 0.0;
    table_ = &table(m.beta, t);
  }
  double operator()(double kx, double ky) const {
    const double k = std::sqrt(q_.yy * kx * kx - 2.0 * q_.xy * kx * ky + q_.xx * ky * ky);
    return (*table_)(k * alpha_) * (sinc_half(kx) * sinc_half(ky));
  }

 private:
  // The table of x -> moffat_fourier(beta, t, x): a function of beta and t alone, kept per thread
  // for the last few (a run's Gammas share one beta; its values do not depend on who made it).
  static const kernels::LogTable& table(double beta, double t) {
    struct Entry {
      double beta, t;
      kernels::LogTable table;
    };
    thread_local std::deque<Entry> cache;  // push_back and pop_front keep the other entries in place
    for (const Entry& e : cache)
      if (e.beta == beta && e.t == t) return e.table;
    if (cache.size() >= 8) cache.pop_front();
    cache.push_back({beta, t, kernels::LogTable([&](double x) { return kernels::moffat_fourier(beta, t, x); },
                                                kernels::LogGrid::covering(1e-3, 400, 100))});
    return cache.back().table;
  }
  double alpha_;
  kernels::EllipseQuadratic q_;
  const kernels::LogTable* table_;
};

// Gamma's transform (times the pixel's): a Moffat's tabulated, or a Gaussian's exp(-sigma^2 |S k|^2 / 2).
class GammaTransform {
 public:
  explicit GammaTransform(const PsfModel& gamma) {
    if (gamma.kind == PsfKind::kMoffat) {
      moffat_.emplace(gamma.moffat);
    } else {
      const double s = kernels::gaussian_sigma(gamma.gaussian.fwhm);
      half_s2_ = 0.5 * s * s;
      q_ = kernels::ellipse_quadratic(gamma.gaussian.e1, gamma.gaussian.e2, 1.0);
    }
  }
  double operator()(double kx, double ky) const {
    if (moffat_) return (*moffat_)(kx, ky);
    return std::exp(-half_s2_ * (q_.yy * kx * kx - 2.0 * q_.xy * kx * ky + q_.xx * ky * ky)) *
           (sinc_half(kx) * sinc_half(ky));
  }

 private:
  std::optional<MoffatTransform> moffat_;
  double half_s2_ = 0;
  kernels::EllipseQuadratic q_;
};

bool is_reconvolution_kind(const PsfModel& gamma) {
  return gamma.kind == PsfKind::kMoffat || gamma.kind == PsfKind::kGaussian;
}

// Where a Gamma's filter exceeds max_gain on the coarse grid, if anywhere: every third row and
// column and the axes (where an image PSF's transform most often dips first, near the Nyquist
// edge), away from the Nyquist row and column (where the full grid's ratios are the same).
struct Violation {
  double gain, kx, ky;
  MetacalType type;
};
std::optional<Violation> coarse_violation(const MetacalFilters::Observed& observed_psf,
                                          const GammaTransform& gamma_transform, double step, double max_gain,
                                          const PixelFrame& frame) {
  const int m = observed_psf.period, h = m / 2 + 1;
  const double dk = 2 * std::numbers::pi / m;
  const std::vector<double>& inverse_abs = observed_psf.inverse_abs;
  for (MetacalType t : kMetacalTypes) {
    const auto b = pixel_inverse_shear(metacal_shear(t, step), frame);
    for (int r = 0; r < m; ++r) {
      if (r == m / 2) continue;
      const int rs = r <= m / 2 ? r : r - m;
      // Row 0 whole; else column 0 and every third column of every third row.
      const int c_step = r == 0 ? 1 : r % 3 == 0 ? 3 : h;
      for (int c = 0; c < h - 1; c += c_step) {
        const double kx = dk * c, ky = dk * rs;
        const double gm = gamma_transform(b[0] * kx + b[2] * ky, b[1] * kx + b[3] * ky);
        const double gain = std::abs(gm) * inverse_abs[static_cast<std::size_t>(rs + m / 2) * h + c];
        if (std::isfinite(gain) && gain > max_gain && std::abs(gm) >= kNegligibleGamma) return Violation{gain, kx, ky, t};
      }
    }
  }
  return std::nullopt;
}

}  // namespace

bool MetacalFilters::passes_coarse_check(const Observed& observed, const PsfModel& reconvolution, double step,
                                         double max_gain, const PixelFrame& frame) {
  if (!is_reconvolution_kind(reconvolution)) return false;
  return !coarse_violation(observed, GammaTransform(reconvolution), step, max_gain, frame);
}

MetacalFilters::Observed::~Observed() {
  SpectrumPool::give(values);
  SpectrumPool::give(inverse);
  ArrayPool<double>::give(inverse_abs);
}

MetacalFilters::~MetacalFilters() {
  for (auto& f : filters_) SpectrumPool::give(f);
}

std::shared_ptr<const MetacalFilters::Observed> MetacalFilters::observe(const PsfModel& psf, int period,
                                                                        std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return std::shared_ptr<const Observed>();
  };
  if (period < 4 || period % 2 != 0) return fail("metacal: the padded grid must be even and >= 4");
  auto out = std::make_shared<Observed>();
  out->period = period;
  const int m = period, h = m / 2 + 1;
  const double dk = 2 * std::numbers::pi / m;
  // The observed PSF x pixel at (2 pi c / M, 2 pi r / M) for c in [0, M/2], r in [-M/2, M/2] (both
  // Nyquist signs: the filters average over them); negative c by Hermitian symmetry. An image PSF
  // in one separable transform, an analytic one point by point.
  std::vector<std::complex<double>>& observed = out->values;
  observed = SpectrumPool::take(static_cast<std::size_t>(m + 1) * h);
  if (psf.kind == PsfKind::kImage) {
    if (!psf.image) return fail("metacal: the PSF image is missing");
    std::vector<double> fx(h), fy(m + 1);
    for (int c = 0; c < h; ++c) fx[c] = static_cast<double>(c) / m;
    for (int r = 0; r <= m; ++r) fy[r] = static_cast<double>(r - m / 2) / m;
    std::string why;
    if (!psf.image->transform(fx, fy, 0.5 * psf.image->oversampling, observed, &why)) return fail("metacal: " + why);
    for (int r = 0; r <= m; ++r)
      for (int c = 0; c < h; ++c) observed[static_cast<std::size_t>(r) * h + c] *= sinc_half(dk * c) * sinc_half(dk * (r - m / 2));
  } else if (psf.kind == PsfKind::kMoffat) {
    const MoffatTransform transform(psf.moffat);
    for (int r = 0; r <= m; ++r)
      for (int c = 0; c < h; ++c) observed[static_cast<std::size_t>(r) * h + c] = transform(dk * c, dk * (r - m / 2));
  } else {
    for (int r = 0; r <= m; ++r)
      for (int c = 0; c < h; ++c) observed[static_cast<std::size_t>(r) * h + c] = with_pixel(psf, dk * c, dk * (r - m / 2));
  }
  out->inverse = SpectrumPool::take(observed.size());
  out->inverse_abs = ArrayPool<double>::take(observed.size());
  for (std::size_t i = 0; i < observed.size(); ++i) {
    const std::complex<double> v = observed[i];
    const double n = std::norm(v);
    if (!std::isfinite(v.real()) || !std::isfinite(v.imag()) || !(n > 0) || !std::isfinite(n))
      return fail("metacal: the PSF's transform is not finite and non-zero on the grid");
    out->inverse[i] = std::conj(v) * (1.0 / n);
    out->inverse_abs[i] = 1.0 / std::sqrt(n);
  }
  return out;
}

std::shared_ptr<const MetacalFilters> MetacalFilters::build(const PsfModel& psf, const PsfModel& reconvolution,
                                                            double step, int period, std::string* error,
                                                            double max_gain, const PixelFrame& frame) {
  const auto observed = observe(psf, period, error);
  if (!observed) return nullptr;
  return build(*observed, reconvolution, step, error, max_gain, frame);
}

std::shared_ptr<const MetacalFilters> MetacalFilters::build(const Observed& observed_psf, const PsfModel& reconvolution,
                                                            double step, std::string* error, double max_gain,
                                                            const PixelFrame& frame) {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return std::shared_ptr<const MetacalFilters>();
  };
  const int period = observed_psf.period;
  if (!(step > 0 && step < 0.5)) return fail("metacal: the shear step must be in (0, 0.5)");
  if (!is_reconvolution_kind(reconvolution))
    return fail("metacal: the reconvolution PSF must be a Moffat or a Gaussian");
  std::shared_ptr<MetacalFilters> f(new MetacalFilters());
  f->period_ = period;
  f->step_ = step;
  f->reconvolution_ = reconvolution;
  const int m = period, h = m / 2 + 1;
  const double dk = 2 * std::numbers::pi / m, norm = 1.0 / (static_cast<double>(m) * m);
  const std::vector<std::complex<double>>& inverse = observed_psf.inverse;
  const GammaTransform gamma_transform(reconvolution);
  auto inverse_at = [&](int c, int r) {  // 1 / (PSF x pixel) at c in [-M/2, M/2], r in [-M/2, M/2]
    if (c < 0) return std::conj(inverse[static_cast<std::size_t>(-r + m / 2) * h - c]);
    return inverse[static_cast<std::size_t>(r + m / 2) * h + c];
  };
  auto refuse = [&](double gain, double kx, double ky, MetacalType t) {
    std::ostringstream msg;
    msg << "metacal: the reconvolution PSF is not wider than the PSF (filter " << gain << " at k = (" << kx << ", " << ky
        << ") rad/pixel, type " << metacal_type_name(t) << ")";
    return fail(msg.str());
  };
  // A Gamma too narrow is refused by a violation somewhere on the grid, most often already on the
  // coarse one (a ninth of the cost); acceptance is decided by the full grid alone.
  if (const auto v = coarse_violation(observed_psf, gamma_transform, step, max_gain, frame))
    return refuse(v->gain, v->kx, v->ky, v->type);
  for (MetacalType t : kMetacalTypes) {
    const auto g = metacal_shear(t, step);
    const auto b = pixel_inverse_shear(g, frame);
    f->inverse_[static_cast<int>(t)] = b;
    // A^-T k (for the identity frame b is symmetric and this is A^-1 k).
    auto gamma = [&](double kx, double ky) { return gamma_transform(b[0] * kx + b[2] * ky, b[1] * kx + b[3] * ky); };
    auto& out = f->filters_[static_cast<int>(t)];
    out = SpectrumPool::take(static_cast<std::size_t>(m) * h);
    for (int r = 0; r < m; ++r) {
      const int rs = r <= m / 2 ? r : r - m;  // signed; the Nyquist row as +M/2
      const double ky = dk * rs;
      const bool nyquist_row = r == m / 2;
      for (int c = 0; c < h; ++c) {
        const double kx = dk * c;
        const bool nyquist_col = c == m / 2;
        // At the Nyquist row and column, +pi and -pi are one sample (the data's coefficient
        // holds both): take the mean of the filter at each, so that the filtered spectrum stays
        // Hermitian (a sheared Gamma, or an elliptical PSF, is not even in one k alone).
        const double g0 = gamma(kx, ky);
        std::complex<double> ratio = g0 * inverse_at(c, rs);
        if (nyquist_row || nyquist_col) {
          int n = 1;
          auto add = [&](int cs, int rr) { ratio += gamma(dk * cs, dk * rr) * inverse_at(cs, rr), ++n; };
          if (nyquist_row) add(c, -rs);
          if (nyquist_col) add(-c, rs);
          if (nyquist_row && nyquist_col) add(-c, -rs);
          ratio /= static_cast<double>(n);
        }
        // Where Gamma itself has fallen below kNegligibleGamma the PSF's transform is at its own floor
        // (an image PSF's truncation, aliasing and float32 rounding), and the ratio of two
        // negligible numbers says nothing of the widths: the gain is clipped there instead of
        // refusing Gamma, which would otherwise have to fall below that floor everywhere.
        const double gain = std::sqrt(std::norm(ratio));
        if (!(gain <= max_gain)) {
          if (std::isfinite(gain) && std::abs(g0) < kNegligibleGamma)
            ratio *= max_gain / gain;
          else
            return refuse(gain, kx, ky, t);
        }
        out[static_cast<std::size_t>(r) * h + c] = ratio * norm;
      }
    }
  }
  for (int t = 0; t < kNumMetacalTypes; ++t)
    f->single_filters_[t].assign(f->filters_[t].begin(), f->filters_[t].end());
  // Noise gain of the noshear filter: mean |f|^2 over the full grid (half-spectrum columns 1 ..
  // m/2 - 1 stand for two).
  const auto& f0 = f->filters_[0];
  double sum = 0;
  for (int r = 0; r < m; ++r)
    for (int c = 0; c < h; ++c) sum += (c == 0 || c == m / 2 ? 1.0 : 2.0) * std::norm(f0[static_cast<std::size_t>(r) * h + c] / norm);
  f->noise_gain_ = sum * norm;
  return f;
}

}  // namespace stampede
