// What a metacalibration run chooses (ini keys metacal*, README "Metacalibration").
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace stampede {

// The model metacal's five fits use. Metacal calibrates whatever model it fits, so this need not be
// the physical bulge + disc: kExponential is the disc alone, kGaussian a Sérsic n = 0.5 alone
// (DES Y3 fits a Gaussian), each replacing the amplitude and index settings of the run's model.
// kWeightedMoments fits nothing: the moments under a fixed round Gaussian weight (DES Y6's wmom,
// kernels/weighted_moments), of width weight_fwhm.
enum class MetacalModel { kBulgeDisc, kExponential, kGaussian, kWeightedMoments };

// The reconvolution PSF Gamma (engine/metacal/reconvolution_psf; docs/metacal.md, "The
// reconvolution PSF"). kGauss: a round Gaussian, the PSF's adaptive-moment Gaussian on its major
// axis dilated by 1 + 2 step (the reference metadetect package's "fitgauss"), its filters' gain at
// most 1.5; kMoffat: the round Moffat widened until every filter is <= 1.01; kAuto: the Gaussian
// where its filters are <= 1.01 too (a Gaussian-like PSF), else kMoffat.
enum class ReconvolutionRule { kAuto, kGauss, kMoffat };
// "auto", "gauss", "moffat": the option's value and the header's.
const char* reconvolution_rule_name(ReconvolutionRule r);
// Case-insensitive inverse of reconvolution_rule_name; false for anything else.
bool parse_reconvolution_rule(std::string_view name, ReconvolutionRule* out);

struct MetacalOptions {
  bool enabled = false;
  double step = 0.01;  // the applied shear delta, in [kMinStep, 0.1]
  // R = (e(+step) - e(-step)) / (2 step): an error in e (the image operations' rounding, the fit's
  // termination, a noisy fit changing basin between the two images) over 2 step is R's error, so a
  // small enough step gives nonsense R with status ok. The floor is far above where noise-free R
  // stops being resolved, and keeps noisy model fits' 1/step tail of R near the default step's
  // (docs/metacal.md, "The step's floor").
  static constexpr double kMinStep = 1e-3;
  // FWHM of the round reconvolution PSF over the PSF's (a Gaussian Gamma's over the PSF's adaptive
  // Gaussian's major axis); 0 = the rule's own: a Gaussian's 1 + 2 step, a Moffat's the smallest
  // safe one, (1 + 2 step) times the PSF's axis ratio factor sqrt((1 + |e|) / (1 - |e|)) (wider
  // than the sheared PSF in every direction).
  double psf_dilation = 0.0;
  ReconvolutionRule reconvolution = ReconvolutionRule::kAuto;
  // Add a second noise field, rotated by 90 degrees through the same operations, so that the
  // images' correlated noise is isotropic (Sheldon & Huff 2017's "fixnoise").
  bool fixnoise = true;
  std::uint64_t seed = 20170101;  // keys the fixnoise fields with each object's id
  // Set by a run on a grid simulated with noise pairs (its NOISEPR = T: objects 4q+2 and 4q+3 are
  // 4q and 4q+1 with the noise negated): the pair's fixnoise fields are negated alike, so the
  // fixnoise noise cancels at first order in the pair as the simulated noise does.
  bool noise_pairs = false;
  // wmom by default: the smallest shear error per object of the four, at the least cost (docs/metacal.md).
  MetacalModel model = MetacalModel::kWeightedMoments;
  // kWeightedMoments: the weight's FWHM in pixels (sky units for MEDS tiles); 0 = kWeightOverGamma
  // x the reconvolution PSF's.
  double weight_fwhm = 0.0;
  static constexpr double kWeightOverGamma = 2.5;  // docs/metacal.md, "Weighted moments"
  // The weight's FWHM for a reconvolution PSF of this FWHM (same units).
  double moments_weight_fwhm(double gamma_fwhm) const { return weight_fwhm > 0 ? weight_fwhm : kWeightOverGamma * gamma_fwhm; }
  bool IsValid(std::string* why) const;
};

}  // namespace stampede
