// The exact renderer's term loop: the transform table and the dispatcher over the
// per-instruction-set builds; see kspace_render.hpp. The loop itself is in kspace_render_impl.hpp.
#include "kernels/kspace_render.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "kernels/isa_dispatch.hpp"
#include "kernels/kspace_render_isa.hpp"

namespace stampede::kernels {

namespace {

constexpr std::uint64_t kExponentBits = 0x7FF0000000000000ULL;
constexpr std::uint64_t kMantissaBits = 0x000FFFFFFFFFFFFFULL;
constexpr std::uint64_t kOneBits = 0x3FF0000000000000ULL;

// 2^e as a double (e within the normal range).
double power_of_two(int e) { return std::ldexp(1.0, e); }

}  // namespace

SersicKTable::SersicKTable(const LogGrid& grid, const std::vector<double>& values) {
  const int count = static_cast<int>(values.size());
  if (count < kCoefficients || count != grid.count)
    throw std::invalid_argument("SersicKTable: values do not match the grid");
  const LogTable reference(grid, values);
  q_max_ = grid.node(count - 1);
  const double w_min = grid.q_min * grid.q_min;
  c2 = (1 - values[0]) / w_min;  // LogTable's series below q_min
  // Whole octaves of w from the one holding q_min^2 to the last one below q_max^2.
  const int e_lo = std::ilogb(w_min), e_hi = std::ilogb(q_max_ * q_max_);
  if (e_hi <= e_lo) throw std::invalid_argument("SersicKTable: the grid spans less than an octave of q^2");
  w_lo = power_of_two(e_lo);
  w_hi = power_of_two(e_hi);
  w_last = std::nextafter(w_hi, 0.0);
  log_w_hi = std::log(w_hi);
  intervals = (e_hi - e_lo) * kSubdivisions;
  index_base = static_cast<std::int64_t>(std::bit_cast<std::uint64_t>(w_lo) >> kIndexShift);
  coefficients.assign(static_cast<std::size_t>(intervals) * kStride, 0.0);
  // Per interval: the reference at six Chebyshev points of u, Newton's divided differences, then
  // the monomial coefficients in u (degree 5 on [0, 1]: well conditioned).
  constexpr int kN = kCoefficients;
  double nodes[kN];
  for (int m = 0; m < kN; ++m) nodes[m] = 0.5 - 0.5 * std::cos(std::numbers::pi * (2 * m + 1) / (2 * kN));
  for (int i = 0; i < intervals; ++i) {
    const int e = e_lo + i / kSubdivisions, j = i % kSubdivisions;
    const double w0 = power_of_two(e) * (1.0 + static_cast<double>(j) / kSubdivisions);
    const double width = power_of_two(e) / kSubdivisions;
    double dd[kN];
    for (int m = 0; m < kN; ++m) dd[m] = reference(std::sqrt(w0 + nodes[m] * width));
    for (int level = 1; level < kN; ++level)
      for (int m = kN - 1; m >= level; --m) dd[m] = (dd[m] - dd[m - 1]) / (nodes[m] - nodes[m - level]);
    // Newton form sum_m dd[m] prod_{l < m} (u - nodes[l]) expanded by Horner from the top.
    double poly[kN] = {};
    poly[0] = dd[kN - 1];
    for (int m = kN - 2; m >= 0; --m) {
      // poly = poly * (u - nodes[m]) + dd[m]
      for (int p = kN - 1; p >= 1; --p) poly[p] = poly[p - 1] - nodes[m] * poly[p];
      poly[0] = -nodes[m] * poly[0] + dd[m];
    }
    for (int p = 0; p < kN; ++p) coefficients[static_cast<std::size_t>(i) * kStride + p] = poly[p];
  }
  // The tail: LogTable's power law (through the last two nodes), anchored at the table's end.
  const double last = values[count - 1], before = values[count - 2];
  if (last != 0 && before != 0 && (last > 0) == (before > 0)) {
    tail_value = reference(std::sqrt(w_hi));
    tail_slope = std::log(last / before) * grid.nodes_per_decade / std::numbers::ln10;
  }
}

void SersicKTable::evaluate(double w, double* value, double* slope_w) const {
  if (w < w_lo) {
    *value = 1 - c2 * w;
    *slope_w = -c2;
    return;
  }
  if (w >= w_hi) {
    *value = tail_value * std::exp(0.5 * tail_slope * (std::log(w) - log_w_hi));
    *slope_w = *value * 0.5 * tail_slope / w;
    return;
  }
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(w);
  const std::int64_t i = static_cast<std::int64_t>(bits >> kIndexShift) - index_base;
  const double u = std::bit_cast<double>(((bits << kSubdivisionBits) & kMantissaBits) | kOneBits) - 1.0;
  const double inv_octave = std::bit_cast<double>(0x7FE0000000000000ULL - (bits & kExponentBits));  // 2^-e
  const double* c = coefficients.data() + static_cast<std::size_t>(i) * kStride;
  double v = 0, dv = 0;
  for (int p = kCoefficients - 1; p >= 0; --p) {
    dv = dv * u + v;
    v = v * u + c[p];
  }
  *value = v;
  *slope_w = dv * (kSubdivisions * inv_octave);
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
