// The exact renderer's prepared PSF; see exact_psf.hpp.
#include "engine/render/exact_psf.hpp"

#include <fftw3.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <functional>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "kernels/ellipse.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/math/gauss_legendre.hpp"
#include "kernels/math/sinc.hpp"
#include "kernels/moments.hpp"
#include "kernels/psf_profile.hpp"

namespace stampede {
namespace {

constexpr double kPi = std::numbers::pi;

using kernels::sinc;

// The PSF's transform (PSF(0) = 1) as a function of (kx, ky), and the |k| beyond which it stays
// at most `tolerance`.
struct PsfTransform {
  std::function<double(double, double)> at;
  double k_bound = 0;
};

PsfTransform psf_transform(const PsfModel& psf, double tolerance) {
  PsfTransform out;
  if (psf.kind == PsfKind::kMoffat) {
    const kernels::MoffatProfile& m = psf.moffat;
    const double alpha = kernels::moffat_alpha(m.fwhm, m.beta);
    const double t = m.truncation > 0 ? m.truncation / alpha : 0.0;
    // |S k| for the sheared profile: S^2 is the real-space form of the opposite shear at r = 1.
    const kernels::EllipseQuadratic s2 = kernels::ellipse_quadratic(-m.e1, -m.e2, 1.0);
    const double e = std::hypot(m.e1, m.e2), stretch = std::sqrt((1 + e) / (1 - e));
    // Largest x = k alpha with |transform| above the tolerance, scanned outwards (a truncated
    // Moffat's transform rings, so it is capped as in the simulator: five pixel-frequency aliases).
    const double x_cap = 10 * kPi * alpha;
    double x_limit = 1.0;
    for (double x = 0.25; x <= x_cap; x += 0.25)
      if (std::abs(kernels::moffat_fourier(m.beta, t, x)) > tolerance) x_limit = x + 0.25;
    x_limit = std::min(x_limit, x_cap);
    out.k_bound = x_limit / alpha * stretch;
    if (t == 0) {
      out.at = [=](double kx, double ky) {
        const double x = std::sqrt(std::max(0.0, s2(kx, ky))) * alpha;
        return x > x_limit ? 0.0 : kernels::moffat_fourier(m.beta, 0.0, x);
      };
    } else {
      // The truncated transform is a quadrature: tabulated as in the simulator (400 nodes per
      // decade keep >= 10 nodes per period of its ringing).
      auto table = std::make_shared<kernels::LogTable>([&](double x) { return kernels::moffat_fourier(m.beta, t, x); },
                                                       kernels::LogGrid::covering(1e-4, x_limit, 400));
      out.at = [=](double kx, double ky) {
        const double x = std::sqrt(std::max(0.0, s2(kx, ky))) * alpha;
        return x > table->q_max() ? 0.0 : (*table)(x);
      };
    }
    return out;
  }
  if (psf.kind == PsfKind::kGaussian) {
    const kernels::GaussianProfile& g = psf.gaussian;
    const double sigma = kernels::gaussian_sigma(g.fwhm);
    const kernels::EllipseQuadratic s2 = kernels::ellipse_quadratic(-g.e1, -g.e2, 1.0);
    const double e = std::hypot(g.e1, g.e2), stretch = std::sqrt((1 + e) / (1 - e));
    // exp(-x^2 / 2) <= tolerance beyond x = sqrt(-2 ln tolerance), x = |S k| sigma.
    out.k_bound = std::sqrt(-2 * std::log(std::min(tolerance, 0.5))) / sigma * stretch;
    out.at = [=](double kx, double ky) { return std::exp(-0.5 * sigma * sigma * std::max(0.0, s2(kx, ky))); };
    return out;
  }
  if (psf.kind == PsfKind::kAiry && psf.airy.obscuration == 0.0) {
    const double l = psf.airy.lambda_over_d;
    out.k_bound = 2 * kPi / l;  // the pupil's cut-off: exactly 0 beyond
    out.at = [=](double kx, double ky) { return kernels::airy_fourier(std::hypot(kx, ky) * l / (2 * kPi)); };
    return out;
  }
  throw std::invalid_argument(
      "the exact renderer's term list needs an analytic PSF transform (Moffat, Gaussian, unobscured Airy); image and "
      "obscured Airy PSFs are not supported yet");
}

// Signed frequency index of half-spectrum row jy (FFTW order).
int signed_row(int jy, int n) { return jy <= n / 2 ? jy : jy - n; }

// <r^2> of the round Moffat (1 + r^2 / alpha^2)^-beta cut at r = t alpha (t = 0: none), in units
// of alpha^2; infinite for an untruncated beta <= 2.
double moffat_mean_r2(double beta, double t) {
  if (t == 0) return beta > 2 ? 1.0 / (beta - 2) : INFINITY;
  // With s = 1 + r^2 / alpha^2 both integrals are elementary: int s^-beta ds and int (s - 1) s^-beta ds
  // over [1, 1 + t^2].
  const double top = 1 + t * t;
  auto power_integral = [&](double p) {  // int_1^top s^p ds
    return p == -1 ? std::log(top) : (std::pow(top, p + 1) - 1) / (p + 1);
  };
  const double flux = power_integral(-beta);
  return (power_integral(1 - beta) - flux) / flux;
}

}  // namespace

std::shared_ptr<const kernels::KSpaceTerms> build_kspace_terms(const PsfModel& psf, int n, double tolerance) {
  std::string why;
  if (!psf.IsValid(&why)) throw std::invalid_argument("exact renderer PSF: " + why);
  if (n < 8) throw std::invalid_argument("exact renderer: period below 8 pixels");
  const PsfTransform p = psf_transform(psf, tolerance);
  auto terms = std::make_shared<kernels::KSpaceTerms>();
  const int half = n / 2 + 1;
  const int stride = (half + kernels::kKBlock - 1) / kernels::kKBlock * kernels::kKBlock;
  const int per_row = stride / kernels::kKBlock;
  const double dk = 2 * kPi / n;
  // Aliases out to where the PSF has fallen below the tolerance (sinc <= 1 only lowers it).
  const int m_max = static_cast<int>(std::ceil(p.k_bound / (2 * kPi) + 0.5));
  const int aliases = 2 * m_max + 1;
  terms->n = n;
  terms->row_stride = stride;
  terms->alias_max = m_max;
  terms->kx_values.resize(static_cast<std::size_t>(aliases) * stride);
  terms->ky_values.resize(static_cast<std::size_t>(aliases) * n);
  for (int a = 0; a < aliases; ++a) {
    for (int jx = 0; jx < stride; ++jx) terms->kx_values[static_cast<std::size_t>(a) * stride + jx] = 2 * kPi * (a - m_max) + dk * jx;
    for (int jy = 0; jy < n; ++jy)
      terms->ky_values[static_cast<std::size_t>(a) * n + jy] = 2 * kPi * (a - m_max) + dk * signed_row(jy, n);
  }
  const double norm = 1.0 / (static_cast<double>(n) * n);  // FFTW's unnormalised inverse
  terms->block_begin.reserve(static_cast<std::size_t>(n) * per_row + 1);
  for (int jy = 0; jy < n; ++jy)
    for (int b = 0; b < per_row; ++b) {
      terms->block_begin.push_back(static_cast<std::int32_t>(terms->entry_ix.size()));
      for (int ay = 0; ay < aliases; ++ay) {
        const int iy = ay * n + jy;
        const double ky = terms->ky_values[static_cast<std::size_t>(iy)];
        if (std::abs(ky) > p.k_bound) continue;
        for (int ax = 0; ax < aliases; ++ax) {
          const int ix = ax * stride + b * kernels::kKBlock;
          std::array<double, kernels::kKBlock> v{};
          double largest = 0;
          for (int l = 0; l < kernels::kKBlock; ++l) {
            const int jx = b * kernels::kKBlock + l;
            const double kx = terms->kx_values[static_cast<std::size_t>(ix + l)];
            if (jx >= half || std::hypot(kx, ky) > p.k_bound) continue;  // padding column, or beyond the PSF
            v[l] = p.at(kx, ky) * sinc(0.5 * kx) * sinc(0.5 * ky);
            largest = std::max(largest, std::abs(v[l]));
          }
          if (!(largest > tolerance)) continue;
          terms->entry_ix.push_back(ix);
          terms->entry_iy.push_back(iy);
          terms->entry_alias.push_back(ax * aliases + ay);
          for (double x : v) terms->ppi.push_back(x * norm);  // centrosymmetric PSFs: real transforms
        }
      }
    }
  terms->block_begin.push_back(static_cast<std::int32_t>(terms->entry_ix.size()));
  return terms;
}

bool blur_moments(const PsfModel& psf, kernels::BlurMoments* out) {
  if (psf.kind == PsfKind::kGaussian) {
    // Covariance sigma^2 Q(-e) and the pixel box's 1/12 per axis, as for the Moffat below.
    const double s2 = std::pow(kernels::gaussian_sigma(psf.gaussian.fwhm), 2);
    const kernels::EllipseQuadratic c = kernels::ellipse_quadratic(-psf.gaussian.e1, -psf.gaussian.e2, 1.0);
    out->xx = s2 * c.xx + 1.0 / 12.0;
    out->xy = s2 * c.xy;
    out->yy = s2 * c.yy + 1.0 / 12.0;
    return true;
  }
  if (psf.kind != PsfKind::kMoffat) return false;  // the Airy disc's second moments diverge
  const kernels::MoffatProfile& m = psf.moffat;
  const double alpha = kernels::moffat_alpha(m.fwhm, m.beta);
  const double r2 = moffat_mean_r2(m.beta, m.truncation > 0 ? m.truncation / alpha : 0.0);
  if (!std::isfinite(r2)) return false;
  // The sheared profile's covariance is sigma^2 Q(e)^-1 = sigma^2 Q(-e) (area-preserving, det 1),
  // sigma^2 = <r^2> / 2 per axis of the round one; the pixel box adds 1/12 per axis.
  const double s2 = 0.5 * r2 * alpha * alpha;
  const kernels::EllipseQuadratic c = kernels::ellipse_quadratic(-m.e1, -m.e2, 1.0);
  out->xx = s2 * c.xx + 1.0 / 12.0;
  out->xy = s2 * c.xy;
  out->yy = s2 * c.yy + 1.0 / 12.0;
  return true;
}

namespace {

std::shared_ptr<const ExactPsf> build_image_psf(const PsfImage& img, int n, std::string* error) {
  auto fail = [&](const std::string& why) -> std::shared_ptr<const ExactPsf> {
    if (error) *error = "exact renderer, image PSF: " + why;
    return nullptr;
  };
  if (img.oversampling != 1 || !img.pixel_integrated)
    return fail("only pixel integrals at the data's sampling (oversampling 1, pixel-integrated) can be drawn");
  if (img.nx != img.ny || img.nx < 3) return fail("the image must be square, 3 pixels or more");
  if (n < 8) return fail("period below 8 pixels");
  // The term list: every bin of the principal zone once, weight 1 / n^2 (FFTW's normalisation).
  auto terms = std::make_shared<kernels::KSpaceTerms>();
  const int half = n / 2 + 1;
  const int stride = (half + kernels::kKBlock - 1) / kernels::kKBlock * kernels::kKBlock;
  const int per_row = stride / kernels::kKBlock;
  const double dk = 2 * kPi / n, norm = 1.0 / (static_cast<double>(n) * n);
  terms->n = n;
  terms->row_stride = stride;
  terms->alias_max = 0;
  terms->kx_values.resize(static_cast<std::size_t>(stride));
  terms->ky_values.resize(static_cast<std::size_t>(n));
  for (int jx = 0; jx < stride; ++jx) terms->kx_values[static_cast<std::size_t>(jx)] = dk * jx;
  for (int jy = 0; jy < n; ++jy) terms->ky_values[static_cast<std::size_t>(jy)] = dk * signed_row(jy, n);
  for (int jy = 0; jy < n; ++jy)
    for (int b = 0; b < per_row; ++b) {
      terms->block_begin.push_back(static_cast<std::int32_t>(terms->entry_ix.size()));
      terms->entry_ix.push_back(b * kernels::kKBlock);
      terms->entry_iy.push_back(jy);
      terms->entry_alias.push_back(0);
      for (int l = 0; l < kernels::kKBlock; ++l) terms->ppi.push_back(b * kernels::kKBlock + l < half ? norm : 0.0);
    }
  terms->block_begin.push_back(static_cast<std::int32_t>(terms->entry_ix.size()));
  // D(k) at the bins: the samples' transform about the PSF's centre, normalised by their sum.
  std::vector<double> fx(static_cast<std::size_t>(half)), fy(static_cast<std::size_t>(n));
  for (int jx = 0; jx < half; ++jx) fx[static_cast<std::size_t>(jx)] = static_cast<double>(jx) / n;
  for (int jy = 0; jy < n; ++jy) fy[static_cast<std::size_t>(jy)] = static_cast<double>(signed_row(jy, n)) / n;
  std::vector<std::complex<double>> d(static_cast<std::size_t>(n) * half);
  std::string why;
  // PsfImage::transform divides a pixel-integrated image's top-hat out (the upsampled renderer adds
  // its own); here the samples' transform is wanted as it is, PSF x pixel.
  PsfImage samples = img;
  samples.pixel_integrated = false;
  if (!samples.transform(fx, fy, 0.5, d, &why)) return fail(why);
  std::vector<double> re(static_cast<std::size_t>(n) * stride, 0.0), im(re.size(), 0.0);
  for (int jy = 0; jy < n; ++jy)
    for (int jx = 0; jx < half; ++jx) {
      const std::complex<double> v = d[static_cast<std::size_t>(jy) * half + jx];
      re[static_cast<std::size_t>(jy) * stride + jx] = v.real();
      im[static_cast<std::size_t>(jy) * stride + jx] = v.imag();
    }
  // Second moments about the centre (the samples are PSF x pixel already), and adaptive ones.
  const double cx = std::isnan(img.centre_x) ? 0.5 * (img.nx - 1) : img.centre_x;
  const double cy = std::isnan(img.centre_y) ? 0.5 * (img.ny - 1) : img.centre_y;
  double s = 0, sxx = 0, sxy = 0, syy = 0;
  for (int y = 0; y < img.ny; ++y)
    for (int x = 0; x < img.nx; ++x) {
      const double v = img.pixels[static_cast<std::size_t>(y) * img.nx + x];
      s += v, sxx += v * (x - cx) * (x - cx), sxy += v * (x - cx) * (y - cy), syy += v * (y - cy) * (y - cy);
    }
  kernels::BlurMoments blur{sxx / s, sxy / s, syy / s};
  if (!(blur.xx > 0 && blur.yy > 0 && blur.xx * blur.yy > blur.xy * blur.xy))
    return fail("its second moments are not those of a PSF (not positive definite)");
  const std::vector<double> ones(img.pixels.size(), 1.0);
  const kernels::ImageMoments m = kernels::adaptive_moments(img.pixels, ones, img.nx);
  if (!m.valid) return fail("the PSF's adaptive moments did not converge");
  return std::make_shared<const ExactPsf>(std::move(terms), blur, m.xx, m.xy, m.yy, std::move(re), std::move(im));
}

}  // namespace

std::shared_ptr<const ExactPsf> build_exact_psf(const PsfModel& psf, int period, double tolerance,
                                                std::string* error) {
  if (psf.kind == PsfKind::kImage) {
    std::string why;
    if (!psf.IsValid(&why) || !psf.image) {
      if (error) *error = "exact renderer, image PSF: " + why;
      return nullptr;
    }
    return build_image_psf(*psf.image, period, error);
  }
  std::shared_ptr<const kernels::KSpaceTerms> terms;
  try {
    terms = build_kspace_terms(psf, period, tolerance);
  } catch (const std::invalid_argument& e) {
    if (error) *error = e.what();
    return nullptr;
  }
  // PSF x pixel centred on pixel (c, c), c = n / 2: its spectrum is the alias sum times e^{-i k c}
  // (aliases add multiples of 2 pi to k, which leave the phase of an integer c alone).
  const int n = terms->n, half = n / 2 + 1, stride = terms->row_stride, per_row = stride / kernels::kKBlock;
  std::vector<std::complex<double>> spectrum(static_cast<std::size_t>(n) * half);
  for (int b = 0; b < terms->blocks(); ++b) {
    const int jy = b / per_row, jx0 = (b % per_row) * kernels::kKBlock;
    for (int e = terms->block_begin[static_cast<std::size_t>(b)]; e < terms->block_begin[static_cast<std::size_t>(b) + 1]; ++e)
      for (int l = 0; l < kernels::kKBlock; ++l) {
        const int jx = jx0 + l;
        if (jx >= half) continue;
        const std::size_t v = static_cast<std::size_t>(e) * kernels::kKBlock + l;
        const double angle = -2 * kPi * (static_cast<double>(jx) + signed_row(jy, n)) * (n / 2) / n;
        spectrum[static_cast<std::size_t>(jy) * half + jx] +=
            std::polar(1.0, angle) * terms->ppi[v];
      }
  }
  std::vector<double> image(static_cast<std::size_t>(n) * n), ones(image.size(), 1.0);
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    fftw_plan plan = fftw_plan_dft_c2r_2d(n, n, reinterpret_cast<fftw_complex*>(spectrum.data()), image.data(),
                                          FFTW_ESTIMATE | FFTW_DESTROY_INPUT);
    fftw_execute(plan);
    fftw_destroy_plan(plan);
  }
  const kernels::ImageMoments m = kernels::adaptive_moments(image, ones, n);
  if (!m.valid) {
    if (error) *error = "the PSF's adaptive moments did not converge";
    return nullptr;
  }
  kernels::BlurMoments blur;
  const bool finite = blur_moments(psf, &blur);
  return std::make_shared<const ExactPsf>(std::move(terms), finite, blur, m.xx, m.xy, m.yy);
}

}  // namespace stampede
