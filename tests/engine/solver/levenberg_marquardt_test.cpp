// Tests engine/levenberg_marquardt: the damping schedule pinned to exact values, the options'
// validation, and the solver on a small analytic problem (y = a exp(-b x) + c): convergence to the
// truth, each stopping rule with its recorded value and threshold, and every failure path.
#include "engine/solver/levenberg_marquardt.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace stampede {
namespace {

// ---------------------------------------------------------------------------------------------
// Damping schedule (Nielsen): accept(rho): mu *= max(1/3, 1 - (2 rho - 1)^3), nu = 2;
// reject: mu *= nu, nu *= 2. Every factor below is a power of two or 1/3 applied to an exactly
// representable mu, so the products are exact or correctly rounded: EXPECT_DOUBLE_EQ / EXPECT_EQ.

TEST(LmDamping, StartsAtMu0WithNu2) {
  const LmDamping d(0.125);
  EXPECT_EQ(d.mu(), 0.125);
  EXPECT_EQ(d.nu(), 2.0);
  EXPECT_FALSE(d.saturated());
}

TEST(LmDamping, AcceptScalesByGainRatio) {
  {
    LmDamping d(0.3);
    d.accept(1.0);  // t = 1: 1 - 1 = 0 -> max(1/3, 0) = 1/3
    EXPECT_DOUBLE_EQ(d.mu(), 0.3 / 3.0);
    EXPECT_EQ(d.nu(), 2.0);
  }
  {
    LmDamping d(0.3);
    d.accept(0.5);  // t = 0: max(1/3, 1) = 1
    EXPECT_EQ(d.mu(), 0.3);
  }
  {
    LmDamping d(0.5);
    d.accept(0.75);  // t = 0.5: 1 - 0.125 = 0.875
    EXPECT_EQ(d.mu(), 0.5 * 0.875);
  }
  {
    LmDamping d(1.0);
    d.accept(0.25);  // t = -0.5: 1 + 0.125 = 1.125 (a poor step raises mu)
    EXPECT_EQ(d.mu(), 1.125);
  }
  {
    LmDamping d(1.0);
    d.accept(0.0);  // t = -1: 1 + 1 = 2
    EXPECT_EQ(d.mu(), 2.0);
  }
  {
    LmDamping d(1.0);
    d.accept(5.0);  // t = 9: 1 - 729 < 1/3 -> 1/3
    EXPECT_DOUBLE_EQ(d.mu(), 1.0 / 3.0);
  }
}

TEST(LmDamping, RejectDoublesNuAndResetsOnAccept) {
  LmDamping d(1e-3);
  d.reject();
  EXPECT_EQ(d.mu(), 2e-3);
  EXPECT_EQ(d.nu(), 4.0);
  d.reject();
  EXPECT_EQ(d.mu(), 8e-3);
  EXPECT_EQ(d.nu(), 8.0);
  d.reject();
  EXPECT_EQ(d.mu(), 6.4e-2);
  EXPECT_EQ(d.nu(), 16.0);
  d.accept(0.5);  // mu unchanged, nu back to 2
  EXPECT_EQ(d.mu(), 6.4e-2);
  EXPECT_EQ(d.nu(), 2.0);
  d.reject();
  EXPECT_EQ(d.mu(), 1.28e-1);
  EXPECT_EQ(d.nu(), 4.0);
}

TEST(LmDamping, SaturatesAt1e30) {
  LmDamping d(1e29);
  EXPECT_FALSE(d.saturated());
  d.reject();  // 2e29
  EXPECT_FALSE(d.saturated());
  d.reject();  // 8e29
  EXPECT_FALSE(d.saturated());
  d.reject();  // 6.4e30
  EXPECT_TRUE(d.saturated());
}

// ---------------------------------------------------------------------------------------------
// Options and stop reasons.

TEST(LmOptions, DefaultsAreValid) {
  std::string why = "untouched";
  EXPECT_TRUE(LmOptions{}.IsValid(&why));
  EXPECT_EQ(why, "untouched");
  EXPECT_TRUE(LmOptions{}.IsValid(nullptr));
}

void expect_invalid(const LmOptions& o, const std::string& field) {
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field;
  EXPECT_NE(why.find(field), std::string::npos) << "message '" << why << "' should name " << field;
  EXPECT_FALSE(o.IsValid(nullptr));
}

TEST(LmOptions, RejectsOutOfRangeValuesNamingTheField) {
  LmOptions o;
  o.eps1 = -1e-3;
  expect_invalid(o, "levmar_eps1");
  o = {};
  o.eps1 = NAN;
  expect_invalid(o, "levmar_eps1");
  o = {};
  o.eps2 = 1.0;  // relative step must be < 1
  expect_invalid(o, "levmar_eps2");
  o = {};
  o.eps2 = -0.1;
  expect_invalid(o, "levmar_eps2");
  o = {};
  o.eps3 = -1.0;
  expect_invalid(o, "levmar_eps3");
  o = {};
  o.eps4 = 1.5;
  expect_invalid(o, "levmar_eps4");
  o = {};
  o.eps4 = NAN;
  expect_invalid(o, "levmar_eps4");
  o = {};
  o.init_mu = 0.0;
  expect_invalid(o, "levmar_LM_INIT_MU");
  o = {};
  o.init_mu = -1e-3;
  expect_invalid(o, "levmar_LM_INIT_MU");
  o = {};
  o.max_iterations = 0;
  expect_invalid(o, "minimizer_max_iterations");
  o = {};
  o.max_iterations = -5;
  expect_invalid(o, "minimizer_max_iterations");
  // Every rule disabled and an unbounded-looking iteration count.
  o = {};
  o.eps4 = 0.0;
  o.max_iterations = 20000;
  expect_invalid(o, "levmar_eps");
  // Boundary values that are allowed: 0 disables a rule.
  o = {};
  o.eps1 = 0.0;
  o.eps2 = 0.999;
  o.eps3 = 1e9;
  o.eps4 = 0.0;
  o.max_iterations = 1;
  EXPECT_TRUE(o.IsValid(nullptr));
}

TEST(StopReason, ToStringAndIsConverged) {
  struct Row {
    StopReason r;
    const char* name;
    bool converged;
  };
  for (const Row& row : {Row{StopReason::kNone, "none", false}, Row{StopReason::kGradient, "gradient", true},
                         Row{StopReason::kRelativeStep, "relative_step", true}, Row{StopReason::kChi2, "chi2", true},
                         Row{StopReason::kRelativeChi2Change, "relative_chi2_change", true},
                         Row{StopReason::kNoProgress, "no_progress", true},
                         Row{StopReason::kMaxIterations, "max_iterations", false},
                         Row{StopReason::kSingular, "singular", false},
                         Row{StopReason::kInvalidStart, "invalid_start", false}}) {
    EXPECT_STREQ(ToString(row.r), row.name);
    EXPECT_EQ(IsConverged(row.r), row.converged) << row.name;
  }
}

// ---------------------------------------------------------------------------------------------
// A small analytic problem: y_i = a exp(-b x_i) + c at x_i = 0.25 i, unit weights, with optional
// fixed perturbations of the data (a deterministic stand-in for noise).

class ExponentialProblem : public LeastSquaresProblem {
 public:
  static constexpr double kA = 3.0, kB = 0.7, kC = 0.5;
  // weight: the same inverse variance on every pixel (chi2 and the normal equations scale with it).
  explicit ExponentialProblem(double noise = 0.0, int npix = 24, double weight = 1.0) : w_(weight) {
    for (int i = 0; i < npix; ++i) {
      x_.push_back(0.25 * i);
      y_.push_back(kA * std::exp(-kB * x_.back()) + kC + noise * std::sin(1.7 * i + 0.3));
    }
  }
  int num_pixels() const override { return static_cast<int>(x_.size()); }

  bool chi2(const LmVector& p, double* chi2) override {
    ++chi2_calls;
    if (!valid(p)) {
      ++invalid_chi2_calls;
      return false;
    }
    double s = 0.0;
    for (std::size_t i = 0; i < x_.size(); ++i) {
      const double r = y_[i] - model(p, x_[i]);
      s += w_ * r * r;
    }
    *chi2 = s;
    return true;
  }

  bool normal_equations(const LmVector& p, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    ++normal_calls;
    if (!valid(p) || (fail_normal_equations && fail_normal_equations(normal_calls))) return false;
    alpha->setZero(3, 3);
    beta->setZero(3);
    double s = 0.0;
    for (std::size_t i = 0; i < x_.size(); ++i) {
      const double e = std::exp(-p[1] * x_[i]);
      LmVector j(3);
      j << e, -p[0] * x_[i] * e, 1.0;  // d model / d (a, b, c)
      const double r = y_[i] - model(p, x_[i]);
      s += w_ * r * r;
      *alpha += w_ * j * j.transpose();
      *beta += w_ * j * r;
    }
    *chi2 = s;
    return true;
  }

  static double model(const LmVector& p, double x) { return p[0] * std::exp(-p[1] * x) + p[2]; }

  // Optional "no model here" region and a hook that makes normal_equations fail on its k-th call.
  std::function<bool(const LmVector&)> invalid_region;
  std::function<bool(int)> fail_normal_equations;
  int chi2_calls = 0, invalid_chi2_calls = 0, normal_calls = 0;

 private:
  bool valid(const LmVector& p) const { return !(invalid_region && invalid_region(p)); }
  double w_;
  std::vector<double> x_, y_;
};

LmVector vec3(double a, double b, double c) {
  LmVector v(3);
  v << a, b, c;
  return v;
}

const LmVector kTruth = vec3(ExponentialProblem::kA, ExponentialProblem::kB, ExponentialProblem::kC);
const LmVector kPoorStart = vec3(1.0, 2.0, 0.0);

// Plain Gauss-Newton from the truth: an independent reference for the least-squares minimum of the
// perturbed problem (the minimum is within ~noise of the truth, where Gauss-Newton converges
// quadratically).
LmVector gauss_newton_minimum(ExponentialProblem& problem, LmMatrix* alpha_out, double* chi2_out) {
  LmVector p = kTruth;
  LmMatrix alpha;
  LmVector beta;
  double chi2 = 0;
  for (int it = 0; it < 50; ++it) {
    problem.normal_equations(p, &chi2, &alpha, &beta);
    p += alpha.ldlt().solve(beta);
  }
  problem.normal_equations(p, &chi2, &alpha, &beta);
  *alpha_out = alpha;
  *chi2_out = chi2;
  return p;
}

TEST(LevenbergMarquardt, ExactDataConvergesToTruthByChi2Rule) {
  // Exact data: chi2 -> 0, so eps3 is the rule that can fire. chi2 <= 1e-24 bounds the parameter
  // error by sqrt(1e-24 / lambda_min(alpha)) ~ 1e-11 (lambda_min ~ 0.01 here), far inside 1e-8.
  ExponentialProblem problem;
  LmOptions o;
  o.eps3 = 1e-24;
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  EXPECT_EQ(s.reason, StopReason::kChi2) << ToString(s.reason);
  EXPECT_TRUE(IsConverged(s.reason));
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.x[k], kTruth[k], 1e-8) << "parameter " << k;
  // The recorded rule: the tested chi2 and its threshold.
  EXPECT_EQ(s.stop_threshold, o.eps3);
  EXPECT_EQ(s.stop_value, s.chi2);
  EXPECT_LE(s.stop_value, s.stop_threshold);
  EXPECT_GT(s.initial_chi2, 1.0);  // the start really is poor
  EXPECT_GT(s.iterations, 3);
  EXPECT_GE(s.evaluations, s.iterations);
  EXPECT_LE(s.iterations, o.max_iterations);
  // Consistency of the reported chi2 with the returned parameters.
  double chi2 = 0;
  ASSERT_TRUE(problem.chi2(s.x, &chi2));
  EXPECT_EQ(chi2, s.chi2);
}

TEST(LevenbergMarquardt, Eps3FiresAtTheFirstPointBelowThreshold) {
  // A loose eps3 stops as soon as chi2 <= eps3, recording that chi2; the point before it was above.
  ExponentialProblem problem;
  LmOptions o;
  o.eps3 = 1e-3;
  o.eps4 = 0.0;
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  ASSERT_EQ(s.reason, StopReason::kChi2) << ToString(s.reason);
  EXPECT_EQ(s.stop_threshold, 1e-3);
  EXPECT_EQ(s.stop_value, s.chi2);
  EXPECT_LE(s.chi2, 1e-3);
  EXPECT_GT(s.chi2, 0.0);
  // Stopping earlier than the tight run: fewer iterations.
  LmOptions tight = o;
  tight.eps3 = 1e-24;
  ExponentialProblem again;
  EXPECT_LT(s.iterations, levenberg_marquardt(again, kPoorStart, tight).iterations);
  // eps3 above the starting chi2 fires before any step.
  ExponentialProblem third;
  LmOptions at_start;
  at_start.eps3 = 1e6;
  const LmSummary s0 = levenberg_marquardt(third, kPoorStart, at_start);
  EXPECT_EQ(s0.reason, StopReason::kChi2);
  EXPECT_EQ(s0.iterations, 1);
  EXPECT_EQ(s0.x, kPoorStart);
  EXPECT_EQ(s0.stop_value, s0.initial_chi2);
}

TEST(LevenbergMarquardt, NoisyDataConvergesByRelativeChi2Change) {
  // With residuals the minimum has chi2 > 0 and eps4 (default 1e-6 per pixel) is the rule that fires.
  ExponentialProblem problem(1e-2);
  const LmOptions o;
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  ASSERT_EQ(s.reason, StopReason::kRelativeChi2Change) << ToString(s.reason);
  EXPECT_TRUE(IsConverged(s.reason));
  const double threshold = o.eps4 / problem.num_pixels();
  EXPECT_DOUBLE_EQ(s.stop_threshold, threshold);
  EXPECT_LT(s.stop_value, s.stop_threshold);
  EXPECT_GE(s.stop_value, 0.0);

  ExponentialProblem reference_problem(1e-2);
  LmMatrix alpha;
  double chi2_min = 0;
  const LmVector p_min = gauss_newton_minimum(reference_problem, &alpha, &chi2_min);
  // The rule guarantees chi2 - chi2_min <~ threshold * chi2 (the undamped model's predicted gain at
  // the previous point, and the last step only lowered chi2); near the minimum chi2 - chi2_min =
  // dp^T alpha dp to second order, which bounds the parameter error in the metric that matters.
  // Factor 2 for the quadratic model's approximation.
  EXPECT_GE(s.chi2, chi2_min * (1 - 1e-14));
  EXPECT_LE(s.chi2 - chi2_min, 2.0 * threshold * s.chi2);
  const LmVector dp = s.x - p_min;
  EXPECT_LE(dp.dot(alpha * dp), 2.0 * threshold * s.chi2) << "dp = " << dp.transpose();
  // And the minimum itself lies near the truth (noise 1e-2).
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(p_min[k], kTruth[k], 0.1);
}

TEST(LevenbergMarquardt, StopAtJacobianEndsAtAJacobianPointThatPredictsNoMore) {
  // Started at the minimum, the rule holds at the first Jacobian point: no step, J^T W J at x.
  ExponentialProblem reference_problem(1e-2);
  LmMatrix alpha;
  double chi2_min = 0;
  const LmVector p_min = gauss_newton_minimum(reference_problem, &alpha, &chi2_min);
  LmOptions o;
  o.stop_at_jacobian = true;
  ExponentialProblem problem(1e-2);
  const LmSummary at = levenberg_marquardt(problem, p_min, o);
  EXPECT_EQ(at.reason, StopReason::kRelativeChi2Change);
  EXPECT_EQ(at.iterations, 1);
  EXPECT_EQ(at.evaluations, 1);
  EXPECT_TRUE(at.alpha_at_x);
  EXPECT_EQ(at.x, p_min);
  EXPECT_LT(at.stop_value, o.eps4 / problem.num_pixels());
  // From a poor start it takes steps, and where it stops the Gauss-Newton gain left is below the rule.
  ExponentialProblem far_problem(1e-2);
  const LmSummary far = levenberg_marquardt(far_problem, kPoorStart, o);
  ASSERT_EQ(far.reason, StopReason::kRelativeChi2Change);
  EXPECT_GT(far.iterations, 1);
  EXPECT_LE(far.chi2 - chi2_min, 2.0 * o.eps4 / far_problem.num_pixels() * far.chi2);
  // Without the rule the same start takes a step (and a Jacobian after it) before stopping.
  ExponentialProblem plain_problem(1e-2);
  const LmSummary plain = levenberg_marquardt(plain_problem, p_min, LmOptions{});
  EXPECT_GT(plain.evaluations, 1);
}

TEST(LevenbergMarquardt, InvariantToWeightScale) {
  // With Marquardt's scaling D = diag(alpha) the step, the gain ratio and every relative stopping test
  // are invariant to a common factor on the weights: the same path and the same recorded relative
  // chi2 change. Only rounding differs; the recorded rel (a difference of chi2 values ~1e-9 apart)
  // carries ~1e-7 relative rounding, so 1e-4.
  ExponentialProblem unit(1e-2, 24, 1.0), scaled(1e-2, 24, 1e8);
  const LmSummary a = levenberg_marquardt(unit, kPoorStart, LmOptions{});
  const LmSummary b = levenberg_marquardt(scaled, kPoorStart, LmOptions{});
  ASSERT_EQ(a.reason, StopReason::kRelativeChi2Change);
  ASSERT_EQ(b.reason, StopReason::kRelativeChi2Change);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.evaluations, b.evaluations);
  EXPECT_NEAR(b.chi2 / a.chi2, 1e8, 1e8 * 1e-10);
  EXPECT_NEAR(b.stop_value, a.stop_value, 1e-4 * a.stop_value);
  EXPECT_EQ(a.stop_threshold, b.stop_threshold);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(a.x[k], b.x[k], 1e-10);
}

// The exponential problem solved in rescaled units, x_stated = unit * x and chi2_stated = c * chi2,
// as engine/fit solves a stamp in units where its largest pixel is ~1.
class RescaledProblem : public LeastSquaresProblem {
 public:
  RescaledProblem(const LmVector& unit, double chi2_unit) : unit_(unit), c_(chi2_unit) {}
  int num_pixels() const override { return inner_.num_pixels(); }
  bool chi2(const LmVector& x, double* chi2) override {
    if (!inner_.chi2(x.cwiseProduct(unit_), chi2)) return false;
    *chi2 /= c_;
    return true;
  }
  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    if (!inner_.normal_equations(x.cwiseProduct(unit_), chi2, alpha, beta)) return false;
    *chi2 /= c_;
    *alpha = unit_.asDiagonal() * *alpha * unit_.asDiagonal() / c_;
    *beta = unit_.cwiseProduct(*beta) / c_;
    return true;
  }
  LmUnits units() const { return LmUnits{c_, unit_}; }

 private:
  ExponentialProblem inner_;
  LmVector unit_;
  double c_;
};

TEST(LevenbergMarquardt, AbsoluteRulesAreTestedInTheStatedUnits) {
  // eps1, eps2 and eps3 mean the same, and record the same values, whether the problem is solved
  // in the stated units or in rescaled ones described by LmUnits.
  const LmVector unit = vec3(1024.0, 1.0, 1.0 / 64);
  const double c = 4096.0;
  const LmVector start = kPoorStart.cwiseQuotient(unit);
  ExponentialProblem probe;
  double chi2 = 0;
  LmMatrix alpha;
  LmVector beta;
  probe.normal_equations(kPoorStart, &chi2, &alpha, &beta);
  LmOptions gradient, step, absolute;
  gradient.eps1 = 2.0 * beta.cwiseAbs().maxCoeff();
  step.eps2 = 0.9;
  absolute.eps3 = 1e-3;
  absolute.eps4 = 0.0;
  for (const LmOptions& o : {gradient, step, absolute}) {
    ExponentialProblem stated;
    RescaledProblem rescaled(unit, c);
    const LmSummary a = levenberg_marquardt(stated, kPoorStart, o);
    const LmSummary b = levenberg_marquardt(rescaled, start, o, rescaled.units());
    ASSERT_EQ(a.reason, b.reason) << ToString(a.reason) << " vs " << ToString(b.reason);
    EXPECT_EQ(a.iterations, b.iterations) << ToString(a.reason);
    EXPECT_NEAR(b.stop_value, a.stop_value, 1e-12 * a.stop_value) << ToString(a.reason);
    EXPECT_EQ(b.stop_threshold, a.stop_threshold);
    EXPECT_NEAR(b.chi2 * c, a.chi2, 1e-12 * a.chi2) << ToString(a.reason);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.x[k] * unit[k], a.x[k], 1e-10) << ToString(a.reason) << " parameter " << k;
  }
}

TEST(LevenbergMarquardt, Eps4ThresholdIsPerPixel) {
  // A loose eps4 = 0.2 over 24 pixels: the rule is rel < 0.2 / 24, not rel < 0.2. The recorded value
  // must be below the recorded per-pixel threshold.
  ExponentialProblem problem(1e-2);
  LmOptions o;
  o.eps4 = 0.2;
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  ASSERT_EQ(s.reason, StopReason::kRelativeChi2Change);
  EXPECT_DOUBLE_EQ(s.stop_threshold, 0.2 / 24);
  EXPECT_LT(s.stop_value, s.stop_threshold);
}

TEST(LevenbergMarquardt, HeavyDampingDoesNotTriggerEps4FarFromTheMinimum) {
  // init_mu = 1e8: the first steps are tiny gradient steps whose relative chi2 change is far below
  // eps4 / n_pixels although the start is far from the optimum. The eps4 rule must also ask the
  // undamped Gauss-Newton model, which still predicts a large gain, so the solve goes on to the truth.
  ExponentialProblem problem;
  LmOptions o;
  o.init_mu = 1e8;
  o.eps3 = 1e-24;
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  EXPECT_EQ(s.reason, StopReason::kChi2) << ToString(s.reason) << " after " << s.iterations << " iterations";
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.x[k], kTruth[k], 1e-8) << "parameter " << k;
}

TEST(LevenbergMarquardt, GradientRuleRecordsMaxBeta) {
  ExponentialProblem probe;
  double chi2 = 0;
  LmMatrix alpha;
  LmVector beta;
  probe.normal_equations(kPoorStart, &chi2, &alpha, &beta);
  const double grad0 = beta.cwiseAbs().maxCoeff();
  ExponentialProblem problem;
  LmOptions o;
  o.eps1 = 2.0 * grad0;  // satisfied at the start
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  EXPECT_EQ(s.reason, StopReason::kGradient);
  EXPECT_EQ(s.stop_value, grad0);
  EXPECT_EQ(s.stop_threshold, o.eps1);
  EXPECT_EQ(s.iterations, 1);
  EXPECT_EQ(s.x, kPoorStart);
  EXPECT_TRUE(s.alpha_at_x);
}

TEST(LevenbergMarquardt, RelativeStepRuleRecordsStepSize) {
  ExponentialProblem problem;
  LmOptions o;
  o.eps2 = 0.9;  // almost any step is "small": fires at the first proposed step
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  EXPECT_EQ(s.reason, StopReason::kRelativeStep);
  EXPECT_EQ(s.stop_threshold, 0.9);
  EXPECT_LE(s.stop_value, 0.9);
  EXPECT_GT(s.stop_value, 0.0);
  EXPECT_EQ(s.x, kPoorStart);  // the step is not taken
}

TEST(LevenbergMarquardt, MaxIterationsOne) {
  ExponentialProblem problem;
  LmOptions o;
  o.max_iterations = 1;
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  EXPECT_EQ(s.reason, StopReason::kMaxIterations);
  EXPECT_FALSE(IsConverged(s.reason));
  EXPECT_EQ(s.iterations, 1);
  EXPECT_EQ(s.stop_value, 1.0);
  EXPECT_EQ(s.stop_threshold, 1.0);
  // One accepted step was taken: the best point so far is better than the start, and alpha is from
  // the start, not from x.
  EXPECT_LT(s.chi2, s.initial_chi2);
  EXPECT_NE(s.x, kPoorStart);
  EXPECT_FALSE(s.alpha_at_x);
}

TEST(LevenbergMarquardt, InvalidStart) {
  {
    ExponentialProblem problem;
    problem.fail_normal_equations = [](int) { return true; };
    const LmSummary s = levenberg_marquardt(problem, kPoorStart, LmOptions{});
    EXPECT_EQ(s.reason, StopReason::kInvalidStart);
    EXPECT_FALSE(IsConverged(s.reason));
    EXPECT_EQ(s.evaluations, 1);
    EXPECT_EQ(problem.chi2_calls, 0);
    EXPECT_TRUE(std::isnan(s.initial_chi2));
  }
  {
    // A non-finite chi2 at the start is no model either.
    ExponentialProblem problem;
    const LmSummary s = levenberg_marquardt(problem, vec3(1.0, -1e6, 0.0), LmOptions{});
    EXPECT_EQ(s.reason, StopReason::kInvalidStart);
  }
}

TEST(LevenbergMarquardt, NormalEquationsFailingAfterAcceptedStepIsSingular) {
  ExponentialProblem problem;
  problem.fail_normal_equations = [](int call) { return call >= 2; };
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, LmOptions{});
  EXPECT_EQ(s.reason, StopReason::kSingular);
  EXPECT_FALSE(IsConverged(s.reason));
  EXPECT_EQ(problem.normal_calls, 2);
}

TEST(LevenbergMarquardt, NoValidStepIsNoProgress) {
  // Every trial point lies in the "no model" region: all steps are rejected until mu saturates.
  ExponentialProblem problem;
  const LmVector start = kPoorStart;
  problem.invalid_region = [start](const LmVector& p) { return p != start; };
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, LmOptions{});
  EXPECT_EQ(s.reason, StopReason::kNoProgress);
  EXPECT_EQ(s.x, kPoorStart);
  EXPECT_GE(s.stop_value, 1e30);
  EXPECT_EQ(s.stop_threshold, 1e30);
  EXPECT_EQ(s.chi2, s.initial_chi2);
  EXPECT_TRUE(s.alpha_at_x);
  EXPECT_GT(problem.invalid_chi2_calls, 5);
}

TEST(LevenbergMarquardt, ConvergesAroundAnOutOfRangeRegion) {
  // From the poor start the first undamped steps go to b ~ -4 (a growing exponential); declare
  // b < 0 "no model". Also declare a small box around the first trial point that the plain run
  // accepts, (a, b, c) = (1.105, 1.575, 0.034), so that an invalid point replaces an otherwise
  // downhill step. Neither region holds the start (1, 2, 0) or the truth (3, 0.7, 0.5). The solver
  // must reject those trial points like uphill steps and still reach the truth.
  LmOptions o;
  o.eps3 = 1e-24;
  ExponentialProblem plain;
  const LmSummary reference = levenberg_marquardt(plain, kPoorStart, o);
  ASSERT_EQ(reference.reason, StopReason::kChi2);

  ExponentialProblem problem;
  int box_hits = 0;
  problem.invalid_region = [&box_hits](const LmVector& p) {
    const bool in_box = std::abs(p[0] - 1.105) < 0.05 && std::abs(p[1] - 1.575) < 0.05 && std::abs(p[2] - 0.034) < 0.05;
    box_hits += in_box ? 1 : 0;
    return p[1] < 0.0 || in_box;
  };
  const LmSummary s = levenberg_marquardt(problem, kPoorStart, o);
  EXPECT_GT(problem.invalid_chi2_calls, box_hits) << "the b < 0 region was never visited; it tests nothing";
  EXPECT_GT(box_hits, 0) << "the box was never visited; it tests nothing";
  EXPECT_EQ(s.reason, StopReason::kChi2) << ToString(s.reason);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.x[k], kTruth[k], 1e-8) << "parameter " << k;
  EXPECT_GT(s.evaluations, reference.evaluations);  // the detour cost extra model evaluations
}

}  // namespace
}  // namespace stampede
