// Single-stamp fitting; see fitter.hpp.
#include "engine/fit/fitter.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "engine/fit/fit_result_assembly.hpp"
#include "engine/fit/solve.hpp"
#include "engine/solver/variable_projection.hpp"
#include "kernels/least_squares.hpp"
#include "kernels/moments.hpp"
#include "kernels/sersic.hpp"

namespace stampede {

bool FitterOptions::IsValid(std::string* why) const {
  if (!render.IsValid(why) || !model.IsValid(why) || !lm.IsValid(why) || !params.IsValid(why)) return false;
  if (!(surrogate_eps4 > 0 && surrogate_eps4 < 1)) {
    if (why) {
      std::ostringstream msg;
      msg << "surrogate_eps4 = " << surrogate_eps4 << ": must be in (0, 1)";
      *why = msg.str();
    }
    return false;
  }
  if (!(noise_sigma >= 0.0 && std::isfinite(noise_sigma))) {
    if (why) {
      std::ostringstream msg;
      msg << "noise_sigma = " << noise_sigma << ": must be >= 0 (0 = unweighted)";
      *why = msg.str();
    }
    return false;
  }
  // Every pixel's weight is 1/noise_sigma^2: refused where it (or chi2) would overflow or underflow,
  // which would make every row bad_pixels or no_data.
  if (noise_sigma > 0 && !(noise_sigma >= 1e-150 && noise_sigma <= 1e150)) {
    if (why) {
      std::ostringstream msg;
      msg << "noise_sigma = " << noise_sigma << ": the pixel weight 1/noise_sigma^2 would "
          << (noise_sigma < 1 ? "overflow" : "underflow") << "; must be 0 or in [1e-150, 1e150]";
      *why = msg.str();
    }
    return false;
  }
  return true;
}

bool projects_amplitudes(const FitterOptions& options) {
  const ParameterSet& ps = options.params;
  auto free_unbounded = [&](Param q) {
    const ParamSpec& spec = ps[q];
    return spec.free && !(std::isfinite(spec.lower) || std::isfinite(spec.upper));
  };
  std::array<Param, kNumParams> free{};
  return options.project_amplitudes && free_unbounded(Param::kBulgeA) && free_unbounded(Param::kDiscA) &&
         ps.free_params(&free) > 2;
}

static_assert(kNumParams <= kMaxFree, "the solver's fixed storage must hold every model parameter");

// The least-squares problem of one stamp in the free parameters.
class Fitter::Problem final : public LeastSquaresProblem {
 public:
  // Every per-pixel array starts on a 64-byte line, so the vector kernels' loads never straddle two.
  Problem(Fitter& f, int npix)
      : f_(f), data_(npix), model_(npix), jacobian_model_(npix), columns_(kMaxFree * kernels::aligned_stride<double>(npix)) {
    for (int k = 0; k < kMaxFree; ++k) column_ptr_[k] = columns_.data() + k * kernels::aligned_stride<double>(npix);
  }
  // The stamp in the fit's units; masked pixels may hold NaN, and as zeros they keep the
  // least-squares kernels on their fast path.
  void set_data(std::span<const double> data, double data_unit, int npix_used) {
    double sum = 0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      data_[i] = f_.weight_[i] != 0.0 ? data[i] / data_unit : 0.0;
      sum += f_.weight_[i] * data_[i] * data_[i];
    }
    npix_used_ = npix_used;
    // A model within ~1e-7 rms of the data, relative to the data, is exact for any purpose: noise-
    // free data drawn by the model's own transforms are fitted to rounding, and chi2 keeps halving.
    negligible_chi2_ = 1e-14 * sum;
  }
  double negligible_chi2() const override { return negligible_chi2_; }
  // The full parameter vector (internal units) the free ones are set in.
  void reset(const ParamVector& full) { full_ = full; }
  int num_pixels() const override { return npix_used_; }
  std::span<const double> data() const { return data_; }

  // x (internal units) in the full vector; false outside the bounds.
  bool expand(const LmVector& x, ParamVector* p) const {
    *p = full_;
    for (int k = 0; k < f_.num_free_; ++k)
      if (!f_.set_within_bounds(f_.free_[k], x[k], p)) return false;  // out of range: no model
    return true;
  }
  // A model that cannot be made has no chi2 (NaN); the solver gets `false` and rejects the step.
  bool chi2(const LmVector& x, double* chi2) override {
    ParamVector p;
    if (!expand(x, &p) || f_.active_->render(p, model_) != RenderStatus::kOk) {
      *chi2 = NAN;
      return false;
    }
    *chi2 = f_.least_squares_->weighted_chi2(data_, model_, f_.weight_);
    return std::isfinite(*chi2);
  }
  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    ParamVector p;
    const int nf = f_.num_free_;
    if (!expand(x, &p) ||
        f_.active_->render_with_jacobian(p, std::span<const Param>(f_.free_.data(), nf), model_,
                                           std::span<double* const>(column_ptr_.data(), nf)) != RenderStatus::kOk) {
      *chi2 = NAN;
      return false;
    }
    alpha->resize(nf, nf);
    beta->resize(nf);
    *chi2 = f_.least_squares_->normal_equations(data_, model_, f_.weight_, column_ptr_.data(), nf, alpha->data(),
                                                 beta->data());
    // The solver's Jacobian points are its iterates: keep this model, so the optimum's need not be
    // drawn again when the last Jacobian was taken there.
    std::copy(model_.begin(), model_.end(), jacobian_model_.begin());
    return std::isfinite(*chi2) && alpha->allFinite() && beta->allFinite();
  }
  // The model of the last normal_equations call.
  const kernels::AlignedVector<double>& jacobian_model() const { return jacobian_model_; }
  // For the projected problem, which draws into the same buffers.
  kernels::AlignedVector<double>& model_buffer() { return model_; }
  kernels::AlignedVector<double>& jacobian_model_buffer() { return jacobian_model_; }
  double* const* columns() const { return column_ptr_.data(); }

 private:
  Fitter& f_;
  kernels::AlignedVector<double> data_;
  ParamVector full_{};
  int npix_used_ = 0;
  double negligible_chi2_ = 0;
  kernels::AlignedVector<double> model_, jacobian_model_;
  kernels::AlignedVector<double> columns_;
  std::array<double*, kMaxFree> column_ptr_{};
};

// The problem in the shape parameters alone, the two amplitudes solved linearly at each trial
// shape (engine/solver/variable_projection.hpp). The optimum is the joint fit's; the path is
// not: no steps along the bulge/disc flux degeneracy, where the joint fit spends tens to
// hundreds of iterations at low S/N (docs/solver.md).
class Fitter::ProjectedProblem final : public LeastSquaresProblem {
 public:
  ProjectedProblem(Fitter& f, Problem& base, int npix)
      : f_(f), base_(base), bulge_(npix), disc_(npix), projected_(kMaxFree * kernels::aligned_stride<double>(npix)) {
    for (int k = 0; k < kMaxFree; ++k) projected_ptr_[k] = projected_.data() + k * kernels::aligned_stride<double>(npix);
  }
  int num_pixels() const override { return base_.num_pixels(); }
  double negligible_chi2() const override { return base_.negligible_chi2(); }
  // Starts a fit: the full vector the shape parameters are set in.
  void reset(const ParamVector& full) {
    full_ = full;
    cached_ = false;
    extra_renders_ = 0;
  }
  // The shape parameters (x) in the full vector with amplitudes `a`; false outside the bounds.
  bool expand(const LmVector& x, const double a[2], ParamVector* p) const {
    *p = full_;
    for (int j = 0; j < f_.num_shape_; ++j)
      if (!f_.set_within_bounds(f_.free_[f_.shape_[j]], x[j], p)) return false;
    (*p)[index(Param::kBulgeA)] = a[0];
    (*p)[index(Param::kDiscA)] = a[1];
    return true;
  }
  bool chi2(const LmVector& x, double* chi2) override {
    *chi2 = NAN;
    cached_ = false;
    ParamVector p;
    const double none[2] = {0, 0};
    if (!expand(x, none, &p) || f_.active_->render_components(p, bulge_, disc_) != RenderStatus::kOk) return false;
    const std::span<const double> data = base_.data();
    const std::span<const double> weight = f_.weight_;
    std::array<double*, 2> cols = {bulge_.data(), disc_.data()};
    double g[4], h[2];
    f_.least_squares_->normal_equations(data, f_.zeros_, weight, cols.data(), 2, g, h);
    if (!solve_linear_amplitudes(g, h, &amplitudes_)) return false;
    auto& model = base_.model_buffer();
    for (std::size_t i = 0; i < model.size(); ++i) model[i] = amplitudes_.a[0] * bulge_[i] + amplitudes_.a[1] * disc_[i];
    *chi2 = f_.least_squares_->weighted_chi2(data, model, weight);
    cached_x_ = x;
    cached_ = std::isfinite(*chi2);
    return cached_;
  }
  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    *chi2 = NAN;
    if (!(cached_ && cached_x_ == x)) {  // the amplitudes at x (the solver's first point only)
      ++extra_renders_;
      double c;
      if (!this->chi2(x, &c)) return false;
    }
    ParamVector p;
    if (!expand(x, amplitudes_.a, &p)) return false;
    // The model and the full Jacobian (every free parameter, amplitudes included) at x.
    auto& model = base_.model_buffer();
    double* const* cols = base_.columns();
    if (f_.active_->render_with_jacobian(p, std::span<const Param>(f_.free_.data(), f_.num_free_), model,
                                           std::span<double* const>(cols, f_.num_free_)) != RenderStatus::kOk)
      return false;
    const double* b = cols[f_.amplitude_[0]];
    const double* d = cols[f_.amplitude_[1]];
    const std::span<const double> weight = f_.weight_;
    const std::size_t npix = model.size();
    for (int j = 0; j < f_.num_shape_; ++j)  // Kaufman's Jacobian: each shape column projected
      project_out(amplitudes_, weight.data(), b, d, cols[f_.shape_[j]], projected_ptr_[j], npix);
    const int n = f_.num_shape_;
    alpha->resize(n, n);
    beta->resize(n);
    *chi2 = f_.least_squares_->normal_equations(base_.data(), model, weight, projected_ptr_.data(), n, alpha->data(),
                                                 beta->data());
    auto& kept = base_.jacobian_model_buffer();
    std::copy(model.begin(), model.end(), kept.begin());
    jacobian_amplitudes_[0] = amplitudes_.a[0];
    jacobian_amplitudes_[1] = amplitudes_.a[1];
    return std::isfinite(*chi2) && alpha->allFinite() && beta->allFinite();
  }
  // After a normal_equations call at x: the full parameter vector and J^T W J over every free
  // parameter (for the errors), from that call's images.
  bool finish(const LmVector& x, ParamVector* p, LmMatrix* alpha) {
    if (!expand(x, jacobian_amplitudes_, p)) return false;
    const int n = f_.num_free_;
    alpha->resize(n, n);
    LmVector beta(n);
    const double c = f_.least_squares_->normal_equations(base_.data(), base_.jacobian_model(), f_.weight_,
                                                         base_.columns(), n, alpha->data(), beta.data());
    return std::isfinite(c) && alpha->allFinite();
  }
  int extra_renders() const { return extra_renders_; }

 private:
  Fitter& f_;
  Problem& base_;
  ParamVector full_{};
  kernels::AlignedVector<double> bulge_, disc_;
  kernels::AlignedVector<double> projected_;
  std::array<double*, kMaxFree> projected_ptr_{};
  LinearAmplitudes amplitudes_;  // at cached_x_
  LmVector cached_x_;
  bool cached_ = false;
  double jacobian_amplitudes_[2] = {0, 0};
  int extra_renders_ = 0;
};

bool Fitter::set_within_bounds(Param q, double x, ParamVector* p) const {
  const int i = index(q);
  const double v = x * units_.of(q);
  if (!(v >= lower_[i] && v <= upper_[i])) return false;
  (*p)[i] = x;
  return true;
}

Fitter::Fitter(const FitterOptions& options, std::shared_ptr<const PreparedPsf> psf, FftPlanCache& plans)
    : options_(options), psf_(std::move(psf)) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument(why);
  least_squares_ = &kernels::least_squares_kernels(options_.render.simd);
  const int s = options_.render.stamp_size;
  const int npix = s * s;
  renderer_ = make_renderer(options_.renderer, options_.render, options_.model, plans);
  active_ = renderer_.get();
  if (psf_) renderer_->set_psf(psf_);
  problem_ = std::make_unique<Problem>(*this, npix);
  projected_ = std::make_unique<ProjectedProblem>(*this, *problem_, npix);
  weight_.assign(npix, 0.0);
  start_bulge_.assign(npix, 0.0);
  start_disc_.assign(npix, 0.0);
  start_model_.assign(npix, 0.0);
  zeros_.assign(npix, 0.0);
  num_free_ = options_.params.free_params(&free_);
  // The amplitudes are solved linearly (ProjectedProblem) when both are free and unbounded.
  for (int k = 0; k < num_free_; ++k) {
    const Param q = free_[k];
    if (q == Param::kBulgeA || q == Param::kDiscA)
      amplitude_[q == Param::kBulgeA ? 0 : 1] = k;
    else
      shape_[num_shape_++] = k;
  }
  project_ = projects_amplitudes(options_);
  for (int k = 0; k < kNumParams; ++k) {
    const ParamSpec& spec = options_.params.spec[k];
    lower_[k] = spec.lower;
    upper_[k] = spec.upper;
  }
  // Centroid bounds default to the stamp itself.
  for (Param c : {Param::kX0, Param::kY0}) {
    if (std::isnan(lower_[index(c)])) lower_[index(c)] = -0.5;
    if (std::isnan(upper_[index(c)])) upper_[index(c)] = s - 0.5;
  }
}

Fitter::~Fitter() = default;

void Fitter::set_psf(std::shared_ptr<const PreparedPsf> psf) {
  psf_ = std::move(psf);
  if (psf_) renderer_->set_psf(psf_);
}

FitStatus Fitter::prepare_weights(std::span<const double> pixels, std::span<const double> weight, WeightKind kind,
                                  std::uint32_t* flags) {
  const std::size_t npix = weight_.size();
  if (pixels.size() != npix || (!weight.empty() && weight.size() != npix))
    throw std::invalid_argument("stamp or weight size does not match stamp_size^2");
  const double sigma = options_.noise_sigma;
  const double w0 = sigma > 0 ? 1.0 / (sigma * sigma) : 1.0;
  const bool mask = kind == WeightKind::kMask;
  if ((weight.empty() || mask) && sigma == 0) *flags |= kFlagUnweighted;
  int used = 0;
  bool flat = true;  // every used pixel equal (all zero included): no galaxy to fit
  double first = NAN, max_abs = 0.0, max_weight = 0.0;
  units_ = FitUnits{};
  for (std::size_t i = 0; i < npix; ++i) {
    const double w = weight.empty() ? w0 : mask ? (weight[i] != 0.0 ? w0 : 0.0) : weight[i];
    if (!(w >= 0.0) || !std::isfinite(w)) return FitStatus::kBadPixels;
    weight_[i] = w;
    if (w == 0.0) {
      *flags |= kFlagMaskedPixels;
      continue;
    }
    if (!std::isfinite(pixels[i])) return FitStatus::kBadPixels;
    if (used++ == 0) first = pixels[i];
    flat &= pixels[i] == first;
    max_abs = std::max(max_abs, std::abs(pixels[i]));
    max_weight = std::max(max_weight, w);
  }
  if (used == 0 || flat) return FitStatus::kNoData;
  // Fit in units where the largest |pixel| and weight are in [1, 2): see fit_units.hpp.
  units_ = FitUnits::for_data(max_abs, max_weight);
  for (double& w : weight_) w /= units_.weight;
  problem_->set_data(pixels, units_.data, used);
  return FitStatus::kOk;
}

ParamVector Fitter::starting_point(std::span<const double> pixels, std::span<const double> weight,
                                   std::uint32_t* flags) {
  if (prepare_weights(pixels, weight, WeightKind::kInverseVariance, flags) != FitStatus::kOk) {
    *flags |= kFlagDefaultStart;
    problem_->set_data(zeros_, 1.0, 0);  // nothing to take moments of
  }
  return units_.to_data(start_from_prepared(flags));
}

ParamVector Fitter::start_from_prepared(std::uint32_t* flags) {
  const int s = options_.render.stamp_size;
  const ParameterSet& ps = options_.params;
  ParamVector p;
  for (int k = 0; k < kNumParams; ++k) p[k] = ps.spec[k].start / units_.of(static_cast<Param>(k));
  const std::span<const double> pixels = problem_->data();
  const kernels::ImageMoments m = kernels::adaptive_moments(pixels, weight_, s);
  double x = 0.5 * (s - 1), y = 0.5 * (s - 1), e1 = 0, e2 = 0, r = 1.5;
  double flux = m.flux;
  if (m.valid && m.x >= 0 && m.x <= s - 1 && m.y >= 0 && m.y <= s - 1) {
    x = m.x;
    y = m.y;
    // Remove the PSF's second moments when that leaves a positive-definite galaxy; when it does
    // not, the object is no larger than the PSF: start round and small rather than at the PSF's
    // size, where a de Vaucouleurs cusp of several pixels can mimic an unresolved source (a local
    // optimum the solver then descends into: projected_fit_test, GalSim case 21).
    double gxx = m.xx, gxy = m.xy, gyy = m.yy;
    bool resolved = true;
    if (psf_) {
      const double dxx = m.xx - psf_->xx(), dxy = m.xy - psf_->xy(), dyy = m.yy - psf_->yy();
      resolved = dxx > 0 && dyy > 0 && dxx * dyy - dxy * dxy > 0.01 * (m.xx * m.yy - m.xy * m.xy);
      if (resolved) {
        gxx = dxx;
        gxy = dxy;
        gyy = dyy;
      }
    }
    if (resolved) {
      kernels::covariance_ellipticity(gxx, gxy, gyy, &e1, &e2);
      // Half-light radius of a Gaussian with this determinant: sqrt(2 ln 2) sigma.
      r = 1.1774 * std::pow(gxx * gyy - gxy * gxy, 0.25);
    } else {
      r = 0.3;
    }
    if (!(r > 0.3) || !std::isfinite(r)) r = 0.3;
  } else {
    *flags |= kFlagDefaultStart;
  }
  auto set_if_unset = [&](Param q, double v) {
    if (std::isnan(p[index(q)])) p[index(q)] = v;
  };
  set_if_unset(Param::kX0, x);
  set_if_unset(Param::kY0, y);
  set_if_unset(Param::kE1, e1);
  set_if_unset(Param::kE2, e2);
  set_if_unset(Param::kRadius, r);
  // Split the flux evenly between the components that are free to have it.
  const bool bulge_free = ps[Param::kBulgeA].free, disc_free = ps[Param::kDiscA].free;
  const double share = (bulge_free && disc_free) ? 0.5 : 1.0;
  const double rd = std::abs(p[index(Param::kRadius)]);
  const double rb = rd * p[index(Param::kRadiusRatio)];
  if (!(flux > 0) || !std::isfinite(flux)) flux = 1.0;
  const bool amplitudes_unset = std::isnan(p[index(Param::kBulgeA)]) && std::isnan(p[index(Param::kDiscA)]);
  set_if_unset(Param::kBulgeA, bulge_free ? share * flux / kernels::sersic_flux_per_amplitude(rb, p[index(Param::kBulgeIndex)]) : 0.0);
  set_if_unset(Param::kDiscA, disc_free ? share * flux / kernels::sersic_flux_per_amplitude(rd, p[index(Param::kDiscIndex)]) : 0.0);
  for (int k = 0; k < kNumParams; ++k) {
    const double unit = units_.of(static_cast<Param>(k));
    if (!std::isnan(lower_[k])) p[k] = std::max(p[k], lower_[k] / unit);
    if (!std::isnan(upper_[k])) p[k] = std::min(p[k], upper_[k] / unit);
  }
  // A projected fit solves the amplitudes at every shape; a joint one starts from the best ones.
  if (amplitudes_unset && bulge_free && disc_free && !project_) solve_start_amplitudes(&p);
  return p;
}

void Fitter::solve_start_amplitudes(ParamVector* p) {
  // The model is linear in the amplitudes: at the starting shape, take the weighted least-squares
  // amplitudes (a 2 x 2 solve) instead of an arbitrary flux split.
  const std::array<Param, 2> amps = {Param::kBulgeA, Param::kDiscA};
  std::array<double*, 2> cols = {start_bulge_.data(), start_disc_.data()};
  if (renderer_->render_with_jacobian(*p, amps, start_model_, cols) != RenderStatus::kOk) return;
  double a[4], b[2];
  least_squares_->normal_equations(problem_->data(), zeros_, weight_, cols.data(), 2, a, b);
  const double det = a[0] * a[3] - a[1] * a[2];
  if (!(std::abs(det) > 1e-12 * std::abs(a[0] * a[3])) || !std::isfinite(det)) return;
  const double ab = (b[0] * a[3] - a[1] * b[1]) / det, ad = (a[0] * b[1] - a[2] * b[0]) / det;
  // A negative component at the start usually means the shape is off; keep the flux split then.
  if (ab >= 0 && ad >= 0) {
    (*p)[index(Param::kBulgeA)] = ab;
    (*p)[index(Param::kDiscA)] = ad;
  }
}

bool Fitter::ready(std::span<const double> pixels, std::span<const double> weight, WeightKind kind, FitResult* r,
                   std::uint32_t* flags) {
  if (!psf_) {
    r->status = FitStatus::kPsfFailure;
    return false;
  }
  const FitStatus input = prepare_weights(pixels, weight, kind, flags);
  if (input != FitStatus::kOk) {
    r->status = input;
    r->flags = *flags;
    return false;
  }
  return true;
}

FitResult Fitter::fit(std::span<const double> pixels, std::span<const double> weight, WeightKind kind) {
  std::uint32_t flags = 0;
  FitResult r;
  if (!ready(pixels, weight, kind, &r, &flags)) return r;
  const ParamVector start = start_from_prepared(&flags);
  return run(start, flags);
}

FitResult Fitter::fit_from(std::span<const double> pixels, std::span<const double> weight, const ParamVector& start) {
  std::uint32_t flags = 0;
  FitResult r;
  if (!ready(pixels, weight, WeightKind::kInverseVariance, &r, &flags)) return r;
  return run(units_.to_internal(start), flags);
}

// The stamp's problem as the solve drives it: the free parameters, or (projected) the shape ones
// with the amplitudes solved linearly; drawn with the renderer or its surrogate.
class Fitter::Solving final : public SolveProblem {
 public:
  Solving(Fitter& f, const ParamVector& start) : f_(f), start_(start) {}
  int num_pixels() const override { return active().num_pixels(); }
  double negligible_chi2() const override { return active().negligible_chi2(); }
  bool chi2(const LmVector& x, double* chi2) override { return active().chi2(x, chi2); }
  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    return active().normal_equations(x, chi2, alpha, beta);
  }
  void use_surrogates(bool on) override { f_.active_ = on ? f_.renderer_->surrogate() : f_.renderer_.get(); }
  void restart() override {
    f_.problem_->reset(start_);
    f_.projected_->reset(start_);
  }
  int extra_evaluations() const override { return f_.project_ ? f_.projected_->extra_renders() : 0; }
  // x as every free parameter (internal units); alpha over them (projected: from the last images).
  bool expand(LmVector* x, LmMatrix* alpha) override {
    if (f_.project_ ? !f_.projected_->finish(*x, &p_, alpha) : !f_.problem_->expand(*x, &p_)) return false;
    x->resize(f_.num_free_);
    for (int k = 0; k < f_.num_free_; ++k) (*x)[k] = p_[index(f_.free_[k])];
    return true;
  }
  const ParamVector& params() const { return p_; }  // after expand: the full vector (internal units)

 private:
  LeastSquaresProblem& active() const {
    return f_.project_ ? static_cast<LeastSquaresProblem&>(*f_.projected_) : *f_.problem_;
  }
  Fitter& f_;
  ParamVector start_;
  ParamVector p_{};
};

FitResult Fitter::run(const ParamVector& start, std::uint32_t flags) {
  FitResult r;
  problem_->reset(start);
  projected_->reset(start);
  // The solver's variables: every free parameter, or (projected) the shape ones.
  const int nx = project_ ? num_shape_ : num_free_;
  LmVector x0(nx);
  LmUnits units{units_.chi2(), LmVector(nx)};
  for (int j = 0; j < nx; ++j) {
    const Param q = free_[project_ ? shape_[j] : j];
    x0[j] = start[index(q)];
    units.param[j] = units_.of(q);
  }
  Solving problem(*this, start);
  SolveResult solved;
  if (!solve(problem, x0, options_, units, renderer_->surrogate() != nullptr, &r, &solved)) {
    r.flags = flags;
    return r;
  }
  // The S/N's signal, sum w m^2 of the best model: none without weights.
  SolvedBand band{.band = 0, .params = problem.params()};
  if (!(flags & kFlagUnweighted)) {
    double s2 = 0;
    const auto& m = problem_->jacobian_model();
    for (std::size_t i = 0; i < m.size(); ++i) s2 += weight_[i] * m[i] * m[i];
    band.signal = s2;
  }
  assemble_fit_result({.solved = solved,
                       .free = std::span<const Param>(free_.data(), static_cast<std::size_t>(num_free_)),
                       .bands = std::span<const SolvedBand>(&band, 1),
                       .units = units_,
                       .renderer = *renderer_,
                       .ellipticity_mirror = options_.model.ellipticity_mirror,
                       .lower = &lower_,
                       .upper = &upper_,
                       .flags = flags},
                      {}, &r);
  return r;
}

}  // namespace stampede
