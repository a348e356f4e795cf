// Shear-measurement metrics (im3shape section 2; GREAT08, Bridle et al. 2009):
//  - per set, the mean of the fitted ellipticities estimates the set's constant shear; 90-degree
//    ring pairs are averaged first so intrinsic shape noise cancels; errors by bootstrap;
//  - across sets, a weighted linear fit g_est_i = (1 + m_i) g_true_i + c_i per component;
//  - c also in the PSF frame (c_plus along the PSF's major axis, c_cross at 45 degrees);
//  - the GREAT08 quality factor Q = 1e-4 / < (<g_est>_set - g_true)^2 >, the average running over
//    every set and both components.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "engine/analysis/unit_shear_estimator.hpp"

namespace stampede {

struct SetShear {
  double g1_true = 0, g2_true = 0;
  double g1 = 0, g2 = 0;        // estimates
  // Bootstrap standard errors; NaN when not computed: fewer than two units (a bootstrap over one
  // ring pair has no spread, not a zero error), fewer than two resamples (bootstrap < 2) or fewer
  // than two resamples with an estimate.
  double err1 = NAN, err2 = NAN;
  long long used = 0;           // objects in the estimate
  long long excluded = 0;       // flagged objects (and the partners of flagged ring members)
  long long units = 0;          // ring pairs (and lone objects) in the estimate: what the bootstrap draws
};

// e1, e2: fitted ellipticities; usable: 0 excludes an object; pair: ring-pair label per object
// (objects sharing a label are averaged first; -1 = no pair). Deterministic for a given seed.
SetShear estimate_set_shear(std::span<const double> e1, std::span<const double> e2, std::span<const int> usable,
                            std::span<const long long> pair, double g1_true, double g2_true, int bootstrap,
                            std::uint64_t seed);

struct BiasFit {
  double m = 0, m_err = 0, c = 0, c_err = 0;
};
// Weighted least squares of y = (1 + m) x + c (weights 1/err^2). When any error is missing (NaN,
// or not positive) the fit is unweighted, its errors from the scatter about the line: that needs
// three sets or more, else m_err and c_err are NaN (two points fit any line exactly; their zero
// scatter is no error). Needs two distinct x.
BiasFit fit_linear_bias(std::span<const double> g_true, std::span<const double> g_est, std::span<const double> err);

struct ShearMetrics {
  std::vector<SetShear> sets;
  BiasFit component[2];
  double c_plus = 0, c_cross = 0;  // c rotated into the PSF frame
  double q = 0;                    // GREAT08 quality factor
};

// psf_e1, psf_e2: the PSF's ellipticity defining the frame (0, 0: c_plus = c1, c_cross = c2).
// m and c are NaN unless two sets with finite estimates differ in each component's true shear.
ShearMetrics combine_sets(std::vector<SetShear> sets, double psf_e1, double psf_e2);

// (c1, c2) in the PSF frame: c_plus along the PSF's major axis, c_cross at 45 degrees to it.
void rotate_into_psf_frame(double c1, double c2, double psf_e1, double psf_e2, double* c_plus, double* c_cross);

// The units of estimate_set_shear (ring pairs whose members are all usable, or lone usable
// objects; a pair with an unusable member counts as unusable), for resampling with another set.
std::unique_ptr<UnitShearEstimator> make_shear_units(std::span<const double> e1, std::span<const double> e2,
                                                     std::span<const int> usable, std::span<const long long> pair);

}  // namespace stampede
