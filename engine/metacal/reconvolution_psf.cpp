// The reconvolution PSF; see reconvolution_psf.hpp.
#include "engine/metacal/reconvolution_psf.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <vector>

#include "engine/common/number_text.hpp"
#include "engine/model/pixelated_psf.hpp"
#include "kernels/ellipse.hpp"
#include "kernels/moments.hpp"

namespace stampede {

const char* reconvolution_rule_name(ReconvolutionRule r) {
  switch (r) {
    case ReconvolutionRule::kAuto: return "auto";
    case ReconvolutionRule::kGauss: return "gauss";
    case ReconvolutionRule::kMoffat: return "moffat";
  }
  return "?";
}

bool parse_reconvolution_rule(std::string_view name, ReconvolutionRule* out) {
  std::string s(name);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (ReconvolutionRule r : {ReconvolutionRule::kAuto, ReconvolutionRule::kGauss, ReconvolutionRule::kMoffat})
    if (s == reconvolution_rule_name(r)) {
      *out = r;
      return true;
    }
  return false;
}

namespace {

PsfModel round_moffat(double beta, double fwhm) {
  kernels::MoffatProfile m;
  m.beta = beta;
  m.fwhm = fwhm;
  return PsfModel::Moffat(m);
}

// The ellipse of a round profile on the sky seen in the frame's pixels: f(|J x|^2 / a^2) =
// f(x^T Q' x / (a^2 / d)) with Q = J^T J = d Q', det Q' = 1, d = |det J|.
struct SkyShape {
  double e1 = 0, e2 = 0, scale = 1;  // the pixels' FWHM = the sky's x scale
};
SkyShape sky_shape(const PixelFrame& frame) {
  SkyShape out;
  if (frame.unit_jacobian()) return out;
  const kernels::EllipseQuadratic q{frame.dudx * frame.dudx + frame.dvdx * frame.dvdx,
                                    frame.dudx * frame.dudy + frame.dvdx * frame.dvdy,
                                    frame.dudy * frame.dudy + frame.dvdy * frame.dvdy};
  double r = 0;
  kernels::ellipse_parameters(q, &out.e1, &out.e2, &r);
  out.scale = 1 / std::sqrt(std::abs(frame.determinant()));
  return out;
}

// A round Gaussian on the sky (FWHM in the frame's sky units) in the frame's pixels.
PsfModel gaussian_on_sky(double fwhm, const PixelFrame& frame) {
  const SkyShape s = sky_shape(frame);
  kernels::GaussianProfile g;
  g.fwhm = fwhm * s.scale, g.e1 = s.e1, g.e2 = s.e2;
  return PsfModel::Gaussian(g);
}

// An image PSF's Gamma search starts at this fraction of its Gaussian-equivalent FWHM: a Moffat's
// moments overstate its core (beta 3: 2.3 x its FWHM), so the narrowest Gamma lies well below.
constexpr double kImageStart = 0.5;

// The search's rungs: start x 1.03^n, n < kRungs, by repeated multiplication.
constexpr int kRungs = 40;
std::array<double, kRungs> rungs_from(double start) {
  std::array<double, kRungs> out{};
  double fwhm = start;
  for (double& f : out) f = fwhm, fwhm *= 1.03;
  return out;
}

// The first rung n >= lo where passes(n) holds, bisecting (passes holds on every rung above one
// where it holds: MetacalFilters::passes_coarse_check); kRungs when none does.
template <class Passes>
int first_passing(int lo, const Passes& passes) {
  if (lo >= kRungs || passes(lo)) return lo;
  int fails = lo, holds = kRungs - 1;
  if (!passes(holds)) return kRungs;
  while (holds - fails > 1) {
    const int mid = (fails + holds) / 2;
    (passes(mid) ? holds : fails) = mid;
  }
  return holds;
}

// The largest singular value of J: how far a unit step in the pixels reaches on the sky at most.
double largest_stretch(const PixelFrame& f) {
  const double a = f.dudx * f.dudx + f.dvdx * f.dvdx, b = f.dudx * f.dudy + f.dvdx * f.dvdy,
               c = f.dudy * f.dudy + f.dvdy * f.dvdy;
  return std::sqrt(0.5 * (a + c) + std::sqrt(0.25 * (a - c) * (a - c) + b * b));
}

// The major axis's variance of a covariance (pixels^2), or on the sky through `frame` (J C J^T).
double major_variance(double xx, double xy, double yy, const PixelFrame& frame) {
  if (!frame.unit_jacobian()) {
    const double j[2][2] = {{frame.dudx, frame.dudy}, {frame.dvdx, frame.dvdy}}, c[2][2] = {{xx, xy}, {xy, yy}};
    double s[2][2];
    for (int r = 0; r < 2; ++r)
      for (int q = 0; q < 2; ++q) {
        s[r][q] = 0;
        for (int a = 0; a < 2; ++a)
          for (int b = 0; b < 2; ++b) s[r][q] += j[r][a] * c[a][b] * j[q][b];
      }
    xx = s[0][0], xy = s[0][1], yy = s[1][1];
  }
  const double tr = xx + yy, det = xx * yy - xy * xy;
  return 0.5 * tr + std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
}

// The Gaussian-equivalent FWHM 2.3548 sqrt(lambda_max) of an image PSF's adaptive-moment
// covariance, in data pixels, or on the sky through `frame` (J C J^T).
bool image_major_fwhm(const PsfImage& im, const PixelFrame& frame, double* major, std::string* error) {
  if (im.nx != im.ny) {
    *error = "metacal needs a square PSF image, not " + std::to_string(im.nx) + " x " + std::to_string(im.ny);
    return false;
  }
  const std::vector<double> ones(im.pixels.size(), 1.0);
  const kernels::ImageMoments mom = kernels::adaptive_moments(im.pixels, ones, im.nx);
  if (!mom.valid) {
    *error = "metacal: the PSF image has no adaptive moments (no positive flux, or no shape)";
    return false;
  }
  const double o2 = static_cast<double>(im.oversampling) * im.oversampling;
  *major = 2.3548 * std::sqrt(major_variance(mom.xx / o2, mom.xy / o2, mom.yy / o2, frame));
  return true;
}

// The same for an analytic PSF, from its pixel-integrated image (each pixel the mean of 3 x 3
// point values, out to four FWHM), as a PSF image of it would give.
bool analytic_major_fwhm(const PsfModel& psf, const PixelFrame& frame, double* major, std::string* error) {
  const double fwhm = psf.fwhm();
  if (!(fwhm > 0) || !std::isfinite(fwhm) || fwhm > 200) {
    *error = "metacal: the PSF's FWHM " + number_text(fwhm) + " px has no Gaussian fit";
    return false;
  }
  const int n = 2 * static_cast<int>(std::ceil(4 * fwhm)) + 1;
  // Per thread: a catalogue of Moffats asks this once per object.
  thread_local std::vector<double> image, ones;
  image.resize(static_cast<std::size_t>(n) * n);
  ones.assign(image.size(), 1.0);
  pixelated_psf(psf, n, 3, image);
  const kernels::ImageMoments mom = kernels::adaptive_moments(image, ones, n);
  if (!mom.valid) {
    *error = "metacal: the PSF has no adaptive moments";
    return false;
  }
  *major = 2.3548 * std::sqrt(major_variance(mom.xx, mom.xy, mom.yy, frame));
  return true;
}

// The largest filter gain a Gaussian Gamma is accepted with: asked for (kGauss), 1.5; chosen by
// kAuto, 1.01, the Moffat rule's bound (Gamma wider than the sheared PSF at every k). Over a Moffat
// PSF (beta 2.5-4.5) the Gaussian fitted to it peaks at 1.12-1.30 at middle k, where the Moffat's
// transform, steepened at low k by its wings, has fallen below the Gaussian's: its images' noise per
// pixel is a quarter of the Moffat rule's, but `fit --metacal` at S/N 20 measured sigma_m x1.7 and
// m1 -1.5e-2 +- 0.4e-2 with it (docs/metacal.md, "The reconvolution PSF"), so auto keeps the Moffat
// there. A PSF whose transform falls below the Gaussian's at high k (a narrow core in a wide halo)
// sends the gain past any bound.
constexpr double kGaussianMaxGain = 1.5;
constexpr double kAutoGaussianMaxGain = 1.01;
double gaussian_max_gain(const MetacalOptions& options) {
  return options.reconvolution == ReconvolutionRule::kGauss ? kGaussianMaxGain : kAutoGaussianMaxGain;
}

// The Gaussian rule's Gamma on the sky through `frame`: the PSF x pixel's adaptive Gaussian, its
// major axis, dilated by 1 + 2 step (or psf_dilation), less the pixel's own variance (|det J| / 12
// on the sky): the metacal images are Gamma x pixel, so that their PSF is the dilated fit, the
// narrowest the rule allows (docs/metadetect.md, "The reconvolution PSF": R11 0.356 -> 0.365 on the
// reference test's random cells, sigma_m per pair 0.127 -> 0.111, against Gamma of the dilated fit
// itself). FWHM in sky units; 0 with *error when none.
double gaussian_gamma_fwhm(const PsfModel& psf, const PixelFrame& frame, const MetacalOptions& options,
                           std::string* error) {
  double major = 0;
  const bool ok = psf.kind == PsfKind::kImage && psf.image ? image_major_fwhm(*psf.image, frame, &major, error)
                                                             : analytic_major_fwhm(psf, frame, &major, error);
  if (!ok) return 0;
  const double dilation = options.psf_dilation > 0 ? options.psf_dilation : 1 + 2 * options.step;
  const double sigma = dilation * major / 2.3548;
  const double pixel = (frame.unit_jacobian() ? 1.0 : std::abs(frame.determinant())) / 12.0;
  const double variance = sigma * sigma - pixel;
  if (!(variance > 0)) {
    *error = "metacal: the PSF's Gaussian (FWHM " + number_text(major) + ") is not wider than a pixel";
    return 0;
  }
  return 2.3548 * std::sqrt(variance);
}

}  // namespace

namespace {

// Why no Gamma serves, after the Moffat rule failed too (kAuto) or alone (kMoffat).
std::string no_gamma(const MetacalOptions& options, const std::string& gauss_why, const std::string& moffat_why) {
  return options.reconvolution == ReconvolutionRule::kAuto
             ? "neither a Gaussian (" + gauss_why + ") nor a Moffat (" + moffat_why + ") reconvolution PSF serves"
             : moffat_why;
}

// Today's rule: the round Moffat (reconvolution_psf.hpp).
std::shared_ptr<const MetacalFilters> moffat_filters(const PsfModel& psf, const MetacalOptions& options, int period,
                                                     std::string* error) {
  if (psf.kind == PsfKind::kMoffat) {
    const double e = std::hypot(psf.moffat.e1, psf.moffat.e2);
    const double dilation =
        options.psf_dilation > 0 ? options.psf_dilation : (1 + 2 * options.step) * std::sqrt((1 + e) / (1 - e));
    return MetacalFilters::build(psf, round_moffat(psf.moffat.beta, psf.moffat.fwhm * dilation), options.step, period,
                                 error);
  }
  if (psf.kind == PsfKind::kImage && psf.image) {
    double major = 0;
    std::string why;
    if (!image_major_fwhm(*psf.image, PixelFrame(), &major, &why)) {
      if (error) *error = why;
      return nullptr;
    }
    // The Gaussian-equivalent FWHM of the major axis overstates a Moffat core's: start below it
    // and widen until every filter is bounded, which finds the narrowest Gamma that serves.
    if (options.psf_dilation > 0) {
      auto f = MetacalFilters::build(psf, round_moffat(3.0, major * options.psf_dilation), options.step, period, &why);
      if (!f && error) *error = why;
      return f;
    }
    const auto observed = MetacalFilters::observe(psf, period, error);
    if (!observed) return nullptr;
    // The narrowest rung that passes the coarse check, then full builds up from it: the rung a
    // full build at every rung from the first would accept, at a fraction of the builds.
    const auto fwhms = rungs_from(kImageStart * major);
    int n = first_passing(0, [&](int i) {
      return MetacalFilters::passes_coarse_check(*observed, round_moffat(3.0, fwhms[i]), options.step);
    });
    for (n = std::min(n, kRungs - 1); n < kRungs; ++n) {
      auto f = MetacalFilters::build(*observed, round_moffat(3.0, fwhms[n]), options.step, &why);
      if (f) return f;
    }
    if (error) *error = why + " (round Moffats up to FWHM " + number_text(fwhms.back()) + " px tried)";
    return nullptr;
  }
  if (error)
    *error = std::string("metacal needs a Moffat or image PSF (psf_input = moffat, moffat_catalog or image); this PSF "
                         "is '") + psf_kind_name(psf.kind) + "'";
  return nullptr;
}

}  // namespace

std::shared_ptr<const MetacalFilters> reconvolution_filters(const PsfModel& psf, const MetacalOptions& options,
                                                            int period, std::string* error) {
  std::string gauss_why;
  if (options.reconvolution != ReconvolutionRule::kMoffat) {
    const double fwhm = gaussian_gamma_fwhm(psf, PixelFrame(), options, &gauss_why);
    if (fwhm > 0) {
      kernels::GaussianProfile g;
      g.fwhm = fwhm;
      auto f = MetacalFilters::build(psf, PsfModel::Gaussian(g), options.step, period, &gauss_why,
                                     gaussian_max_gain(options));
      if (f) return f;
    }
    if (options.reconvolution == ReconvolutionRule::kGauss) {
      if (error) *error = "Gaussian reconvolution PSF: " + gauss_why;
      return nullptr;
    }
  }
  std::string moffat_why;
  auto f = moffat_filters(psf, options, period, &moffat_why);
  if (!f && error) *error = no_gamma(options, gauss_why, moffat_why);
  return f;
}

PsfModel round_on_sky(double beta, double fwhm, const PixelFrame& frame) {
  if (frame.unit_jacobian()) return round_moffat(beta, fwhm);
  const SkyShape s = sky_shape(frame);
  PsfModel p = round_moffat(beta, fwhm * s.scale);
  p.moffat.e1 = s.e1, p.moffat.e2 = s.e2;
  return p;
}

namespace {

// The Gaussian rule across cutouts: each cutout's Gamma on the sky, the widest serving all.
bool sky_gaussian(std::span<const MetacalEpochPsf> epochs, const MetacalOptions& options, SkyReconvolution* out,
                  std::string* error) {
  double fwhm = 0;
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    std::string why;
    const double f = gaussian_gamma_fwhm(*epochs[k].psf, epochs[k].frame, options, &why);
    if (!(f > 0)) {
      *error = "cutout " + std::to_string(k) + ": " + why;
      return false;
    }
    fwhm = std::max(fwhm, f);
  }
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    std::string why;
    out->filters[k] = MetacalFilters::build(*epochs[k].psf, gaussian_on_sky(fwhm, epochs[k].frame), options.step,
                                            epochs[k].period, &why, gaussian_max_gain(options), epochs[k].frame);
    if (!out->filters[k]) {
      *error = "cutout " + std::to_string(k) + ": " + why;
      return false;
    }
  }
  out->kind = PsfKind::kGaussian, out->fwhm = fwhm, out->beta = 0;
  return true;
}

bool sky_moffat(std::span<const MetacalEpochPsf> epochs, const MetacalOptions& options, SkyReconvolution* out,
                std::string* error);

}  // namespace

bool sky_reconvolution(std::span<const MetacalEpochPsf> epochs, const MetacalOptions& options, SkyReconvolution* out,
                       std::string* error) {
  out->filters.assign(epochs.size(), nullptr);
  if (epochs.empty()) {
    if (error) *error = "metacal: no cutout";
    return false;
  }
  std::string gauss_why;
  if (options.reconvolution != ReconvolutionRule::kMoffat) {
    if (sky_gaussian(epochs, options, out, &gauss_why)) return true;
    if (options.reconvolution == ReconvolutionRule::kGauss) {
      if (error) *error = "Gaussian reconvolution PSF: " + gauss_why;
      return false;
    }
    out->filters.assign(epochs.size(), nullptr);
  }
  std::string moffat_why;
  if (sky_moffat(epochs, options, out, &moffat_why)) return true;
  if (error) *error = no_gamma(options, gauss_why, moffat_why);
  return false;
}

namespace {

bool sky_moffat(std::span<const MetacalEpochPsf> epochs, const MetacalOptions& options, SkyReconvolution* out,
                std::string* error) {
  auto fail = [&](std::size_t k, const std::string& why) {
    if (error) *error = "cutout " + std::to_string(k) + ": " + why;
    return false;
  };
  // Each cutout's first Gamma by the single-stamp rule, as its widest extent on the sky; the
  // largest of them starts the search (with that cutout's beta).
  std::vector<std::shared_ptr<const MetacalFilters::Observed>> observed(epochs.size());
  double start = 0, beta = 3;
  bool ladder = false;
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    const MetacalEpochPsf& e = epochs[k];
    const PsfModel& psf = *e.psf;
    std::string why;
    double first = 0, b = 3;
    if (psf.kind == PsfKind::kMoffat) {
      const double ell = std::hypot(psf.moffat.e1, psf.moffat.e2);
      const double dilation =
          options.psf_dilation > 0 ? options.psf_dilation : (1 + 2 * options.step) * std::sqrt((1 + ell) / (1 - ell));
      first = psf.moffat.fwhm * dilation * (e.frame.unit_jacobian() ? 1.0 : largest_stretch(e.frame));
      b = psf.moffat.beta;
    } else if (psf.kind == PsfKind::kImage && psf.image) {
      double major = 0;
      if (!image_major_fwhm(*psf.image, e.frame, &major, &why)) return fail(k, why);
      first = options.psf_dilation > 0 ? major * options.psf_dilation : kImageStart * major;
      ladder = ladder || options.psf_dilation == 0;
    } else {
      return fail(k, std::string("metacal needs a Moffat or image PSF; this PSF is '") + psf_kind_name(psf.kind) + "'");
    }
    observed[k] = MetacalFilters::observe(psf, e.period, &why);
    if (!observed[k]) return fail(k, why);
    if (first > start) start = first, beta = b;
  }
  // An analytic PSF's rule is wide enough by construction: the search widens only when the
  // cutouts' frames or PSFs disagree. Image PSFs search from below, as the single-stamp rule.
  std::string why;
  const auto fwhms = rungs_from(start);
  const int attempts = options.psf_dilation > 0 && !ladder ? 1 : kRungs;
  // An image PSF's search: the narrowest rung every cutout passes the coarse check at (a cutout is
  // bisected past the rung found so far only when it fails there), then full builds up from it:
  // the rung that full builds of every cutout at every rung from the first would accept, at a
  // fraction of the builds. An analytic PSF's first rung nearly always serves.
  int n = 0;
  if (ladder)
    for (std::size_t k = 0; k < epochs.size(); ++k)
      n = first_passing(n, [&](int i) {
        return MetacalFilters::passes_coarse_check(*observed[k], round_on_sky(beta, fwhms[i], epochs[k].frame),
                                                   options.step, 1.01, epochs[k].frame);
      });
  for (n = std::min(n, attempts - 1); n < attempts; ++n) {
    bool all = true;
    for (std::size_t k = 0; k < epochs.size() && all; ++k) {
      const MetacalEpochPsf& e = epochs[k];
      out->filters[k] =
          MetacalFilters::build(*observed[k], round_on_sky(beta, fwhms[n], e.frame), options.step, &why, 1.01, e.frame);
      if (!out->filters[k]) {
        why = "cutout " + std::to_string(k) + ": " + why;
        all = false;
      }
    }
    if (all) {
      out->kind = PsfKind::kMoffat, out->fwhm = fwhms[n], out->beta = beta;
      return true;
    }
  }
  if (error) *error = why + " (round Moffats on the sky up to FWHM " + number_text(fwhms[attempts - 1]) + " tried)";
  return false;
}

}  // namespace

}  // namespace stampede
