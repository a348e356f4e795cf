// PSF kernels; see psf_kernel.hpp.
#include "engine/render/psf_kernel.hpp"

#include "engine/render/fourier_downsampler.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

#include "kernels/math/sinc.hpp"
#include "kernels/moments.hpp"

namespace stampede {
namespace {

using kernels::sinc;
inline int signed_frequency(int k, int n) { return k <= n / 2 ? k : k - n; }

// Multiplies a half-spectrum by the sub-pixel top-hat sinc(pi k / n) per axis and by 1/n^2.
void apply_subpixel_tophat(std::vector<std::complex<double>>& spec, int n) {
  const int nc = n / 2 + 1;
  const double inv = 1.0 / (static_cast<double>(n) * n);
  for (int ky = 0; ky < n; ++ky) {
    const double sy = sinc(std::numbers::pi * signed_frequency(ky, n) / n);
    for (int kx = 0; kx < nc; ++kx) spec[static_cast<std::size_t>(ky) * nc + kx] *= sy * sinc(std::numbers::pi * kx / n) * inv;
  }
}

// Continuous Fourier transform of a sampled PSF image at the model grid's frequencies, computed
// separably (rows, then columns); band-limited to the image's own Nyquist frequency.
bool image_spectrum(const PsfImage& img, const GridGeometry& g, std::vector<std::complex<double>>* spec,
                    std::string* error) {
  const int n = g.grid_size();
  const int nc = n / 2 + 1;
  const double o = img.oversampling;
  const double cx = std::isnan(img.centre_x) ? 0.5 * (img.nx - 1) : img.centre_x;
  const double cy = std::isnan(img.centre_y) ? 0.5 * (img.ny - 1) : img.centre_y;
  double total = 0;
  for (double v : img.pixels) total += v;
  if (!std::isfinite(total) || !(total > 0.0)) {
    std::ostringstream msg;
    msg << "PSF image cannot be normalised: its pixel sum is " << total;
    *error = msg.str();
    return false;
  }
  // Frequencies in cycles per data pixel: f = k * upsampling / n.
  const double f_per_k = static_cast<double>(g.upsampling) / n;
  const double nyquist = 0.5 * std::min<double>(o, g.upsampling);
  // Row transform along y: T[ky][m] = sum_j p[j][m] exp(-2 pi i fy y_j).
  std::vector<std::complex<double>> t(static_cast<std::size_t>(n) * img.nx);
  for (int ky = 0; ky < n; ++ky) {
    const double fy = signed_frequency(ky, n) * f_per_k;
    if (std::abs(fy) > nyquist) continue;
    for (int j = 0; j < img.ny; ++j) {
      const double ph = -2.0 * std::numbers::pi * fy * (j - cy) / o;
      const std::complex<double> w(std::cos(ph), std::sin(ph));
      const double* row = img.pixels.data() + static_cast<std::size_t>(j) * img.nx;
      std::complex<double>* trow = t.data() + static_cast<std::size_t>(ky) * img.nx;
      for (int m = 0; m < img.nx; ++m) trow[m] += w * row[m];
    }
  }
  std::vector<std::complex<double>> wx(static_cast<std::size_t>(nc) * img.nx);
  for (int kx = 0; kx < nc; ++kx) {
    const double fx = kx * f_per_k;
    for (int m = 0; m < img.nx; ++m) {
      const double ph = -2.0 * std::numbers::pi * fx * (m - cx) / o;
      wx[static_cast<std::size_t>(kx) * img.nx + m] = {std::cos(ph), std::sin(ph)};
    }
  }
  spec->assign(static_cast<std::size_t>(n) * nc, {0.0, 0.0});
  for (int ky = 0; ky < n; ++ky) {
    const double fy = signed_frequency(ky, n) * f_per_k;
    if (std::abs(fy) > nyquist) continue;
    const std::complex<double>* trow = t.data() + static_cast<std::size_t>(ky) * img.nx;
    for (int kx = 0; kx < nc; ++kx) {
      const double fx = kx * f_per_k;
      if (fx > nyquist) break;
      std::complex<double> s = 0;
      const std::complex<double>* w = wx.data() + static_cast<std::size_t>(kx) * img.nx;
      for (int m = 0; m < img.nx; ++m) s += trow[m] * w[m];
      s /= total;
      // A pixel-integrated sample carries the image pixel's top-hat: divide it out.
      if (img.pixel_integrated) s /= sinc(std::numbers::pi * fx / o) * sinc(std::numbers::pi * fy / o);
      (*spec)[static_cast<std::size_t>(ky) * nc + kx] = s;
    }
  }
  return true;
}

}  // namespace

const char* psf_type_name(PsfType t) {
  switch (t) {
    case PsfType::kMoffat: return "moffat";
    case PsfType::kAiry: return "airy";
    case PsfType::kImage: return "image";
  }
  return "?";
}

bool parse_psf_type(const std::string& name, PsfType* out) {
  for (PsfType t : {PsfType::kMoffat, PsfType::kAiry, PsfType::kImage})
    if (name == psf_type_name(t)) {
      *out = t;
      return true;
    }
  return false;
}

bool PsfOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  switch (type) {
    case PsfType::kMoffat:
      if (!(moffat.beta > 1.0 && moffat.beta < 100.0))
        msg << "psf_beta = " << moffat.beta << ": must be in (1, 100) (a Moffat with beta <= 1 has infinite flux)";
      else if (!(moffat.fwhm > 0.0 && std::isfinite(moffat.fwhm)))
        msg << "psf_fwhm = " << moffat.fwhm << ": must be > 0 (pixels)";
      else if (!(std::hypot(moffat.e1, moffat.e2) < 1.0))
        msg << "psf_e1, psf_e2 = " << moffat.e1 << ", " << moffat.e2 << ": |e| must be < 1";
      else if (!(moffat.truncation >= 0.0 && std::isfinite(moffat.truncation)))
        msg << "psf_truncation = " << moffat.truncation << ": must be >= 0 (0 = none)";
      break;
    case PsfType::kAiry:
      if (!(airy.lambda_over_d > 0.0 && std::isfinite(airy.lambda_over_d)))
        msg << "airy_lambda_over_d = " << airy.lambda_over_d << ": must be > 0 (pixels)";
      else if (!(airy.obscuration >= 0.0 && airy.obscuration < 1.0))
        msg << "airy_obscuration = " << airy.obscuration << ": must be in [0, 1)";
      break;
    case PsfType::kImage:
      if (!image)
        msg << "psf_input = image needs a PSF image";
      else if (image->nx < 1 || image->ny < 1 ||
               image->pixels.size() != static_cast<std::size_t>(image->nx) * image->ny)
        msg << "PSF image is " << image->nx << " x " << image->ny << " with " << image->pixels.size() << " pixels";
      else if (image->oversampling < 1)
        msg << "psf_upsampling = " << image->oversampling << ": must be >= 1";
      break;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

std::shared_ptr<const PsfKernel> PsfKernel::build(const PsfOptions& psf, const GridGeometry& geometry,
                                                  FftPlanCache& plans, std::string* error) {
  std::string why;
  if (!psf.IsValid(&why)) {
    *error = why;
    return nullptr;
  }
  auto kernel = std::shared_ptr<PsfKernel>(new PsfKernel(geometry));
  const int n = geometry.grid_size();
  const double step = geometry.step();
  if (psf.type == PsfType::kImage) {
    if (!image_spectrum(*psf.image, geometry, &kernel->spectrum_, error)) return nullptr;
    const PsfImage& img = *psf.image;
    kernel->grid_flux_ = 1.0;
    if (img.nx == img.ny) {
      // The wrapped-layout helper expects lag 0 at index 0: shift the image's centre there.
      std::vector<double> wrapped(img.pixels.size());
      const int m = img.nx;
      const int sx = static_cast<int>(std::lround(std::isnan(img.centre_x) ? 0.5 * (m - 1) : img.centre_x));
      const int sy = static_cast<int>(std::lround(std::isnan(img.centre_y) ? 0.5 * (m - 1) : img.centre_y));
      for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i)
          wrapped[static_cast<std::size_t>(((j - sy) % m + m) % m) * m + ((i - sx) % m + m) % m] =
              img.pixels[static_cast<std::size_t>(j) * m + i];
      kernel->set_adaptive_moments(wrapped.data(), m, 1.0 / img.oversampling);
    }
  } else {
    FftConvolver& fft = plans.get(n);
    AlignedBuffer buffer = fft.make_real_buffer();
    auto* samples = static_cast<double*>(buffer.data());
    if (psf.type == PsfType::kMoffat)
      kernels::sample_moffat_wrapped(psf.moffat, n, step, samples);
    else
      kernels::sample_airy_wrapped(psf.airy, n, step, samples);
    double s = 0;
    for (int k = 0; k < n * n; ++k) s += samples[k];
    kernel->grid_flux_ = s;
    kernel->set_adaptive_moments(samples, n, step);
    kernel->spectrum_.resize(fft.spectrum_size());
    fft.forward(samples, kernel->spectrum_.data());
  }
  apply_subpixel_tophat(kernel->spectrum_, n);
  kernel->folded_ = FourierDownsampler::fold_kernel(geometry, kernel->spectrum_.data());
  return kernel;
}

}  // namespace stampede

namespace stampede {

void PsfKernel::set_adaptive_moments(const double* wrapped, int n, double step) {
  // Unwrap so the PSF sits at the centre of an n x n image, then measure it the way the starting
  // point measures galaxies (adaptive moments), so the two can be subtracted.
  std::vector<double> img(static_cast<std::size_t>(n) * n), ones(img.size(), 1.0);
  const int h = n / 2;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      img[static_cast<std::size_t>((j + h) % n) * n + (i + h) % n] = wrapped[static_cast<std::size_t>(j) * n + i];
  const kernels::ImageMoments m = kernels::adaptive_moments(img, ones, n);
  if (!m.valid) return;
  // Sub-pixel samples: convert to data pixels^2 and add the data pixel's own variance (1/12).
  xx_ = m.xx * step * step + 1.0 / 12.0;
  xy_ = m.xy * step * step;
  yy_ = m.yy * step * step + 1.0 / 12.0;
}

}  // namespace stampede
