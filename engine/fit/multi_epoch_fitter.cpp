// Joint fits over cutouts; see multi_epoch_fitter.hpp.
#include "engine/fit/multi_epoch_fitter.hpp"

#include "engine/fit/joint_fit_solve.hpp"
#include "engine/fit/projected_joint_problem.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "kernels/moments.hpp"

namespace stampede {

class MultiEpochFitter::Problem final : public SolveProblem {
 public:
  explicit Problem(MultiEpochFitter& f)
      : cutouts_([&f](int box) -> Renderer& { return f.renderer_for(box); },
                 kernels::least_squares_kernels(f.options_.render.simd)) {}

  // The fit's cutouts, its full parameter vector and which of them are free.
  void reset(std::span<const Observation> epochs, const ParamVector& start, std::span<const Param> free) {
    cutouts_.reset(epochs);
    p_ = start;
    free_ = free;
  }
  int num_pixels() const override { return cutouts_.pixels(); }
  double negligible_chi2() const override { return cutouts_.negligible_chi2(); }

  ParamVector full(const LmVector& x) const {
    ParamVector p = p_;
    for (std::size_t k = 0; k < free_.size(); ++k) p[index(free_[k])] = x[static_cast<Eigen::Index>(k)];
    return p;
  }

  bool chi2(const LmVector& x, double* chi2) override {
    const ParamVector p = full(x);
    double sum = 0;
    for (std::size_t c = 0; c < cutouts_.epochs().size(); ++c) {
      double one = 0;
      if (!cutouts_.chi2(c, p, &one)) return false;
      sum += one;
    }
    *chi2 = sum;
    return std::isfinite(sum);
  }

  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    const ParamVector p = full(x);
    const int n = static_cast<int>(free_.size());
    alpha->setZero(n, n);
    beta->setZero(n);
    double sum = 0, signal = 0;
    for (std::size_t c = 0; c < cutouts_.epochs().size(); ++c) {
      if (!cutouts_.sums(c, p, free_, &sums_)) return false;
      sum += sums_.chi2, signal += sums_.signal;
      for (int a = 0; a < n; ++a) {
        (*beta)[a] += sums_.beta[static_cast<std::size_t>(a)];
        for (int b = 0; b < n; ++b) (*alpha)(a, b) += sums_.alpha[static_cast<std::size_t>(a * n + b)];
      }
    }
    *chi2 = sum;
    signal_ = signal;
    return std::isfinite(sum);
  }

  double signal() const { return signal_; }  // sum w m^2 at the last normal_equations
  void use_surrogates(bool on) override { cutouts_.use_surrogates(on); }

 private:
  JointCutouts cutouts_;
  ParamVector p_{};
  std::span<const Param> free_;
  double signal_ = NAN;
  CutoutSums sums_;
};

MultiEpochFitter::MultiEpochFitter(const FitterOptions& options)
    : options_(options),
      plans_(FftPlanning::kEstimate),
      problem_(std::make_unique<Problem>(*this)),
      project_(projects_amplitudes(options)),
      projected_(std::make_unique<ProjectedJointProblem>([this](int box) -> Renderer& { return renderer_for(box); },
                                                         kernels::least_squares_kernels(options.render.simd))) {
  if (options.renderer == RendererKind::kUpsampled)
    throw std::invalid_argument("MultiEpochFitter: cutouts with WCS Jacobians need renderer = exact");
}

MultiEpochFitter::~MultiEpochFitter() = default;

Renderer& MultiEpochFitter::renderer_for(int box_size) {
  auto it = renderers_.find(box_size);
  if (it == renderers_.end()) {
    RenderOptions ro = options_.render;
    ro.stamp_size = box_size;
    it = renderers_.emplace(box_size, std::make_unique<ExactRenderer>(ro, options_.model)).first;
  }
  return *it->second;
}

Fitter& MultiEpochFitter::starter_for(int box_size) {
  auto it = starters_.find(box_size);
  if (it == starters_.end()) {
    FitterOptions o = options_;
    o.render.stamp_size = box_size;
    it = starters_.emplace(box_size, std::make_unique<Fitter>(o, nullptr, plans_)).first;
  }
  return *it->second;
}

ParamVector MultiEpochFitter::sky_start(const Observation& e, std::uint32_t* flags) {
  Fitter& f = starter_for(e.box_size);
  f.set_psf(e.psf);
  const ParamVector pixel = f.starting_point(e.pixels, e.weight, flags);
  // The moments' ellipse in pixels, carried to (u, v); the flux kept (A r^2), over the flux scale.
  ParamVector sky = pixel;
  const double rp = std::abs(pixel[index(Param::kRadius)]);
  double e1 = 0, e2 = 0, r = rp * std::sqrt(std::abs(e.frame.determinant()));
  const kernels::EllipseQuadratic q =
      e.frame.to_sky(kernels::ellipse_quadratic(pixel[index(Param::kE1)], pixel[index(Param::kE2)], rp));
  if (!kernels::ellipse_parameters(q, &e1, &e2, &r)) e1 = e2 = 0;
  sky[index(Param::kE1)] = e1;
  sky[index(Param::kE2)] = e2;
  sky[index(Param::kRadius)] = r;
  const double dx = pixel[index(Param::kX0)] - e.frame.x_ref, dy = pixel[index(Param::kY0)] - e.frame.y_ref;
  sky[index(Param::kX0)] = e.frame.dudx * dx + e.frame.dudy * dy;
  sky[index(Param::kY0)] = e.frame.dvdx * dx + e.frame.dvdy * dy;
  const double area = rp * rp / (r * r) / e.flux_scale;
  sky[index(Param::kBulgeA)] *= area;
  sky[index(Param::kDiscA)] *= area;
  return sky;
}

ParamVector MultiEpochFitter::joint_start(std::span<const Observation> epochs, std::size_t first, std::uint32_t* flags) {
  ParamVector p = sky_start(epochs[first], flags);
  if (epochs.size() < 2) return p;
  double sw = 0, u = 0, v = 0, flux = 0, g[3] = {0, 0, 0}, t[3] = {0, 0, 0};
  double first_flux = NAN;
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    const Observation& e = epochs[k];
    if (!e.psf) continue;
    const kernels::ImageMoments m = kernels::adaptive_moments(e.pixels, e.weight, e.box_size);
    if (!m.valid || !(m.flux > 0)) continue;
    if (k == first) first_flux = m.flux / e.flux_scale;
    double wsum = 0;
    int used = 0;
    for (double w : e.weight)
      if (w > 0) wsum += w, ++used;
    const double we = m.flux * m.flux * wsum / std::max(used, 1);
    // du = J dx: a pixel covariance M is J M J^T on the sky.
    const double J[2][2] = {{e.frame.dudx, e.frame.dudy}, {e.frame.dvdx, e.frame.dvdy}};
    auto sky = [&](double xx, double xy, double yy, double out[3]) {
      const double M[2][2] = {{xx, xy}, {xy, yy}};
      double S[2][2];
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) S[i][j] = J[i][0] * (M[0][0] * J[j][0] + M[0][1] * J[j][1]) + J[i][1] * (M[1][0] * J[j][0] + M[1][1] * J[j][1]);
      out[0] = S[0][0], out[1] = S[0][1], out[2] = S[1][1];
    };
    double ms[3], ps[3];
    sky(m.xx, m.xy, m.yy, ms);
    sky(e.psf->xx(), e.psf->xy(), e.psf->yy(), ps);
    for (int i = 0; i < 3; ++i) g[i] += we * (ms[i] - ps[i]), t[i] += we * ms[i];
    const double dx = m.x - e.frame.x_ref, dy = m.y - e.frame.y_ref;
    u += we * (J[0][0] * dx + J[0][1] * dy);
    v += we * (J[1][0] * dx + J[1][1] * dy);
    flux += we * m.flux / e.flux_scale;
    sw += we;
  }
  if (!(sw > 0) || !(first_flux > 0)) return p;
  for (int i = 0; i < 3; ++i) g[i] /= sw, t[i] /= sw;
  const double r0 = p[index(Param::kRadius)];
  // As the single-stamp start: the PSF's moments removed when that leaves a positive-definite
  // galaxy; otherwise the object is no larger than the PSF and starts round and small.
  const bool resolved = g[0] > 0 && g[2] > 0 && g[0] * g[2] - g[1] * g[1] > 0.01 * (t[0] * t[2] - t[1] * t[1]);
  double e1 = 0, e2 = 0, r = r0;
  if (resolved) {
    kernels::covariance_ellipticity(g[0], g[1], g[2], &e1, &e2);
    r = 1.1774 * std::pow(g[0] * g[2] - g[1] * g[1], 0.25);
  } else {
    r = std::min(r0, 0.3 * std::sqrt(std::abs(epochs[first].frame.determinant())));
  }
  if (!(r > 0) || !std::isfinite(r)) return p;
  const ParameterSet& ps = options_.params;
  auto set = [&](Param q, double value) {
    if (std::isnan(ps[q].start)) p[index(q)] = value;
  };
  set(Param::kX0, u / sw);
  set(Param::kY0, v / sw);
  set(Param::kE1, e1);
  set(Param::kE2, e2);
  set(Param::kRadius, r);
  // Amplitudes: flux ~ A r^2 at a fixed profile.
  const double scale = (flux / sw) / first_flux * (r0 * r0) / (r * r);
  if (std::isnan(ps[Param::kBulgeA].start)) p[index(Param::kBulgeA)] *= scale;
  if (std::isnan(ps[Param::kDiscA].start)) p[index(Param::kDiscA)] *= scale;
  return p;
}

FitResult MultiEpochFitter::fit(std::span<const Observation> epochs, std::size_t first) {
  if (first >= epochs.size()) throw std::invalid_argument("MultiEpochFitter::fit: no epoch to start from");
  if (!epochs[first].psf) {
    FitResult r;
    r.status = FitStatus::kPsfFailure;
    return r;
  }
  const Observation& e = epochs.front();
  if (epochs.size() == 1 && e.flux_scale == 1 && e.frame.unit_jacobian()) {
    // One cutout whose sky is its pixel grid is a single stamp: the single-stamp fit (amplitude
    // projection, scaled units), so such a MEDS row is the grid path's row bit for bit; only the
    // centroid is moved to the frame's reference.
    Fitter& f = starter_for(e.box_size);
    f.set_psf(e.psf);
    FitResult r = f.fit(e.pixels, e.weight, WeightKind::kInverseVariance);
    r.params[index(Param::kX0)] -= e.frame.x_ref;
    r.params[index(Param::kY0)] -= e.frame.y_ref;
    return r;
  }
  std::uint32_t flags = 0;
  const ParamVector start = joint_start(epochs, first, &flags);
  FitResult r = fit(epochs, start);
  r.flags |= flags;
  return r;
}

FitResult MultiEpochFitter::fit(std::span<const Observation> epochs, const ParamVector& start) {
  FitResult r;
  std::array<Param, kNumParams> free_all{};
  const int nf = options_.params.free_params(&free_all);
  const std::span<const Param> free(free_all.data(), static_cast<std::size_t>(nf));
  r.status = check_cutouts(epochs, "MultiEpochFitter::fit");
  if (r.status != FitStatus::kOk) return r;
  problem_->reset(epochs, start, free);
  if (problem_->num_pixels() == 0) {
    r.status = FitStatus::kNoData;
    return r;
  }
  LmVector x0(nf);
  for (int k = 0; k < nf; ++k) x0[k] = start[index(free[static_cast<std::size_t>(k)])];
  const bool coarse = any_surrogate(epochs, [this](int box) -> Renderer& { return renderer_for(box); });
  SolveResult solved;
  if (project_) {
    slot_of_cutout_.assign(epochs.size(), 0);
    projected_->reset(epochs, start, free, slot_of_cutout_, 1, [](std::size_t a, int) { return static_cast<int>(a); }, nf);
    if (!solve(*projected_, projected_->shape_of(x0), options_, LmUnits{}, coarse, &r, &solved)) return r;
  } else if (!solve(*problem_, x0, options_, LmUnits{}, coarse, &r, &solved)) {
    return r;
  }
  const LmSummary& sum = solved.summary;
  const double chi2 = solved.chi2;
  const ParamVector p = problem_->full(sum.x);
  std::uint32_t flags = 0;
  if (!solved.cov_ok) flags |= kFlagNoErrors;
  for (int k = 0; k < nf; ++k)
    if (solved.cov_ok) r.errors[index(free[static_cast<std::size_t>(k)])] = std::sqrt(solved.cov(k, k));
  if (std::hypot(p[index(Param::kE1)], p[index(Param::kE2)]) > options_.model.ellipticity_mirror) flags |= kFlagMirrored;
  Renderer& any = renderer_for(epochs.front().box_size);
  any.effective_params(p, &r.params);
  r.e1_err = r.errors[index(Param::kE1)];
  r.e2_err = r.errors[index(Param::kE2)];
  any.component_fluxes(p, &r.bulge_flux, &r.disc_flux);
  r.flux = r.bulge_flux + r.disc_flux;
  r.chi2 = chi2;
  r.likelihood = -0.5 * chi2;
  r.snr = std::sqrt(project_ ? projected_->signal(0) : problem_->signal());
  r.status = status_of_stop(sum.reason, &flags);
  r.flags = flags;
  return r;
}

}  // namespace stampede
