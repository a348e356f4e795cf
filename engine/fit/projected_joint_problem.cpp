// Joint fits with the amplitudes projected out; see projected_joint_problem.hpp.
#include "engine/fit/projected_joint_problem.hpp"

#include <cmath>
#include <stdexcept>

namespace stampede {

void ProjectedJointProblem::reset(std::span<const Observation> epochs, const ParamVector& base, std::span<const Param> free,
                                  std::span<const int> slot_of_cutout, int slots,
                                  const std::function<int(std::size_t, int)>& global, int n_global) {
  if (slots < 1 || slots > kMaxBands || slot_of_cutout.size() != epochs.size())
    throw std::invalid_argument("ProjectedJointProblem::reset: slots do not match the cutouts");
  epochs_ = epochs;
  cutouts_.reset(epochs);  // the units, pixels, the negligible chi2, the kernels' data
  base_ = cutouts_.units().to_internal(base);
  free_ = free;
  slot_of_cutout_.assign(slot_of_cutout.begin(), slot_of_cutout.end());
  slots_ = slots;
  n_global_ = n_global;
  n_shape_ = 0;
  bulge_ = disc_ = -1;
  for (std::size_t a = 0; a < free.size(); ++a) {
    if (free[a] == Param::kBulgeA)
      bulge_ = static_cast<int>(a);
    else if (free[a] == Param::kDiscA)
      disc_ = static_cast<int>(a);
    else
      shape_[static_cast<std::size_t>(n_shape_++)] = static_cast<int>(a);
    for (int s = 0; s < slots; ++s) global_[static_cast<std::size_t>(s)][a] = global(a, s);
  }
  if (bulge_ < 0 || disc_ < 0 || n_shape_ == 0)
    throw std::invalid_argument("ProjectedJointProblem::reset: needs both amplitudes and a shape parameter free");
  offset_.resize(epochs.size() + 1);
  offset_[0] = 0;
  for (std::size_t c = 0; c < epochs.size(); ++c) offset_[c + 1] = offset_[c] + 2 * epochs[c].pixels.size();
  if (components_.size() < offset_.back()) components_.resize(offset_.back());  // grows, then is reused
  cached_ = false;
  jacobian_x_ = LmVector();
}

ParamVector ProjectedJointProblem::params(const LmVector& x, const LinearAmplitudes& la) const {
  ParamVector p = base_;
  for (int j = 0; j < n_shape_; ++j) p[index(free_[static_cast<std::size_t>(shape_[static_cast<std::size_t>(j)])])] = x[j];
  p[index(Param::kBulgeA)] = la.a[0];
  p[index(Param::kDiscA)] = la.a[1];
  return p;
}

bool ProjectedJointProblem::chi2(const LmVector& x, double* chi2) {
  *chi2 = NAN;
  cached_ = false;
  const ParamVector p = params(x, LinearAmplitudes{});
  std::array<std::array<double, 4>, kMaxBands> g{};
  std::array<std::array<double, 2>, kMaxBands> h{};
  // The data and weights in the fit's units, as the kernels' (powers of two: exact).
  const double to_data = 1.0 / cutouts_.units().data, to_weight = 1.0 / cutouts_.units().weight;
  for (std::size_t c = 0; c < epochs_.size(); ++c) {
    const Observation& e = epochs_[c];
    const std::size_t n = e.pixels.size();
    double* b = components_.data() + offset_[c];
    double* d = b + n;
    if (cutouts_.select(c).render_components(p, {b, n}, {d, n}) != RenderStatus::kOk) return false;
    auto& gs = g[static_cast<std::size_t>(slot_of_cutout_[c])];
    auto& hs = h[static_cast<std::size_t>(slot_of_cutout_[c])];
    const double s = e.flux_scale;
    for (std::size_t i = 0; i < n; ++i) {
      b[i] *= s;
      d[i] *= s;
      if (e.weight[i] == 0) continue;
      const double w = e.weight[i] * to_weight, data = e.pixels[i] * to_data;
      const double wb = w * b[i], wd = w * d[i];
      gs[0] += wb * b[i];
      gs[1] += wb * d[i];
      gs[3] += wd * d[i];
      hs[0] += wb * data;
      hs[1] += wd * data;
    }
  }
  for (int s = 0; s < slots_; ++s) {
    auto& gs = g[static_cast<std::size_t>(s)];
    gs[2] = gs[1];
    if (!solve_linear_amplitudes(gs.data(), h[static_cast<std::size_t>(s)].data(), &amplitudes_[static_cast<std::size_t>(s)]))
      return false;
  }
  double sum = 0;
  for (std::size_t c = 0; c < epochs_.size(); ++c) {
    const Observation& e = epochs_[c];
    const std::size_t n = e.pixels.size();
    const double* b = components_.data() + offset_[c];
    const double* d = b + n;
    const LinearAmplitudes& la = amplitudes_[static_cast<std::size_t>(slot_of_cutout_[c])];
    for (std::size_t i = 0; i < n; ++i) {
      if (e.weight[i] == 0) continue;
      const double w = e.weight[i] * to_weight;
      const double r = e.pixels[i] * to_data - (la.a[0] * b[i] + la.a[1] * d[i]);
      sum += w * r * r;
    }
  }
  *chi2 = sum;
  cached_x_ = x;
  cached_ = std::isfinite(sum);
  return cached_;
}

bool ProjectedJointProblem::normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) {
  *chi2 = NAN;
  if (!(cached_ && cached_x_ == x)) {  // the amplitudes at x (the solver's first point)
    double c;
    if (!this->chi2(x, &c)) return false;
  }
  jacobian_x_ = LmVector();  // set again below once this point's sums are complete
  jacobian_amplitudes_ = amplitudes_;
  const int nf = static_cast<int>(free_.size());
  // Each slot's unprojected sums over its cutouts, lower triangle (every free parameter, local).
  std::array<LmMatrix, kMaxBands> m;
  std::array<LmVector, kMaxBands> v;
  for (int s = 0; s < slots_; ++s) {
    m[static_cast<std::size_t>(s)].setZero(nf, nf);
    v[static_cast<std::size_t>(s)].setZero(nf);
  }
  signal_.fill(0.0);
  double sum = 0;
  for (std::size_t c = 0; c < epochs_.size(); ++c) {
    const std::size_t slot = static_cast<std::size_t>(slot_of_cutout_[c]);
    if (!cutouts_.sums(c, params(x, jacobian_amplitudes_[slot]), free_, &sums_)) return false;
    LmMatrix& ms = m[slot];
    LmVector& vs = v[slot];
    for (int a = 0; a < nf; ++a) {
      vs[a] += sums_.beta[static_cast<std::size_t>(a)];
      for (int b = 0; b < nf; ++b) ms(a, b) += sums_.alpha[static_cast<std::size_t>(a * nf + b)];
    }
    sum += sums_.chi2;
    signal_[slot] += sums_.signal;
  }
  full_alpha_.setZero(n_global_, n_global_);
  alpha->setZero(n_shape_, n_shape_);
  beta->setZero(n_shape_);
  for (int s = 0; s < slots_; ++s) {
    const LmMatrix& ms = m[static_cast<std::size_t>(s)];
    const auto& gl = global_[static_cast<std::size_t>(s)];
    for (int a = 0; a < nf; ++a)
      for (int b = 0; b < nf; ++b) full_alpha_(gl[static_cast<std::size_t>(a)], gl[static_cast<std::size_t>(b)]) += ms(a, b);
    // T = G^-1 Phi^T W X (2 x n_shape), G^-1 the one the amplitudes were solved with.
    const LinearAmplitudes& la = jacobian_amplitudes_[static_cast<std::size_t>(s)];
    const std::array<int, 2> amp = {bulge_, disc_};
    double t[2][kNumParams];
    for (int j = 0; j < n_shape_; ++j) {
      const int sj = shape_[static_cast<std::size_t>(j)];
      for (int u = 0; u < 2; ++u) t[u][j] = la.ginv[u][0] * ms(amp[0], sj) + la.ginv[u][1] * ms(amp[1], sj);
    }
    const LmVector& vs = v[static_cast<std::size_t>(s)];
    for (int j = 0; j < n_shape_; ++j) {
      const int sj = shape_[static_cast<std::size_t>(j)];
      (*beta)[j] += vs[sj] - t[0][j] * vs[amp[0]] - t[1][j] * vs[amp[1]];
      for (int k = 0; k < n_shape_; ++k) {
        const int sk = shape_[static_cast<std::size_t>(k)];
        double a = ms(sj, sk);
        for (int u = 0; u < 2; ++u) {
          a -= ms(sj, amp[u]) * t[u][k] + t[u][j] * ms(amp[u], sk);
          for (int w = 0; w < 2; ++w) a += t[u][j] * ms(amp[u], amp[w]) * t[w][k];
        }
        (*alpha)(j, k) += a;
      }
    }
  }
  *chi2 = sum;
  if (!(std::isfinite(sum) && alpha->allFinite() && beta->allFinite())) return false;
  jacobian_x_ = x;
  return true;
}

LmVector ProjectedJointProblem::shape_of(const LmVector& global) const {
  LmVector x(n_shape_);
  for (int j = 0; j < n_shape_; ++j) x[j] = global[global_[0][static_cast<std::size_t>(shape_[static_cast<std::size_t>(j)])]];
  return x;
}

bool ProjectedJointProblem::expand(LmVector* x, LmMatrix* alpha) {
  if (!(jacobian_x_.size() == x->size() && jacobian_x_ == *x)) {  // the solver's last Jacobian was elsewhere
    double c;
    LmMatrix a;
    LmVector b;
    if (!normal_equations(*x, &c, &a, &b)) return false;
  }
  LmVector out(n_global_);
  for (int s = 0; s < slots_; ++s) {
    const auto& gl = global_[static_cast<std::size_t>(s)];
    for (int j = 0; j < n_shape_; ++j) out[gl[static_cast<std::size_t>(shape_[static_cast<std::size_t>(j)])]] = (*x)[j];
    out[gl[static_cast<std::size_t>(bulge_)]] = jacobian_amplitudes_[static_cast<std::size_t>(s)].a[0];
    out[gl[static_cast<std::size_t>(disc_)]] = jacobian_amplitudes_[static_cast<std::size_t>(s)].a[1];
  }
  *x = out;
  *alpha = full_alpha_;
  return true;
}

}  // namespace stampede
