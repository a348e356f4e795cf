// Metacalibration's Fourier-space filters; see metacal_filters.hpp.
#include "engine/metacal/metacal_filters.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

namespace stampede {
namespace {

double sinc_half(double k) { return k == 0 ? 1.0 : std::sin(0.5 * k) / (0.5 * k); }

// PSF x pixel at (kx, ky) radians per pixel.
std::complex<double> with_pixel(const PsfModel& p, double kx, double ky) {
  return p.k_value(kx, ky) * (sinc_half(kx) * sinc_half(ky));
}

}  // namespace

std::shared_ptr<const MetacalFilters> MetacalFilters::build(const PsfModel& psf, const PsfModel& reconvolution,
                                                            double step, int period, std::string* error,
                                                            double max_gain) {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return std::shared_ptr<const MetacalFilters>();
  };
  if (period < 4 || period % 2 != 0) return fail("metacal: the padded grid must be even and >= 4");
  if (!(step > 0 && step < 0.5)) return fail("metacal: the shear step must be in (0, 0.5)");
  std::shared_ptr<MetacalFilters> f(new MetacalFilters());
  f->period_ = period;
  f->step_ = step;
  f->reconvolution_ = reconvolution;
  const int m = period, h = m / 2 + 1;
  const double dk = 2 * std::numbers::pi / m, norm = 1.0 / (static_cast<double>(m) * m);
  // The observed PSF x pixel at (2 pi c / M, 2 pi r / M) for c in [0, M/2], r in [-M/2, M/2] (both
  // Nyquist signs: the filters average over them); negative c by Hermitian symmetry. An image PSF
  // in one separable transform, an analytic one point by point.
  std::vector<std::complex<double>> observed(static_cast<std::size_t>(m + 1) * h);
  if (psf.kind == PsfKind::kImage) {
    if (!psf.image) return fail("metacal: the PSF image is missing");
    std::vector<double> fx(h), fy(m + 1);
    for (int c = 0; c < h; ++c) fx[c] = static_cast<double>(c) / m;
    for (int r = 0; r <= m; ++r) fy[r] = static_cast<double>(r - m / 2) / m;
    std::string why;
    if (!psf.image->transform(fx, fy, 0.5 * psf.image->oversampling, observed, &why)) return fail("metacal: " + why);
    for (int r = 0; r <= m; ++r)
      for (int c = 0; c < h; ++c) observed[static_cast<std::size_t>(r) * h + c] *= sinc_half(dk * c) * sinc_half(dk * (r - m / 2));
  } else {
    for (int r = 0; r <= m; ++r)
      for (int c = 0; c < h; ++c) observed[static_cast<std::size_t>(r) * h + c] = with_pixel(psf, dk * c, dk * (r - m / 2));
  }
  for (const std::complex<double>& v : observed)
    if (!std::isfinite(v.real()) || !std::isfinite(v.imag()) || std::abs(v) == 0)
      return fail("metacal: the PSF's transform is not finite and non-zero on the grid");
  auto observed_at = [&](int c, int r) {  // c in [-M/2, M/2], r in [-M/2, M/2]
    if (c < 0) return std::conj(observed[static_cast<std::size_t>(-r + m / 2) * h - c]);
    return observed[static_cast<std::size_t>(r + m / 2) * h + c];
  };
  for (MetacalType t : kMetacalTypes) {
    const auto g = metacal_shear(t, step);
    const auto b = inverse_shear_matrix(g[0], g[1]);  // symmetric: A^-T = A^-1
    auto gamma = [&](double kx, double ky) { return with_pixel(reconvolution, b[0] * kx + b[1] * ky, b[2] * kx + b[3] * ky); };
    auto& out = f->filters_[static_cast<int>(t)];
    out.resize(static_cast<std::size_t>(m) * h);
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
        std::complex<double> ratio = gamma(kx, ky) / observed_at(c, rs);
        if (nyquist_row || nyquist_col) {
          int n = 1;
          auto add = [&](int cs, int rr) { ratio += gamma(dk * cs, dk * rr) / observed_at(cs, rr), ++n; };
          if (nyquist_row) add(c, -rs);
          if (nyquist_col) add(-c, rs);
          if (nyquist_row && nyquist_col) add(-c, -rs);
          ratio /= static_cast<double>(n);
        }
        if (!std::isfinite(ratio.real()) || !std::isfinite(ratio.imag()) || std::abs(ratio) > max_gain) {
          std::ostringstream msg;
          msg << "metacal: the reconvolution PSF is not wider than the PSF (filter " << std::abs(ratio) << " at k = ("
              << kx << ", " << ky << ") rad/pixel, type " << metacal_type_name(t) << ")";
          return fail(msg.str());
        }
        out[static_cast<std::size_t>(r) * h + c] = ratio * norm;
      }
    }
  }
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
