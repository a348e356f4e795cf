// A PSF description apart from any renderer's kernel: what the PSF is (Moffat, truncated Moffat,
// Airy, or a sampled image at any oversampling), with its real-space and Fourier-space values
// (GalSim's xValue / kValue). The simulator draws from it; each renderer builds its own kernel
// from it (render/psf_kernel for the upsampled renderer).
//
// A value: copied into batches (no allocation for the analytic kinds; an image is shared through
// a pointer to const), compared by its parameters, and never changed behind its holder's back (no
// lazy or cached state), so threads share it freely.
#pragma once

#include <cmath>
#include <complex>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kernels/psf_profile.hpp"

namespace stampede {

// A truncated Moffat is a Moffat with truncation > 0: one kind, so its name, key and header card
// (PSFTYPE) stay "moffat". kGaussian is metacalibration's reconvolution PSF (engine/metacal), not
// a PSF a run reads or simulates.
enum class PsfKind { kMoffat, kAiry, kImage, kGaussian };
// "moffat", "airy", "image", "gaussian": the spelling of psf_input, of the PSFTYPE card and of
// messages.
const char* psf_kind_name(PsfKind kind);
// Case-insensitive inverse of psf_kind_name for the kinds psf_input takes (not "gaussian"); false
// for anything else.
bool parse_psf_kind(std::string_view name, PsfKind* out);

// A user PSF image. Pixels are row-major nx x ny at `oversampling` samples per data pixel.
struct PsfImage {
  int nx = 0, ny = 0;
  std::vector<double> pixels;
  double centre_x = NAN, centre_y = NAN;  // PSF centre in image pixels (0-based); NaN = (n - 1) / 2
  int oversampling = 1;
  bool pixel_integrated = true;  // true: each sample is a pixel integral (its top-hat is divided out)

  // The continuous Fourier transform of the samples, normalised by their sum, at the separable
  // frequencies (fx[i], fy[j]) in cycles per data pixel: out[j * fx.size() + i]. Band-limited: 0
  // where |fx| or |fy| exceeds `nyquist` (at most the image's own, oversampling / 2). False, with
  // *error, when the samples cannot be normalised (zero, negative or non-finite sum).
  bool transform(std::span<const double> fx, std::span<const double> fy, double nyquist,
                 std::span<std::complex<double>> out, std::string* error) const;
};

struct PsfModel {
  PsfKind kind = PsfKind::kMoffat;
  kernels::MoffatProfile moffat;          // kind == kMoffat
  kernels::AiryProfile airy;              // kind == kAiry
  kernels::GaussianProfile gaussian;      // kind == kGaussian
  std::shared_ptr<const PsfImage> image;  // kind == kImage

  static PsfModel Moffat(const kernels::MoffatProfile& m);
  static PsfModel Airy(const kernels::AiryProfile& a);
  static PsfModel Gaussian(const kernels::GaussianProfile& g);
  static PsfModel Image(std::shared_ptr<const PsfImage> img);

  // Message names the option (as in the ini file), its value and the constraint.
  bool IsValid(std::string* why) const;

  // Surface brightness (flux per pixel^2, unit total flux) at (dx, dy) pixels from the centre.
  // NaN for an image: a sampled image has no value between its samples until an interpolant is
  // chosen, and none is (its renderers work from the samples or from k_value).
  double x_value(double dx, double dy) const;
  // Fourier transform at (kx, ky) radians per pixel, k_value(0, 0) = 1: Moffat from
  // kernels::moffat_fourier through the shear, Airy from kernels::airy_fourier, an image from
  // PsfImage::transform at its own Nyquist frequency. NaN where no transform is implemented (an
  // obscured Airy disc) and for an image that cannot be normalised.
  std::complex<double> k_value(double kx, double ky) const;

  // The PSF as written to output rows: ellipticity and FWHM in pixels (an Airy disc is round, its
  // FWHM that of the unobscured disc); NaN for an image.
  double e1() const;
  double e2() const;
  double fwhm() const;

  // Same kind and parameters; images are the same when they are the same object.
  bool operator==(const PsfModel& other) const;
};

}  // namespace stampede
