// PSF models; see psf_model.hpp.
#include "engine/model/psf_model.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cctype>
#include <numbers>
#include <sstream>

#include "kernels/ellipse.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/math/airy.hpp"
#include "kernels/math/phasors.hpp"
#include "kernels/math/sinc.hpp"

namespace stampede {
const char* psf_kind_name(PsfKind kind) {
  switch (kind) {
    case PsfKind::kMoffat: return "moffat";
    case PsfKind::kAiry: return "airy";
    case PsfKind::kImage: return "image";
    case PsfKind::kGaussian: return "gaussian";
  }
  return "?";
}

bool parse_psf_kind(std::string_view name, PsfKind* out) {
  std::string s(name);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (PsfKind k : {PsfKind::kMoffat, PsfKind::kAiry, PsfKind::kImage})
    if (s == psf_kind_name(k)) {
      *out = k;
      return true;
    }
  return false;
}

bool PsfImage::transform(std::span<const double> fx, std::span<const double> fy, double nyquist,
                         std::span<std::complex<double>> out, std::string* error) const {
  const double o = oversampling;
  const double cx = std::isnan(centre_x) ? 0.5 * (nx - 1) : centre_x;
  const double cy = std::isnan(centre_y) ? 0.5 * (ny - 1) : centre_y;
  double total = 0;
  for (double v : pixels) total += v;
  if (!std::isfinite(total) || !(total > 0.0)) {
    std::ostringstream msg;
    msg << "PSF image cannot be normalised: its pixel sum is " << total;
    *error = msg.str();
    return false;
  }
  // Separably: rows along y first, T[j'][m] = sum_j p[j][m] exp(-2 pi i fy_j' y_j), then columns
  // as one complex product T Wx^T. Scratch per thread: a MEDS object transforms each cutout's
  // PSF, and a steady state allocates nothing.
  using ComplexRows = Eigen::Matrix<std::complex<double>, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const auto nfx = static_cast<Eigen::Index>(fx.size()), nfy = static_cast<Eigen::Index>(fy.size());
  thread_local ComplexRows t, wx, sum;
  thread_local std::vector<std::complex<double>> wy;
  thread_local std::vector<double> sinc_x;
  t.setZero(nfy, nx);
  wy.resize(static_cast<std::size_t>(ny));
  for (Eigen::Index ky = 0; ky < nfy; ++ky) {
    if (std::abs(fy[ky]) > nyquist) continue;
    const double d = -2.0 * std::numbers::pi * fy[ky] / o;
    kernels::phasors(-d * cy, d, ny, wy.data());
    std::complex<double>* trow = t.row(ky).data();
    for (int j = 0; j < ny; ++j) {
      const std::complex<double> w = wy[j];
      const double* row = pixels.data() + static_cast<std::size_t>(j) * nx;
      for (int m = 0; m < nx; ++m) trow[m] += w * row[m];
    }
  }
  wx.resize(nfx, nx);
  sinc_x.resize(static_cast<std::size_t>(nfx));
  for (Eigen::Index kx = 0; kx < nfx; ++kx) {
    const double d = -2.0 * std::numbers::pi * fx[kx] / o;
    kernels::phasors(-d * cx, d, nx, wx.row(kx).data());
    sinc_x[kx] = pixel_integrated ? kernels::sinc(std::numbers::pi * fx[kx] / o) : 1.0;
  }
  sum.resize(nfy, nfx);
  sum.noalias() = t * wx.transpose();
  for (Eigen::Index ky = 0; ky < nfy; ++ky) {
    // A pixel-integrated sample carries the image pixel's top-hat: divide it out.
    const double sinc_y = pixel_integrated ? kernels::sinc(std::numbers::pi * fy[ky] / o) : 1.0;
    for (Eigen::Index kx = 0; kx < nfx; ++kx) {
      const bool beyond = std::abs(fx[kx]) > nyquist || std::abs(fy[ky]) > nyquist;
      out[ky * nfx + kx] = beyond ? std::complex<double>(0.0, 0.0) : sum(ky, kx) / (total * (sinc_x[kx] * sinc_y));
    }
  }
  return true;
}

PsfModel PsfModel::Moffat(const kernels::MoffatProfile& m) {
  PsfModel p;
  p.kind = PsfKind::kMoffat;
  p.moffat = m;
  return p;
}

PsfModel PsfModel::Airy(const kernels::AiryProfile& a) {
  PsfModel p;
  p.kind = PsfKind::kAiry;
  p.airy = a;
  return p;
}

PsfModel PsfModel::Gaussian(const kernels::GaussianProfile& g) {
  PsfModel p;
  p.kind = PsfKind::kGaussian;
  p.gaussian = g;
  return p;
}

PsfModel PsfModel::Image(std::shared_ptr<const PsfImage> img) {
  PsfModel p;
  p.kind = PsfKind::kImage;
  p.image = std::move(img);
  return p;
}

bool PsfModel::IsValid(std::string* why) const {
  std::ostringstream msg;
  switch (kind) {
    case PsfKind::kMoffat:
      if (!(moffat.beta > 1.0 && moffat.beta < 100.0))
        msg << "psf_beta = " << moffat.beta << ": must be in (1, 100) (a Moffat with beta <= 1 has infinite flux)";
      else if (!(moffat.fwhm > 0.0 && std::isfinite(moffat.fwhm)))
        msg << "psf_fwhm = " << moffat.fwhm << ": must be > 0 (pixels)";
      else if (!(std::hypot(moffat.e1, moffat.e2) < 1.0))
        msg << "psf_e1, psf_e2 = " << moffat.e1 << ", " << moffat.e2 << ": |e| must be < 1";
      else if (!(moffat.truncation >= 0.0 && std::isfinite(moffat.truncation)))
        msg << "psf_truncation = " << moffat.truncation << ": must be >= 0 (0 = none)";
      break;
    case PsfKind::kAiry:
      if (!(airy.lambda_over_d > 0.0 && std::isfinite(airy.lambda_over_d)))
        msg << "airy_lambda_over_d = " << airy.lambda_over_d << ": must be > 0 (pixels)";
      else if (!(airy.obscuration >= 0.0 && airy.obscuration < 1.0))
        msg << "airy_obscuration = " << airy.obscuration << ": must be in [0, 1)";
      break;
    case PsfKind::kImage:
      if (!image)
        msg << "psf_input = image needs a PSF image";
      else if (image->nx < 1 || image->ny < 1 ||
               image->pixels.size() != static_cast<std::size_t>(image->nx) * image->ny)
        msg << "PSF image is " << image->nx << " x " << image->ny << " with " << image->pixels.size() << " pixels";
      else if (image->oversampling < 1)
        msg << "psf_upsampling = " << image->oversampling << ": must be >= 1";
      break;
    case PsfKind::kGaussian:
      if (!(gaussian.fwhm > 0.0 && std::isfinite(gaussian.fwhm)))
        msg << "Gaussian PSF FWHM = " << gaussian.fwhm << ": must be > 0 (pixels)";
      else if (!(std::hypot(gaussian.e1, gaussian.e2) < 1.0))
        msg << "Gaussian PSF e1, e2 = " << gaussian.e1 << ", " << gaussian.e2 << ": |e| must be < 1";
      break;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

double PsfModel::x_value(double dx, double dy) const {
  switch (kind) {
    case PsfKind::kMoffat: return kernels::moffat_intensity(moffat, dx, dy);
    case PsfKind::kAiry: return kernels::airy_intensity(airy, dx, dy);
    case PsfKind::kGaussian: return kernels::gaussian_intensity(gaussian, dx, dy);
    case PsfKind::kImage: break;
  }
  return NAN;
}

std::complex<double> PsfModel::k_value(double kx, double ky) const {
  switch (kind) {
    case PsfKind::kMoffat: {
      // I(x) = f(x^T Q x) with det Q = 1 has transform F_round(sqrt(k^T Q^-1 k)); Q^-1 swaps the
      // diagonal and negates the off-diagonal.
      const double alpha = kernels::moffat_alpha(moffat.fwhm, moffat.beta);
      const kernels::EllipseQuadratic q = kernels::ellipse_quadratic(moffat.e1, moffat.e2, 1.0);
      const double k = std::sqrt(q.yy * kx * kx - 2.0 * q.xy * kx * ky + q.xx * ky * ky);
      const double t = moffat.truncation > 0 ? moffat.truncation / alpha : 0.0;
      return kernels::moffat_fourier(moffat.beta, t, k * alpha);
    }
    case PsfKind::kAiry:
      if (airy.obscuration != 0.0) return NAN;
      return kernels::airy_fourier(std::hypot(kx, ky) * airy.lambda_over_d / (2 * std::numbers::pi));
    case PsfKind::kImage: {
      const double fx = kx / (2 * std::numbers::pi), fy = ky / (2 * std::numbers::pi);
      std::complex<double> v;
      std::string error;
      if (!image || !image->transform({&fx, 1}, {&fy, 1}, 0.5 * image->oversampling, {&v, 1}, &error)) return NAN;
      return v;
    }
    case PsfKind::kGaussian: {
      const kernels::EllipseQuadratic q = kernels::ellipse_quadratic(gaussian.e1, gaussian.e2, 1.0);
      const double s = kernels::gaussian_sigma(gaussian.fwhm);
      return std::exp(-0.5 * s * s * (q.yy * kx * kx - 2.0 * q.xy * kx * ky + q.xx * ky * ky));
    }
  }
  return NAN;
}

double PsfModel::e1() const {
  return kind == PsfKind::kMoffat ? moffat.e1 : kind == PsfKind::kGaussian ? gaussian.e1 : kind == PsfKind::kAiry ? 0.0 : NAN;
}

double PsfModel::e2() const {
  return kind == PsfKind::kMoffat ? moffat.e2 : kind == PsfKind::kGaussian ? gaussian.e2 : kind == PsfKind::kAiry ? 0.0 : NAN;
}

double PsfModel::fwhm() const {
  if (kind == PsfKind::kMoffat) return moffat.fwhm;
  if (kind == PsfKind::kGaussian) return gaussian.fwhm;
  if (kind == PsfKind::kAiry) return kernels::kAiryFwhmOverLambdaOverD * airy.lambda_over_d;  // the unobscured disc's
  return NAN;
}

bool PsfModel::operator==(const PsfModel& o) const {
  if (kind != o.kind) return false;
  switch (kind) {
    case PsfKind::kMoffat:
      return moffat.beta == o.moffat.beta && moffat.fwhm == o.moffat.fwhm && moffat.e1 == o.moffat.e1 &&
             moffat.e2 == o.moffat.e2 && moffat.truncation == o.moffat.truncation;
    case PsfKind::kAiry:
      return airy.lambda_over_d == o.airy.lambda_over_d && airy.obscuration == o.airy.obscuration;
    case PsfKind::kImage: return image == o.image;
    case PsfKind::kGaussian:
      return gaussian.fwhm == o.gaussian.fwhm && gaussian.e1 == o.gaussian.e1 && gaussian.e2 == o.gaussian.e2;
  }
  return false;
}

}  // namespace stampede
