// Tests kernels/least_squares: chi^2 and the normal equations against a naive dense Eigen
// computation (J^T W J, J^T W r) on random data, masked (zero-weight) pixels included.
#include "kernels/least_squares.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
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
  // KNOWN BUG (kernels/least_squares.cpp, weighted_chi2): it computes w * (d - m)^2 for every pixel,
  // so 0 * NaN = NaN and 0 * Inf^2 = NaN poison the sum, while accumulate_normal_equations skips
  // w == 0. In the fitter every trial step of a stamp with a non-finite masked pixel then reads
  // chi2 = NaN, is rejected, and the fit ends as kNoProgress ("converged", status kOk) at the
  // starting point. This assertion fails until weighted_chi2 skips zero-weight pixels.
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

TEST(AccumulateNormalEquations, ZeroWeightPixelsContributeNothing) {
  // Masked pixels may hold garbage (non-finite model or derivative values): the result must equal
  // the computation on the unmasked pixels alone.
  const int ncol = 4;
  Problem p = random_problem(500, ncol, 5u, 0.3);
  Problem kept;
  kept.columns.assign(ncol, {});
  for (std::size_t i = 0; i < p.data.size(); ++i) {
    if (p.weight[i] != 0.0) {
      kept.data.push_back(p.data[i]);
      kept.model.push_back(p.model[i]);
      kept.weight.push_back(p.weight[i]);
      for (int k = 0; k < ncol; ++k) kept.columns[k].push_back(p.columns[k][i]);
    } else {
      p.model[i] = 1e300;
      for (int k = 0; k < ncol; ++k) p.columns[k][i] = (k % 2) ? NAN : INFINITY;
    }
  }
  for (const auto& c : kept.columns) kept.column_ptrs.push_back(c.data());
  ASSERT_LT(kept.data.size(), p.data.size());
  std::vector<double> a1(ncol * ncol), b1(ncol), a2(ncol * ncol), b2(ncol);
  const double c1 = accumulate_normal_equations(p.data, p.model, p.weight, p.column_ptrs.data(), ncol, a1.data(), b1.data());
  const double c2 =
      accumulate_normal_equations(kept.data, kept.model, kept.weight, kept.column_ptrs.data(), ncol, a2.data(), b2.data());
  // Same terms in the same order: identical.
  EXPECT_EQ(c1, c2);
  for (int k = 0; k < ncol; ++k) EXPECT_EQ(b1[k], b2[k]);
  for (int k = 0; k < ncol * ncol; ++k) EXPECT_EQ(a1[k], a2[k]);
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
