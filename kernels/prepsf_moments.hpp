// Pre-PSF Gaussian moments ("pgauss", as ngmix's PGaussMom in DES Y6 metadetection): the moments
// of the galaxy before its PSF under a round Gaussian weight, taken in Fourier space. The stamp's
// DFT over the PSF's transform is the deconvolved galaxy's transform; the weight and its second
// moments are smooth in k (a Gaussian and its k-derivatives), so the sums over k converge wherever
// the weight's transform falls faster than the PSF's, with no regularisation. Like wmom, a fixed
// weight keeps the estimator a smooth function of the pixels; unlike wmom, its shape is the
// pre-PSF galaxy's, so its response is nearer 1 and does not fall with the PSF's size.
#pragma once

#include <complex>
#include <span>
#include <vector>

namespace stampede::kernels {

struct PrepsfMoments {
  bool valid = false;     // false: no positive weighted flux or T, |e| >= 1, or a PSF transform <= 0 the weight needs
  double flux = 0;        // integral of w G, w peaking at 1 (as wmom's sum w I): a point source's flux
  double t = 0;           // Mxx + Myy of the weighted, flux-normalised pre-PSF moments, pixels^2
  double e1 = 0, e2 = 0;  // (Mxx - Myy) / T, 2 Mxy / T
  double e1_err = 0, e2_err = 0, snr = 0;  // white pixel noise of `variance`, propagated linearly
};

// The angular frequency (radians per pixel) of DFT index i of n: 2 pi m / n, m = i for i <= n / 2,
// else i - n. psf_k is laid out on it: psf_k[j * n + i] at (kx, ky) = (f(i), f(j)).
double dft_frequency(int i, int n);

// image: size x size, row-major (x fastest), pixel centres at integers; (xc, yc): the weight's
// centre (the phase centre), in pixels. psf_k: the PSF's transform on the stamp's DFT grid, real
// (a centred, point-symmetric PSF; the pixel's response included when the image is pixel-
// integrated), 1 at k = 0; read only where the weight's transform exceeds 1e-15 of its peak
// (sigma^2 k^2 / 2 < 34.5). fwhm: the weight's, pixels. The stamp is periodic to the DFT, so the
// object and its PSF-convolved light should lie well inside it. scratch grows to what is needed
// and is kept: a caller that reuses it allocates nothing in steady state.
PrepsfMoments prepsf_moments(std::span<const double> image, int size, double xc, double yc, double fwhm,
                             std::span<const double> psf_k, double variance,
                             std::vector<std::complex<double>>& scratch);

}  // namespace stampede::kernels
