// The periodic copies' light on the stamp; see wrapped_wings.hpp.
#include "kernels/wrapped_wings.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "kernels/isa_dispatch.hpp"
#include "kernels/wrapped_wings_isa.hpp"

namespace stampede::kernels {
namespace {

constexpr double kMaxBlur = 2.4495;  // sqrt(6): the saturated blur's bound, see wrapped_wings_impl.hpp

double root_of(const WingComponent& c, double u) {
  switch (c.root) {
    case SersicRoot::kSquareRoot: return std::sqrt(u);
    case SersicRoot::kEighthRoot: return std::sqrt(std::sqrt(std::sqrt(u)));
    case SersicRoot::kGeneralPow: break;
  }
  return std::pow(u, c.s);
}

}  // namespace

void significant_copies(const WingComponent& c, int period, int size, int max_rings, double floor,
                        std::vector<CopyOffset>* out) {
  out->clear();
  const EllipseQuadratic& q = c.q;
  // u >= lambda_min(Q) d^2 at distance d from the centre.
  const double lambda = 0.5 * (q.xx + q.yy) - std::hypot(0.5 * (q.xx - q.yy), q.xy);
  if (!(lambda > 0)) return;
  const double hi = size - 1.0;
  for (int ring = 1; ring <= max_rings; ++ring) {
    bool any = false;
    for (int j = -ring; j <= ring; ++j)
      for (int i = -ring; i <= ring; ++i) {
        if (std::max(std::abs(i), std::abs(j)) != ring) continue;
        const double cx = c.x0 + i * period, cy = c.y0 + j * period;
        const double dx = std::max({0.0, cx - hi, -cx}), dy = std::max({0.0, cy - hi, -cy});
        const double u = lambda * (dx * dx + dy * dy);
        if (std::exp(kMaxBlur - c.b * root_of(c, u)) <= floor) continue;
        out->push_back({static_cast<double>(i) * period, static_cast<double>(j) * period});
        any = true;
      }
    if (!any) break;  // the wings fall off outwards: the next ring's bounds are smaller still
  }
}

namespace {

const IsaDispatch<WrapKernels>& table() {
  static const IsaDispatch<WrapKernels> t(  // immutable after its thread-safe initialisation
      wrap_kernels_scalar, STAMPEDE_SSE42_ENTRY(wrap_kernels_sse42), STAMPEDE_AVX2_ENTRY(wrap_kernels_avx2),
      STAMPEDE_AVX512_ENTRY(wrap_kernels_avx512));
  return t;
}

}  // namespace

const WrapKernels* wrap_kernels_for(Isa isa) { return table().find(isa); }

const WrapKernels& wrap_kernels(Isa isa) { return table().get(isa); }

double wrapped_wings(const WingComponent& c, const BlurMoments& m, std::span<const CopyOffset> copies, double x,
                     double y, std::array<double, kWingDerivatives>* derivatives) {
  double value = 0;
  std::array<double, kWingDerivatives> d{};
  std::array<double*, kWingDerivatives> columns;
  for (int k = 0; k < kWingDerivatives; ++k) columns[k] = &d[k];
  wrap_kernels(Isa::kScalar)
      .add_wings(c, m, copies.data(), static_cast<int>(copies.size()), &x, &y, 1, 1.0, &value, 1.0,
                 derivatives ? columns.data() : nullptr);
  if (derivatives) *derivatives = d;
  return value;
}

double blurred_wing(const WingComponent& c, const BlurMoments& m, double x, double y,
                    std::array<double, kWingDerivatives>* derivatives) {
  const CopyOffset self{};
  return wrapped_wings(c, m, std::span<const CopyOffset>(&self, 1), x, y, derivatives);
}

ChebyshevStamp::ChebyshevStamp(int size, int nodes, Isa isa) : size_(size), nodes_(nodes), kernels_(&wrap_kernels(isa)) {
  if (size < 1 || nodes < 2) throw std::invalid_argument("ChebyshevStamp: needs size >= 1 and nodes >= 2");
  const double half = 0.5 * (size - 1), pi = std::numbers::pi;
  std::vector<double> weight(static_cast<std::size_t>(nodes));
  node_.resize(static_cast<std::size_t>(nodes));
  for (int j = 0; j < nodes; ++j) {
    const double angle = (2 * j + 1) * pi / (2 * nodes);
    node_[static_cast<std::size_t>(j)] = half * (1 - std::cos(angle));  // ascending
    weight[static_cast<std::size_t>(j)] = (j % 2 ? -1.0 : 1.0) * std::sin(angle);  // barycentric, first kind
  }
  basis_.assign(static_cast<std::size_t>(size) * nodes, 0.0);
  for (int x = 0; x < size; ++x) {
    double* b = &basis_[static_cast<std::size_t>(x) * nodes];
    double sum = 0;
    int exact = -1;
    for (int j = 0; j < nodes; ++j) {
      const double dx = x - node_[static_cast<std::size_t>(j)];
      if (dx == 0) exact = j;
      b[j] = dx == 0 ? 0.0 : weight[static_cast<std::size_t>(j)] / dx;
      sum += b[j];
    }
    if (exact >= 0) {
      for (int j = 0; j < nodes; ++j) b[j] = j == exact ? 1.0 : 0.0;
    } else {
      for (int j = 0; j < nodes; ++j) b[j] /= sum;
    }
  }
  basis_t_.resize(basis_.size());
  for (int x = 0; x < size; ++x)
    for (int j = 0; j < nodes; ++j)
      basis_t_[static_cast<std::size_t>(j) * size + x] = basis_[static_cast<std::size_t>(x) * nodes + j];
}

void ChebyshevStamp::add_interpolated(const double* values, double* out, double* scratch) const {
  kernels_->interpolate(size_, nodes_, basis_.data(), basis_t_.data(), values, out, scratch);
}

}  // namespace stampede::kernels
