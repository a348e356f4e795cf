// PSF kernels; see psf_kernel.hpp.
#include "engine/render/psf_kernel.hpp"

#include "engine/render/fourier_downsampler.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

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

// The image's continuous transform at the model grid's frequencies (cycles per data pixel,
// f = k * upsampling / n), band-limited to the lower of the image's and the grid's Nyquist frequency.
bool image_spectrum(const PsfImage& img, const GridGeometry& g, std::vector<std::complex<double>>* spec,
                    std::string* error) {
  const int n = g.grid_size();
  const int nc = n / 2 + 1;
  const double f_per_k = static_cast<double>(g.upsampling) / n;
  std::vector<double> fx(nc), fy(n);
  for (int kx = 0; kx < nc; ++kx) fx[kx] = kx * f_per_k;
  for (int ky = 0; ky < n; ++ky) fy[ky] = signed_frequency(ky, n) * f_per_k;
  spec->resize(static_cast<std::size_t>(n) * nc);
  return img.transform(fx, fy, 0.5 * std::min<double>(img.oversampling, g.upsampling), *spec, error);
}

}  // namespace

std::shared_ptr<const PsfKernel> PsfKernel::build(const PsfModel& psf, const GridGeometry& geometry,
                                                  FftPlanCache& plans, std::string* error) {
  std::string why;
  if (!psf.IsValid(&why)) {
    *error = why;
    return nullptr;
  }
  auto kernel = std::shared_ptr<PsfKernel>(new PsfKernel(geometry));
  const int n = geometry.grid_size();
  const double step = geometry.step();
  if (psf.kind == PsfKind::kImage) {
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
    if (psf.kind == PsfKind::kMoffat)
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
