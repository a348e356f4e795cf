// The noise-bias model of the calibration (im3shape section 5.3 and appendix C): cubic bias curves
// per grid point, a cubic-spline interpolation between grid points, population means over a deep
// sample, and the per-object scaling and PSF rotation.
//
// Curves. At each (r_d, F) and for e_true along axis a (e1 or e2), the bias of component c,
//   b_ac(e) = <e_fit,c> - e_true,c = a0 + a1 e + a2 e^2 + a3 e^3,
// is fitted to the grid's point biases (weights 1 / error^2).
//
// From curves to m and c. Away from PSF effects the bias is radial, e_fit - e = f(|e|) e / |e|,
// with f odd: the odd part of b_11 along e1 (and of b_22 along e2) is f(r) = a1 r + a3 r^3. For a
// population isotropic in e, a shear g turns e into e' = (e + g) / (1 + conj(g) e) (reduced-shear
// ellipticities, whose ring mean is exactly g), d e' / d g1 = 1 - e^2, and the orientation average
// of d F_1(e') / d g1 for F = f(r) e / r is
//   1 + m,   m = (f' + f / r) / 2 - r^2 (f' - f / r) / 2 = a1 + 2 a3 r^2 - a3 r^4   (r = |e|).
// The even parts, a0 + a2 r^2, are the additive bias; averaging b_1 over the four orientations the
// grid samples (along +-e1 from b_11, along +-e2 from b_21) gives c1(r), and c2(r) likewise from
// b_12 and b_22. m is the mean of the two components' values (they differ only through the PSF).
// A PSF of ellipticity e0 leaves the problem symmetric under the reflection that keeps e0, so the
// mean additive bias lies along e0: c is projected on it (appendix C's scalar c_hat), the cross
// component, pure noise, dropped. A round calibration PSF gives no direction: c is kept whole.
//
// Interpolation. The 16 coefficients (2 axes x 2 components x a0..a3) are interpolated together
// over (ln r_d, F) by the tensor product of natural cubic splines (kernels/tensor_spline). The paper
// uses a Gaussian RBF; held-out nodes of a dense table are predicted better by the splines, and an
// RBF of fixed width turns singular on a dense grid (docs/calibration/interpolation_check.py).
// Properties outside the grid are clamped to its edge and counted.
//
// Application. A bias b measured at S/N_ref scales to an object of S/N s as b (S/N_ref / s)^2
// (Refregier et al. 2012; Kacprzak et al. 2012). c is measured with the calibration's PSF e0; for an
// object whose PSF has ellipticity e_psf (complex), c = c_hat * e_psf / e0 (appendix C: scaled by
// |e_psf| / |e0| and turned by the PSF's angle). With a round calibration PSF, c is applied as is.
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "engine/calibration/calibration_grid.hpp"
#include "kernels/tensor_spline.hpp"

namespace stampede {

struct BiasCurve {
  double radius = 0, bulge_fraction = 0;
  BiasAxis axis = BiasAxis::kE1;
  int component = 0;  // 0: e1, 1: e2
  std::array<double, 4> coefficients{};  // a0 .. a3 (NaN when the fit failed)
  std::array<double, 4> errors{};
  double chi2 = 0;
  int points = 0;  // grid points with a measured bias
};

// What `stampede calibrate build` measures and writes.
struct CalibrationTable {
  CalibrationGridOptions grid;
  std::vector<CalibrationPoint> points;
  std::vector<PointBias> biases;  // one per point
  std::vector<BiasCurve> curves;  // per (radius, F): axis e1 comp 0, e1 comp 1, e2 comp 0, e2 comp 1
  // The fit configuration of the calibration run (the science run must use the same).
  std::vector<std::pair<std::string, std::string>> config;
};

// Fits the cubic curves of every (radius, F, axis, component) to the points' biases. The points
// and biases are those of `grid` (same order).
std::vector<BiasCurve> fit_bias_curves(const CalibrationGridOptions& grid, const std::vector<CalibrationPoint>& points,
                                       const std::vector<PointBias>& biases);

// True properties of a galaxy (or the best estimate available).
struct GalaxyProperties {
  double radius = 0;          // disc half-light radius r_d, pixels
  double bulge_fraction = 0;  // F
  double e = 0;               // |e|
};

struct Bias {
  double m = 0, c1 = 0, c2 = 0;
};

class NoiseBiasModel {
 public:
  // Throws std::invalid_argument when a curve is missing, failed or out of order.
  explicit NoiseBiasModel(const CalibrationTable& table);
  // m and c at the reference S/N in the calibration PSF's frame. *clamped (if given) is set when a
  // property lay outside the grid and was moved to its edge.
  Bias at(const GalaxyProperties& galaxy, bool* clamped = nullptr) const;
  double snr_ref() const { return snr_ref_; }
  std::complex<double> psf_e0() const { return psf_e0_; }

 private:
  kernels::TensorSpline spline_;
  double ln_r_min_ = 0, ln_r_max_ = 0, f_min_ = 0, f_max_ = 0, e_max_ = 0;
  double snr_ref_ = 0;
  std::complex<double> psf_e0_ = 0;
};

// Running mean of the model over a sample (the deep catalogue: the population mean of
// appendix C, m_hat = integral m(theta) p(theta) d theta with p from the deep fits).
class PopulationBias {
 public:
  explicit PopulationBias(const NoiseBiasModel& model) : model_(model) {}
  void add(const GalaxyProperties& galaxy);
  long long count() const { return n_; }
  long long clamped() const { return clamped_; }
  Bias mean() const;

 private:
  const NoiseBiasModel& model_;
  long long n_ = 0, clamped_ = 0;
  double sum_m_ = 0, sum_c1_ = 0, sum_c2_ = 0;
};

// The calibration's statistical error on a population mean: the point biases are redrawn
// `resamples` times from N(bias, error), the cubics refitted and the model rebuilt, and the
// standard deviation of the sample's mean m and c over the redraws returned (a parametric bootstrap
// that keeps the covariance of each cubic's coefficients). Deterministic for a seed.
Bias population_bias_error(const CalibrationTable& table, const std::vector<GalaxyProperties>& sample, int resamples,
                           std::uint64_t seed);

// The correction for one object: `bias` (at S/N_ref, calibration PSF frame) scaled by
// (snr_ref / snr)^2 and c turned to the object's PSF (psf_e NaN: the calibration PSF assumed).
// NaN when snr is not a positive number.
Bias object_correction(const Bias& bias, double snr_ref, std::complex<double> psf_e0, double snr,
                       std::complex<double> psf_e);

// e_cal = (e - c) / (1 + m), per component.
inline void calibrate_ellipticity(const Bias& b, double e1, double e2, double* e1_cal, double* e2_cal) {
  *e1_cal = (e1 - b.c1) / (1 + b.m);
  *e2_cal = (e2 - b.c2) / (1 + b.m);
}

}  // namespace stampede
