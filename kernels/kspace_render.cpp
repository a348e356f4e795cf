// The exact renderer's term loop: the transform table and the dispatcher over the
// per-instruction-set builds; see kspace_render.hpp. The loop itself is in kspace_render_impl.hpp.
#include "kernels/kspace_render.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "kernels/isa_dispatch.hpp"
#include "kernels/kspace_render_isa.hpp"

namespace stampede::kernels {

SersicKTable::SersicKTable(const LogGrid& grid, const std::vector<double>& values) {
  constexpr int kPoints = kCoefficients;
  const int count = static_cast<int>(values.size());
  if (count < kPoints || count != grid.count) throw std::invalid_argument("SersicKTable: values do not match the grid");
  log_q_min = std::log(grid.q_min);
  inv_step = grid.nodes_per_decade / std::numbers::ln10;
  intervals = count - 1;
  w_min = grid.q_min * grid.q_min;
  c2 = (1 - values[0]) / w_min;
  q_max_ = grid.node(count - 1);
  w_max = q_max_ * q_max_;
  log_q_max = std::log(q_max_);
  // The tail of LogTable: the power law through the last two nodes, or 0.
  const double last = values[count - 1], before = values[count - 2];
  if (last != 0 && before != 0 && (last > 0) == (before > 0)) {
    tail_value = last;
    tail_slope = std::log(last / before) * inv_step;
  }
  for (auto& c : coefficients) c.assign(static_cast<std::size_t>(intervals), 0.0);
  // Interval i, t in [i, i + 1): LogTable's window of nodes st .. st + 5 (st = clamp(i - 2)), its
  // Lagrange interpolant expanded in u = t - i (s = u + d, d = i - st) into monomials.
  constexpr double kInvDenominator[6] = {-1.0 / 120, 1.0 / 24, -1.0 / 12, 1.0 / 12, -1.0 / 24, 1.0 / 120};
  for (int i = 0; i < intervals; ++i) {
    const int st = std::clamp(i - (kPoints / 2 - 1), 0, count - kPoints);
    const double d = i - st;
    double poly[kPoints] = {};
    for (int j = 0; j < kPoints; ++j) {
      double basis[kPoints] = {1.0};  // prod_{m != j} (u + d - m), built one factor at a time
      int degree = 0;
      for (int m = 0; m < kPoints; ++m) {
        if (m == j) continue;
        const double a = d - m;  // factor (u + a)
        for (int p = degree + 1; p >= 1; --p) basis[p] = basis[p - 1] + a * basis[p];
        basis[0] *= a;
        ++degree;
      }
      const double scale = kInvDenominator[j] * values[static_cast<std::size_t>(st + j)];
      for (int p = 0; p < kPoints; ++p) poly[p] += scale * basis[p];
    }
    for (int p = 0; p < kPoints; ++p) coefficients[static_cast<std::size_t>(p)][static_cast<std::size_t>(i)] = poly[p];
  }
}

void SersicKTable::evaluate(double w, double* value, double* slope_w) const {
  if (w < w_min) {
    *value = 1 - c2 * w;
    *slope_w = -c2;
    return;
  }
  const double half_log_w = 0.5 * std::log(w);
  if (w >= w_max) {
    *value = tail_value * std::exp(tail_slope * (half_log_w - log_q_max));
    *slope_w = *value * 0.5 * tail_slope / w;
    return;
  }
  const double t = std::min((half_log_w - log_q_min) * inv_step, intervals - 1e-12);
  const int i = static_cast<int>(t);
  const double u = t - i;
  double v = 0, dv = 0;
  for (int p = kCoefficients - 1; p >= 0; --p) {
    dv = dv * u + v;
    v = v * u + coefficients[static_cast<std::size_t>(p)][static_cast<std::size_t>(i)];
  }
  *value = v;
  *slope_w = dv * 0.5 * inv_step / w;
}

namespace {

const IsaDispatch<KSpaceKernels>& table() {
  static const IsaDispatch<KSpaceKernels> t(  // immutable after its thread-safe initialisation
      kspace_kernels_scalar, STAMPEDE_SSE42_ENTRY(kspace_kernels_sse42), STAMPEDE_AVX2_ENTRY(kspace_kernels_avx2),
      STAMPEDE_AVX512_ENTRY(kspace_kernels_avx512));
  return t;
}

}  // namespace

const KSpaceKernels* kspace_kernels_for(Isa isa) { return table().find(isa); }

const KSpaceKernels& kspace_kernels(Isa isa) { return table().get(isa); }

}  // namespace stampede::kernels
