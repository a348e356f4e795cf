// Parameter vector -> rendered components; see galaxy_model.hpp.
#include "engine/model/galaxy_model.hpp"

#include <cmath>
#include <sstream>

#include "kernels/ellipse.hpp"
#include "kernels/sersic.hpp"

namespace stampede {

bool ModelOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(ellipticity_mirror > 0.0 && ellipticity_mirror < 1.0))
    msg << "ellipticity_mirror = " << ellipticity_mirror << ": must be in (0, 1)";
  else if (!(radius_softening > 0.0 && std::isfinite(radius_softening)))
    msg << "radius_softening = " << radius_softening << ": must be > 0 (sub-pixels)";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

EffectiveEllipticity mirror_ellipticity(double e1, double e2, double mirror) {
  EffectiveEllipticity out;
  const double t = std::hypot(e1, e2);
  if (t <= mirror) {
    out.e1 = e1;
    out.e2 = e2;
    return out;
  }
  // Signed radius s(t): a triangle wave of period 4 m with s = t on [-m, m], so |s| <= m.
  const double period = 4.0 * mirror;
  double phase = std::fmod(t + mirror, period);  // in [0, 4m)
  double s, ds;
  if (phase <= 2.0 * mirror) {
    s = phase - mirror;
    ds = 1.0;
  } else {
    s = 3.0 * mirror - phase;
    ds = -1.0;
  }
  // e_eff = e g(t), g = s / t: d e_eff_i / d e_j = g delta_ij + e_i e_j g'(t) / t.
  const double g = s / t;
  const double dg = (ds * t - s) / (t * t);
  out.e1 = e1 * g;
  out.e2 = e2 * g;
  out.d[0][0] = g + e1 * e1 * dg / t;
  out.d[0][1] = e1 * e2 * dg / t;
  out.d[1][0] = out.d[0][1];
  out.d[1][1] = g + e2 * e2 * dg / t;
  return out;
}

double soften_radius(double r, double transition, double* derivative) {
  if (std::abs(r) >= transition) {
    *derivative = r >= 0 ? 1.0 : -1.0;
    return std::abs(r);
  }
  *derivative = r / transition;
  return 0.5 * (transition + r * r / transition);
}


GalaxyModel::GalaxyModel(const ModelOptions& options, double subpixel_step)
    : options_(options), transition_(options.radius_softening * subpixel_step) {}

namespace {

// Bulge ellipticity from the disc's: |e_b| = |e_d| + delta_e, angle + delta_theta; and its
// Jacobian with respect to the disc ellipticity.
bool offset_ellipticity(double e1, double e2, double delta_e, double delta_theta, double* b1, double* b2,
                        double jac[2][2]) {
  if (delta_e == 0.0 && delta_theta == 0.0) {
    *b1 = e1;
    *b2 = e2;
    jac[0][0] = jac[1][1] = 1.0;
    jac[0][1] = jac[1][0] = 0.0;
    return true;
  }
  const double s = std::hypot(e1, e2);
  const double c2 = std::cos(2.0 * delta_theta), s2 = std::sin(2.0 * delta_theta);
  if (s < 1e-12) {  // direction undefined: take the +x axis
    *b1 = delta_e * c2;
    *b2 = delta_e * s2;
    jac[0][0] = jac[1][1] = 1.0;
    jac[0][1] = jac[1][0] = 0.0;
    return true;
  }
  const double f = (s + delta_e) / s;
  // e_b = f R e_d, d e_b / d e_d = R (f I - delta_e e e^T / s^3).
  const double m00 = f - delta_e * e1 * e1 / (s * s * s);
  const double m01 = -delta_e * e1 * e2 / (s * s * s);
  const double m11 = f - delta_e * e2 * e2 / (s * s * s);
  *b1 = f * (c2 * e1 - s2 * e2);
  *b2 = f * (s2 * e1 + c2 * e2);
  jac[0][0] = c2 * m00 - s2 * m01;
  jac[0][1] = c2 * m01 - s2 * m11;
  jac[1][0] = s2 * m00 + c2 * m01;
  jac[1][1] = s2 * m01 + c2 * m11;
  return true;
}

void fill_block(double x0, double y0, double e1, double e2, double radius, double n, double amplitude,
                const double chain[2][2], double du_dr_over_u, kernels::SersicDerivativeBlock* out) {
  out->shape.x0 = x0;
  out->shape.y0 = y0;
  out->shape.q = kernels::ellipse_quadratic(e1, e2, radius);
  out->shape.b = kernels::sersic_b(n);
  out->shape.inv_2n = 0.5 / n;
  out->shape.root = kernels::sersic_root_for(n);
  out->amplitude = amplitude;
  kernels::EllipseQuadratic q1, q2;  // with respect to this component's own e
  kernels::ellipse_quadratic_derivatives(e1, e2, radius, &q1, &q2);
  // Chain to the model's e parameters: dq/de_j = sum_i dq/de_i (d e_i / d e_j).
  auto combine = [&](int j) {
    return kernels::EllipseQuadratic{q1.xx * chain[0][j] + q2.xx * chain[1][j], q1.xy * chain[0][j] + q2.xy * chain[1][j],
                                     q1.yy * chain[0][j] + q2.yy * chain[1][j]};
  };
  out->dq_de1 = combine(0);
  out->dq_de2 = combine(1);
  out->du_dr_over_u = du_dr_over_u;
}

}  // namespace

bool GalaxyModel::components(const ParamVector& p, ModelComponents* out) const {
  for (double v : p)
    if (!std::isfinite(v)) return false;
  const double x0 = p[index(Param::kX0)], y0 = p[index(Param::kY0)];
  const EffectiveEllipticity e =
      mirror_ellipticity(p[index(Param::kE1)], p[index(Param::kE2)], options_.ellipticity_mirror);
  double dr = 0;
  const double r_disc = soften_radius(p[index(Param::kRadius)], transition_, &dr);
  const double r_bulge = r_disc * p[index(Param::kRadiusRatio)];
  if (!(r_bulge > 0.0)) return false;
  double b1, b2, off[2][2];
  offset_ellipticity(e.e1, e.e2, p[index(Param::kDeltaE)], p[index(Param::kDeltaTheta)], &b1, &b2, off);
  if (!(b1 * b1 + b2 * b2 < 1.0)) return false;
  double bulge_chain[2][2];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) bulge_chain[i][j] = off[i][0] * e.d[0][j] + off[i][1] * e.d[1][j];
  // u scales as 1 / r^2 in both components: du/dr = -2 u (dr_eff/dr) / r_eff.
  const double du_dr_over_u = -2.0 * dr / r_disc;
  fill_block(x0, y0, b1, b2, r_bulge, p[index(Param::kBulgeIndex)], p[index(Param::kBulgeA)], bulge_chain, du_dr_over_u,
             &out->bulge);
  fill_block(x0, y0, e.e1, e.e2, r_disc, p[index(Param::kDiscIndex)], p[index(Param::kDiscA)], e.d, du_dr_over_u,
             &out->disc);
  out->bulge_radius = r_bulge;
  out->disc_radius = r_disc;
  out->e1 = e.e1;
  out->e2 = e.e2;
  return true;
}

void GalaxyModel::fluxes(const ParamVector& p, double* bulge_flux, double* disc_flux) const {
  double dr = 0;
  const double r_disc = soften_radius(p[index(Param::kRadius)], transition_, &dr);
  *bulge_flux = kernels::sersic_flux(p[index(Param::kBulgeA)], r_disc * p[index(Param::kRadiusRatio)],
                                     p[index(Param::kBulgeIndex)]);
  *disc_flux = kernels::sersic_flux(p[index(Param::kDiscA)], r_disc, p[index(Param::kDiscIndex)]);
}

bool GalaxyModel::effective_params(const ParamVector& p, ParamVector* out) const {
  ModelComponents comp;
  const bool ok = components(p, &comp);
  *out = p;
  (*out)[index(Param::kE1)] = comp.e1;
  (*out)[index(Param::kE2)] = comp.e2;
  (*out)[index(Param::kRadius)] = comp.disc_radius;
  return ok;
}

}  // namespace stampede
