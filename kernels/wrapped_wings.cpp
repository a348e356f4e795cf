// The periodic copies' light on the stamp; see wrapped_wings.hpp.
#include "kernels/wrapped_wings.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace stampede::kernels {
namespace {

double root_of(const WingComponent& c, double u) {
  switch (c.root) {
    case SersicRoot::kSquareRoot: return std::sqrt(u);
    case SersicRoot::kEighthRoot: return std::sqrt(std::sqrt(std::sqrt(u)));
    case SersicRoot::kGeneralPow: break;
  }
  return std::pow(u, c.s);
}

}  // namespace

double blurred_wing(const WingComponent& c, const BlurMoments& m, double x, double y,
                    std::array<double, kWingDerivatives>* derivatives) {
  const EllipseQuadratic& q = c.q;
  const double dx = x - c.x0, dy = y - c.y0;
  const double vx = q.xx * dx + q.xy * dy, vy = q.xy * dx + q.yy * dy;  // Q d: grad u = 2 Q d
  const double u = dx * vx + dy * vy;
  if (!(u > 0)) {  // only the centre itself; copies never come near it
    if (derivatives) derivatives->fill(0.0);
    return 0.0;
  }
  const double mvx = m.xx * vx + m.xy * vy, mvy = m.xy * vx + m.yy * vy;
  const double g = 4 * (vx * mvx + vy * mvy);                   // grad u^T M grad u
  const double t = m.xx * q.xx + 2 * m.xy * q.xy + m.yy * q.yy;  // tr(M Q) = 1/2 M : grad grad u
  // I(u) = exp(phi), phi = -b u^s, and the blur's second-order term over I, in log form:
  //   B = 1/2 M : grad grad I / I = 1/2 (phi'' + phi'^2) G + phi' T,
  // G = grad u^T M grad u, T = tr(M Q) (grad grad u = 2 Q). The value is I e^B rather than
  // I (1 + B): the same to second order, and exact for an exponential wing under a Gaussian blur
  // (1 + B leaves 3 % of a disc's wing at 30-60 px where the blur raises it by 26 %). Where the
  // profile is steep on the blur's scale (across a thin disc's minor axis) B grows without bound
  // and the expansion means nothing (a Moffat's power-law wing against an exponential has no
  // such moment), so B is saturated smoothly at 2: 2 tanh(B / 2) = B (1 - B^2 / 12 ...).
  const double us = root_of(c, u);
  const double p1 = -c.b * c.s * us / u;
  const double p2 = p1 * (c.s - 1) / u;
  const double blur = 0.5 * (p2 + p1 * p1) * g + p1 * t;
  const double th = std::tanh(0.5 * blur);
  const double value = std::exp(-c.b * us + 2 * th);
  if (!derivatives) return value;
  const double p3 = p2 * (c.s - 2) / u;
  // d value = value (phi' du + sech^2(B / 2) dB), dB = (B's u-derivative) du + 1/2 (phi'' + phi'^2) dG + phi' dT:
  // value (a_u du + a_g dG + a_t dT).
  const double sat = value * (1 - th * th);
  const double a_u = value * p1 + sat * (0.5 * (p3 + 2 * p1 * p2) * g + p2 * t);
  const double a_g = sat * 0.5 * (p2 + p1 * p1), a_t = sat * p1;
  auto& d = *derivatives;
  // Centre: d(dx)/dx0 = -1, so du = -2 (Q d)_x, dG = 8 (M Q d) . dv with dv = -Q e_x.
  d[0] = a_u * (-2 * vx) + a_g * (-8 * (mvx * q.xx + mvy * q.xy));
  d[1] = a_u * (-2 * vy) + a_g * (-8 * (mvx * q.xy + mvy * q.yy));
  auto shape = [&](const EllipseQuadratic& dq) {
    const double wx = dq.xx * dx + dq.xy * dy, wy = dq.xy * dx + dq.yy * dy;
    const double du = dx * wx + dy * wy;
    const double dg = 8 * (mvx * wx + mvy * wy);
    const double dt = m.xx * dq.xx + 2 * m.xy * dq.xy + m.yy * dq.yy;
    return a_u * du + a_g * dg + a_t * dt;
  };
  d[2] = shape(c.dq_de1);
  d[3] = shape(c.dq_de2);
  // Radius: Q scales by (1 + kappa dr), so u, G and T do too (G twice).
  const double k = c.du_dr_over_u;
  d[4] = a_u * k * u + a_g * 2 * k * g + a_t * k * t;
  return value;
}

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
        if (std::exp(2 - c.b * root_of(c, u)) <= floor) continue;  // e^2: the saturated blur
        out->push_back({static_cast<double>(i) * period, static_cast<double>(j) * period});
        any = true;
      }
    if (!any) break;  // the wings fall off outwards: the next ring's bounds are smaller still
  }
}

double wrapped_wings(const WingComponent& c, const BlurMoments& m, std::span<const CopyOffset> copies, double x,
                     double y, std::array<double, kWingDerivatives>* derivatives) {
  double sum = 0;
  std::array<double, kWingDerivatives> total{}, one{};
  for (const CopyOffset& o : copies) {
    // The copy at the centre + o seen from (x, y) is the original seen from (x, y) - o.
    sum += blurred_wing(c, m, x - o.dx, y - o.dy, derivatives ? &one : nullptr);
    if (derivatives)
      for (int k = 0; k < kWingDerivatives; ++k) total[k] += one[k];
  }
  if (derivatives) *derivatives = total;
  return sum;
}

ChebyshevStamp::ChebyshevStamp(int size, int nodes) : size_(size), nodes_(nodes) {
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
}

void ChebyshevStamp::add_interpolated(const double* values, double* out, double* scratch) const {
  const int s = size_, p = nodes_;
  // scratch[jy * s + x] = sum_jx values[jy][jx] basis(x, jx): along x first.
  for (int jy = 0; jy < p; ++jy)
    for (int x = 0; x < s; ++x) {
      const double* b = &basis_[static_cast<std::size_t>(x) * p];
      const double* v = values + static_cast<std::size_t>(jy) * p;
      double acc = 0;
      for (int jx = 0; jx < p; ++jx) acc += v[jx] * b[jx];
      scratch[static_cast<std::size_t>(jy) * s + x] = acc;
    }
  for (int y = 0; y < s; ++y) {
    const double* b = &basis_[static_cast<std::size_t>(y) * p];
    double* o = out + static_cast<std::size_t>(y) * s;
    for (int jy = 0; jy < p; ++jy) {
      const double w = b[jy];
      const double* t = scratch + static_cast<std::size_t>(jy) * s;
      for (int x = 0; x < s; ++x) o[x] += w * t[x];
    }
  }
}

}  // namespace stampede::kernels
