// Tests kernels/least_squares: chi^2 and the normal equations against a naive dense Eigen
// computation (J^T W J, J^T W r) on random data, masked (zero-weight) pixels included, for every
// instruction set this machine runs.
#include "kernels/least_squares.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace stampede::kernels {
namespace {

struct Problem {
  std::vector<double> data, model, weight;
  std::vector<std::vector<double>> columns;
  std::vector<const double*> column_ptrs;
};

Problem random_problem(int npix, int ncol, unsigned seed, double masked_fraction) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0), w(0.1, 4.0), coin(0.0, 1.0);
  Problem p;
  p.data.resize(npix);
  p.model.resize(npix);
  p.weight.resize(npix);
  p.columns.assign(ncol, std::vector<double>(npix));
  for (int i = 0; i < npix; ++i) {
    p.data[i] = 10.0 + u(rng);
    p.model[i] = 10.0 + u(rng);
    p.weight[i] = coin(rng) < masked_fraction ? 0.0 : w(rng);
    for (int k = 0; k < ncol; ++k) p.columns[k][i] = u(rng) * (k + 1);
  }
  for (const auto& c : p.columns) p.column_ptrs.push_back(c.data());
  return p;
}

Eigen::MatrixXd jacobian(const Problem& p) {
  const int npix = static_cast<int>(p.data.size()), ncol = static_cast<int>(p.columns.size());
  Eigen::MatrixXd j(npix, ncol);
  for (int k = 0; k < ncol; ++k)
    for (int i = 0; i < npix; ++i) j(i, k) = p.columns[k][i];
  return j;
}

// Sums of n ~ 1e3 products of O(10) terms: relative error ~ sqrt(n) eps in each, 1e-12 of the
// largest entry leaves room for the different summation orders of the kernel and Eigen.
constexpr double kRel = 1e-12;

TEST(WeightedChi2, MatchesNaiveSum) {
  for (double masked : {0.0, 0.3}) {
    const Problem p = random_problem(1521, 1, 7u, masked);
    const Eigen::Map<const Eigen::VectorXd> d(p.data.data(), p.data.size()), m(p.model.data(), p.model.size()),
        w(p.weight.data(), p.weight.size());
    const double expected = (w.array() * (d - m).array().square()).sum();
    EXPECT_NEAR(weighted_chi2(p.data, p.model, p.weight), expected, kRel * expected);
  }
}

TEST(WeightedChi2, KnownSmallCase) {
  const std::vector<double> d{1.0, 2.0, 3.0}, m{0.5, 2.0, 5.0}, w{4.0, 9.0, 0.25};
  EXPECT_DOUBLE_EQ(weighted_chi2(d, m, w), 4.0 * 0.25 + 0.0 + 0.25 * 4.0);
}

TEST(WeightedChi2, ZeroWeightPixelsContributeNothing) {
  // A masked pixel may hold a non-finite value (Fitter::prepare_weights accepts NaN / Inf under zero
  // weight, and accumulate_normal_equations skips w == 0). weighted_chi2 must agree with the normal
  // equations' chi2 there, or the solver's trial evaluations disagree with its Jacobian evaluations.
  const int ncol = 2;
  Problem p = random_problem(400, ncol, 11u, 0.2);
  std::vector<double> alpha(ncol * ncol), beta(ncol);
  const double clean = weighted_chi2(p.data, p.model, p.weight);
  int poisoned = 0;
  for (std::size_t i = 0; i < p.data.size(); ++i) {
    if (p.weight[i] == 0.0) {
      p.data[i] = (poisoned++ % 2) ? NAN : INFINITY;
    }
  }
  ASSERT_GT(poisoned, 0);
  const double normal = accumulate_normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), ncol,
                                                    alpha.data(), beta.data());
  EXPECT_NEAR(normal, clean, kRel * clean);
  // Were a NaN under zero weight to reach the sum (0 * NaN = NaN), every trial step of such a stamp
  // would read chi2 = NaN and be rejected, ending the fit at its starting point.
  EXPECT_NEAR(weighted_chi2(p.data, p.model, p.weight), clean, kRel * clean);
}

TEST(AccumulateNormalEquations, MatchesNaiveEigen) {
  for (int ncol : {1, 3, 7, 12}) {
    for (double masked : {0.0, 0.25}) {
      const Problem p = random_problem(1200, ncol, 100u + ncol, masked);
      std::vector<double> alpha(ncol * ncol, NAN), beta(ncol, NAN);  // must be overwritten
      const double chi2 = accumulate_normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), ncol,
                                                      alpha.data(), beta.data());
      const Eigen::MatrixXd j = jacobian(p);
      const Eigen::Map<const Eigen::VectorXd> d(p.data.data(), p.data.size()), m(p.model.data(), p.model.size()),
          w(p.weight.data(), p.weight.size());
      const Eigen::VectorXd r = d - m;
      const Eigen::MatrixXd a_ref = j.transpose() * w.asDiagonal() * j;
      const Eigen::VectorXd b_ref = j.transpose() * w.asDiagonal() * r;
      const double chi2_ref = r.dot(w.asDiagonal() * r);
      EXPECT_NEAR(chi2, chi2_ref, kRel * chi2_ref);
      EXPECT_NEAR(chi2, weighted_chi2(p.data, p.model, p.weight), kRel * chi2_ref);
      const double a_scale = a_ref.cwiseAbs().maxCoeff(), b_scale = b_ref.cwiseAbs().maxCoeff();
      for (int k = 0; k < ncol; ++k) {
        EXPECT_NEAR(beta[k], b_ref[k], kRel * b_scale * 10) << "ncol " << ncol << " k " << k;
        for (int l = 0; l < ncol; ++l) {
          EXPECT_NEAR(alpha[k * ncol + l], a_ref(k, l), kRel * a_scale) << "ncol " << ncol << " (" << k << ", " << l << ")";
          EXPECT_EQ(alpha[k * ncol + l], alpha[l * ncol + k]) << "alpha must be exactly symmetric";
        }
      }
    }
  }
}

std::vector<const LeastSquaresKernels*> every_set() {
  std::vector<const LeastSquaresKernels*> out;
  for (Isa isa : {Isa::kScalar, Isa::kSse42, Isa::kAvx2, Isa::kAvx512})
    if (const LeastSquaresKernels* k = least_squares_kernels_for(isa)) out.push_back(k);
  return out;
}

TEST(AccumulateNormalEquations, ZeroWeightPixelsContributeNothing) {
  // Masked pixels may hold garbage (non-finite data, model or derivative values): they must add
  // exactly +0 to every sum, so the result is bitwise that of the same problem with zeros there,
  // and equals the computation on the unmasked pixels alone up to the summation order. Finite
  // garbage stays on the kernels' unmasked first pass (its products with w = 0 are ±0); non-finite
  // garbage sends them to the masked second pass: both must give the zeros' bits.
  const int ncol = 4;
  const Problem p = random_problem(501, ncol, 5u, 0.3);  // odd: every set has a tail
  Problem garbage = p, finite_garbage = p, zeros = p, kept;
  kept.columns.assign(ncol, {});
  for (std::size_t i = 0; i < p.data.size(); ++i) {
    if (p.weight[i] != 0.0) {
      kept.data.push_back(p.data[i]);
      kept.model.push_back(p.model[i]);
      kept.weight.push_back(p.weight[i]);
      for (int k = 0; k < ncol; ++k) kept.columns[k].push_back(p.columns[k][i]);
    } else {
      garbage.data[i] = (i % 3) ? NAN : -INFINITY;
      garbage.model[i] = 1e300;
      finite_garbage.data[i] = (i % 2) ? 1e150 : -1e150;
      finite_garbage.model[i] = -3.0;
      zeros.data[i] = zeros.model[i] = 0.0;
      for (int k = 0; k < ncol; ++k) {
        garbage.columns[k][i] = (k % 2) ? NAN : INFINITY;
        finite_garbage.columns[k][i] = (k % 2) ? -1e200 : 1e200;
        zeros.columns[k][i] = 0.0;
      }
    }
  }
  for (Problem* q : {&garbage, &finite_garbage, &zeros, &kept}) {
    q->column_ptrs.clear();
    for (const auto& c : q->columns) q->column_ptrs.push_back(c.data());
  }
  ASSERT_LT(kept.data.size(), p.data.size());
  for (const LeastSquaresKernels* k : every_set()) {
    SCOPED_TRACE(k->name);
    std::vector<double> a1(ncol * ncol), b1(ncol), a2(ncol * ncol), b2(ncol), a3(ncol * ncol), b3(ncol);
    const double c1 = k->normal_equations(garbage.data, garbage.model, garbage.weight, garbage.column_ptrs.data(), ncol,
                                          a1.data(), b1.data());
    const double c2 = k->normal_equations(zeros.data, zeros.model, zeros.weight, zeros.column_ptrs.data(), ncol,
                                          a2.data(), b2.data());
    const double c3 =
        k->normal_equations(kept.data, kept.model, kept.weight, kept.column_ptrs.data(), ncol, a3.data(), b3.data());
    std::vector<double> a4(ncol * ncol), b4(ncol);
    const double c4 = k->normal_equations(finite_garbage.data, finite_garbage.model, finite_garbage.weight,
                                          finite_garbage.column_ptrs.data(), ncol, a4.data(), b4.data());
    EXPECT_EQ(c1, c2);
    EXPECT_EQ(c4, c2);
    EXPECT_EQ(c1, k->weighted_chi2(garbage.data, garbage.model, garbage.weight));
    EXPECT_EQ(c4, k->weighted_chi2(finite_garbage.data, finite_garbage.model, finite_garbage.weight));
    EXPECT_NEAR(c1, c3, kRel * c3);
    for (int j = 0; j < ncol; ++j) {
      EXPECT_EQ(b1[j], b2[j]);
      EXPECT_EQ(b4[j], b2[j]);
      EXPECT_NEAR(b1[j], b3[j], kRel * 10 * std::abs(b3[j]) + 1e-12);
    }
    for (int j = 0; j < ncol * ncol; ++j) {
      EXPECT_EQ(a1[j], a2[j]);
      EXPECT_EQ(a4[j], a2[j]);
      EXPECT_NEAR(a1[j], a3[j], kRel * std::abs(a3[j]));
    }
  }
}

TEST(LeastSquaresIsa, EverySetMatchesNaiveEigenAndTheScalarReference) {
  const LeastSquaresKernels& ref = *least_squares_kernels_for(Isa::kScalar);
  for (const LeastSquaresKernels* k : every_set()) {
    SCOPED_TRACE(k->name);
    for (int npix : {1, 7, 1521}) {
      for (int ncol : {1, 2, 7, 12, 16}) {
        const Problem p = random_problem(npix, ncol, 31u * npix + ncol, 0.2);
        std::vector<double> alpha(ncol * ncol, NAN), beta(ncol, NAN), alpha_ref(ncol * ncol), beta_ref(ncol);
        const double chi2 = k->normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), ncol, alpha.data(),
                                                beta.data());
        const double chi2_ref = ref.normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), ncol,
                                                     alpha_ref.data(), beta_ref.data());
        const Eigen::MatrixXd j = jacobian(p);
        const Eigen::Map<const Eigen::VectorXd> d(p.data.data(), npix), m(p.model.data(), npix), w(p.weight.data(), npix);
        const Eigen::VectorXd r = d - m;
        const Eigen::MatrixXd a_eigen = j.transpose() * w.asDiagonal() * j;
        const Eigen::VectorXd b_eigen = j.transpose() * w.asDiagonal() * r;
        const double chi2_eigen = r.dot(w.asDiagonal() * r);
        const double a_scale = a_eigen.cwiseAbs().maxCoeff() + 1e-300, b_scale = b_eigen.cwiseAbs().maxCoeff() + 1e-300;
        EXPECT_NEAR(chi2, chi2_eigen, kRel * chi2_eigen);
        EXPECT_NEAR(chi2, chi2_ref, kRel * chi2_ref);
        EXPECT_NEAR(k->weighted_chi2(p.data, p.model, p.weight), chi2_eigen, kRel * chi2_eigen);
        for (int a = 0; a < ncol; ++a) {
          EXPECT_NEAR(beta[a], b_eigen[a], kRel * 10 * b_scale) << "npix " << npix << " ncol " << ncol;
          EXPECT_NEAR(beta[a], beta_ref[a], kRel * 10 * b_scale);
          for (int b = 0; b < ncol; ++b) {
            EXPECT_NEAR(alpha[a * ncol + b], a_eigen(a, b), kRel * a_scale) << "npix " << npix << " ncol " << ncol;
            EXPECT_NEAR(alpha[a * ncol + b], alpha_ref[a * ncol + b], kRel * a_scale);
            EXPECT_EQ(alpha[a * ncol + b], alpha[b * ncol + a]) << "alpha must be exactly symmetric";
          }
        }
      }
    }
  }
}

TEST(AccumulateNormalEquations, RejectsTooManyColumns) {
  const Problem p = random_problem(10, kMaxLeastSquaresColumns + 1, 1u, 0.0);
  std::vector<double> alpha(p.columns.size() * p.columns.size()), beta(p.columns.size());
  EXPECT_THROW(accumulate_normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(),
                                           kMaxLeastSquaresColumns + 1, alpha.data(), beta.data()),
               std::invalid_argument);
}

TEST(AccumulateNormalEquations, PerfectModelHasZeroChi2AndBeta) {
  const int ncol = 3;
  Problem p = random_problem(300, ncol, 3u, 0.1);
  p.model = p.data;
  std::vector<double> alpha(ncol * ncol), beta(ncol, 1.0);
  EXPECT_EQ(accumulate_normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), ncol, alpha.data(), beta.data()),
            0.0);
  for (double b : beta) EXPECT_EQ(b, 0.0);
  // alpha = J^T W J is still positive definite.
  Eigen::Map<Eigen::Matrix3d> a(alpha.data());
  EXPECT_EQ(Eigen::LLT<Eigen::Matrix3d>(a).info(), Eigen::Success);
}

}  // namespace
}  // namespace stampede::kernels
