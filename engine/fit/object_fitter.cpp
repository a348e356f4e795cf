// One galaxy fitted to its observations; see object_fitter.hpp.
#include "engine/fit/object_fitter.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "engine/fit/fit_result_assembly.hpp"
#include "engine/fit/joint_fit_solve.hpp"
#include "engine/fit/projected_joint_problem.hpp"
#include "engine/render/renderer_factory.hpp"
#include "kernels/moments.hpp"

namespace stampede {
namespace {

bool is_amplitude(Param p) { return p == Param::kBulgeA || p == Param::kDiscA; }

bool is_single_stamp(std::span<const Observation> observations) {
  return observations.size() == 1 && observations.front().flux_scale == 1 && observations.front().frame.unit_jacobian();
}

}  // namespace

// The joint problem over every observation, bands as slots: the free parameters in ParameterSet
// order with the first slot's amplitudes, then each further slot's free amplitudes. The solver's
// vector, chi2 and the sums are in the cutouts' units (JointCutouts::units).
class ObjectFitter::Problem final : public SolveProblem {
 public:
  explicit Problem(ObjectFitter& f)
      : cutouts_([&f](int box) -> Renderer& { return f.renderer_for(box); },
                 kernels::least_squares_kernels(f.options_.render.simd)) {}

  // The fit's observations, the full parameter vector of fixed values (data units), the free
  // parameters and the slot of each band in the solver's vector (-1: not fitted).
  void reset(std::span<const Observation> observations, const ParamVector& base, std::span<const Param> free,
             std::span<const int> slot_of_band, int slots) {
    cutouts_.reset(observations);
    base_ = cutouts_.units().to_internal(base);
    free_ = free;
    slot_of_band_ = slot_of_band;
    slots_ = slots;
    n_amp_ = 0;
    for (std::size_t a = 0; a < free.size(); ++a) amplitude_[a] = is_amplitude(free[a]) ? n_amp_++ : -1;
  }
  int size() const { return static_cast<int>(free_.size()) + (slots_ - 1) * n_amp_; }
  const FitUnits& units() const { return cutouts_.units(); }
  // The units the solver's tolerances are stated in: each variable's and chi2's data units.
  LmUnits lm_units() const {
    LmUnits u{units().chi2(), LmVector(size())};
    for (std::size_t a = 0; a < free_.size(); ++a)
      for (int s = 0; s < slots_; ++s) u.param[global(a, s)] = units().of(free_[a]);
    return u;
  }
  int num_pixels() const override { return cutouts_.pixels(); }
  double negligible_chi2() const override { return cutouts_.negligible_chi2(); }

  // The solver's index of free parameter a in the band at `slot`.
  int global(std::size_t a, int slot) const {
    return slot == 0 || amplitude_[a] < 0 ? static_cast<int>(a)
                                          : static_cast<int>(free_.size()) + (slot - 1) * n_amp_ + amplitude_[a];
  }
  // Band slot s's full parameter vector at x (internal units).
  ParamVector full(const LmVector& x, int slot) const {
    ParamVector p = base_;
    for (std::size_t a = 0; a < free_.size(); ++a) p[index(free_[a])] = x[global(a, slot)];
    return p;
  }
  // x (internal units) from a shape start and per-slot amplitude starts (data units).
  LmVector vector_of(const ParamVector& shape, std::span<const ParamVector> amplitudes) const {
    LmVector x(size());
    for (std::size_t a = 0; a < free_.size(); ++a)
      for (int s = 0; s < slots_; ++s)
        x[global(a, s)] = (amplitude_[a] < 0 ? shape : amplitudes[static_cast<std::size_t>(s)])[index(free_[a])] /
                          units().of(free_[a]);
    return x;
  }

  bool chi2(const LmVector& x, double* chi2) override {
    double sum = 0;
    for (std::size_t c = 0; c < cutouts_.epochs().size(); ++c) {
      double one = 0;
      if (!cutouts_.chi2(c, full(x, slot_of(c)), &one)) return false;
      sum += one;
    }
    *chi2 = sum;
    return std::isfinite(sum);
  }

  bool normal_equations(const LmVector& x, double* chi2, LmMatrix* alpha, LmVector* beta) override {
    const int n = size();
    const int nf = static_cast<int>(free_.size());
    alpha->setZero(n, n);
    beta->setZero(n);
    double sum = 0;
    signal_.fill(0.0);
    std::array<int, kNumParams> g{};
    for (std::size_t c = 0; c < cutouts_.epochs().size(); ++c) {
      const int slot = slot_of(c);
      for (int a = 0; a < nf; ++a) g[static_cast<std::size_t>(a)] = global(static_cast<std::size_t>(a), slot);
      if (!cutouts_.sums(c, full(x, slot), free_, &sums_)) return false;
      sum += sums_.chi2;
      signal_[static_cast<std::size_t>(slot)] += sums_.signal;
      // A band's amplitudes are its own columns; the shape's are every band's.
      for (int a = 0; a < nf; ++a) {
        (*beta)[g[static_cast<std::size_t>(a)]] += sums_.beta[static_cast<std::size_t>(a)];
        for (int b = 0; b < nf; ++b)
          (*alpha)(g[static_cast<std::size_t>(a)], g[static_cast<std::size_t>(b)]) +=
              sums_.alpha[static_cast<std::size_t>(a * nf + b)];
      }
    }
    *chi2 = sum;
    return std::isfinite(sum);
  }

  // sum w m^2 of slot s's observations at the last normal_equations (internal units).
  double signal(int slot) const { return signal_[static_cast<std::size_t>(slot)]; }
  void use_surrogates(bool on) override { cutouts_.use_surrogates(on); }

 private:
  int slot_of(std::size_t c) const { return slot_of_band_[static_cast<std::size_t>(cutouts_.epochs()[c].band)]; }

  JointCutouts cutouts_;
  ParamVector base_{};
  std::span<const Param> free_;
  std::array<int, kNumParams> amplitude_{};  // each free parameter's index among the amplitudes, -1 none
  std::span<const int> slot_of_band_;
  int slots_ = 1, n_amp_ = 0;
  std::array<double, kMaxBands> signal_{};
  CutoutSums sums_;
};

ObjectFitter::ObjectFitter(const FitterOptions& options, FftPlanning planning)
    : options_(options),
      plans_(planning),
      problem_(std::make_unique<Problem>(*this)),
      project_(projects_amplitudes(options)),
      projected_(std::make_unique<ProjectedJointProblem>([this](int box) -> Renderer& { return renderer_for(box); },
                                                         kernels::least_squares_kernels(options.render.simd))) {}

ObjectFitter::~ObjectFitter() = default;

Renderer& ObjectFitter::renderer_for(int box_size) {
  auto it = renderers_.find(box_size);
  if (it == renderers_.end()) {
    RenderOptions ro = options_.render;
    ro.stamp_size = box_size;
    it = renderers_.emplace(box_size, make_renderer(options_.renderer, ro, options_.model, plans_)).first;
  }
  return *it->second;
}

Fitter& ObjectFitter::stamp_fitter_for(int box_size) {
  auto it = stamp_fitters_.find(box_size);
  if (it == stamp_fitters_.end()) {
    FitterOptions o = options_;
    o.render.stamp_size = box_size;
    it = stamp_fitters_.emplace(box_size, std::make_unique<Fitter>(o, nullptr, plans_)).first;
  }
  return *it->second;
}

ParamVector ObjectFitter::sky_start(const Observation& e, std::uint32_t* flags) {
  Fitter& f = stamp_fitter_for(e.box_size);
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

ParamVector ObjectFitter::joint_start(std::span<const Observation> epochs, std::size_t first, std::uint32_t* flags) {
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
        for (int j = 0; j < 2; ++j)
          S[i][j] = J[i][0] * (M[0][0] * J[j][0] + M[0][1] * J[j][1]) + J[i][1] * (M[1][0] * J[j][0] + M[1][1] * J[j][1]);
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

FitResult ObjectFitter::fit(std::span<const Observation> observations, int n_bands, std::span<BandFit> bands,
                            std::size_t first) {
  if (n_bands < 1 || n_bands > kMaxBands)
    throw std::invalid_argument("ObjectFitter::fit: " + std::to_string(n_bands) + " bands (1.." +
                                std::to_string(kMaxBands) + ")");
  if (!bands.empty() && bands.size() != static_cast<std::size_t>(n_bands))
    throw std::invalid_argument("ObjectFitter::fit: " + std::to_string(bands.size()) + " band results for " +
                                std::to_string(n_bands) + " bands");
  if (first >= observations.size()) throw std::invalid_argument("ObjectFitter::fit: no observation to start from");
  std::array<int, kMaxBands> count{};
  for (std::size_t k = 0; k < observations.size(); ++k) {
    const int b = observations[k].band;
    if (b < 0 || b >= n_bands)
      throw std::invalid_argument("ObjectFitter::fit: observation " + std::to_string(k) + " has band " +
                                  std::to_string(b) + " of " + std::to_string(n_bands));
    ++count[static_cast<std::size_t>(b)];
  }
  slot_of_band_.assign(static_cast<std::size_t>(n_bands), -1);
  band_of_slot_.clear();
  for (int b = 0; b < n_bands; ++b) {
    if (!bands.empty()) {
      bands[static_cast<std::size_t>(b)] = BandFit();
      bands[static_cast<std::size_t>(b)].n_epochs = count[static_cast<std::size_t>(b)];
    }
    if (count[static_cast<std::size_t>(b)] > 0) {
      slot_of_band_[static_cast<std::size_t>(b)] = static_cast<int>(band_of_slot_.size());
      band_of_slot_.push_back(b);
    }
  }
  const int slots = static_cast<int>(band_of_slot_.size());
  FitResult r;
  if (slots == 1) {
    const Observation& e = observations.front();
    if (is_single_stamp(observations)) {
      // A single stamp: the single-stamp fit (amplitude projection, scaled units; without a PSF it
      // reports kPsfFailure), so a MEDS row of one such cutout is the grid path's row bit for bit;
      // only the centroid is moved to the frame's reference.
      Fitter& f = stamp_fitter_for(e.box_size);
      f.set_psf(e.psf);
      r = f.fit(e.pixels, e.weight, e.weight_kind);
      r.params[index(Param::kX0)] -= e.frame.x_ref;
      r.params[index(Param::kY0)] -= e.frame.y_ref;
    } else if (!observations[first].psf) {
      r.status = FitStatus::kPsfFailure;
    } else {
      std::uint32_t flags = 0;
      const ParamVector start = joint_start(observations, first, &flags);
      amplitude_start_.assign(1, start);
      r = fit_joint(observations, start, amplitude_start_, slot_of_band_, band_of_slot_, {});
      r.flags |= flags;
    }
    if (!bands.empty()) {
      BandFit& band = bands[static_cast<std::size_t>(band_of_slot_[0])];
      band.bulge_a = r.params[index(Param::kBulgeA)], band.disc_a = r.params[index(Param::kDiscA)];
      band.bulge_flux = r.bulge_flux, band.disc_flux = r.disc_flux, band.flux = r.flux, band.snr = r.snr;
    }
    if (n_bands > 1) r.params[index(Param::kBulgeA)] = r.params[index(Param::kDiscA)] = NAN;
    return r;
  }
  r.status = check_cutouts(observations, "ObjectFitter::fit");
  if (r.status != FitStatus::kOk) return r;
  // The shape from every band's observations; a projected fit solves the amplitudes at every
  // shape, a joint one starts each band's from its own observations' start at that radius
  // (flux ~ A r^2).
  std::uint32_t flags = 0;
  const ParamVector start = joint_start(observations, first, &flags);
  amplitude_start_.assign(static_cast<std::size_t>(slots), start);
  for (int s = 0; s < slots && !project_; ++s) {
    band_observations_.clear();
    for (const Observation& e : observations)
      if (e.band == band_of_slot_[static_cast<std::size_t>(s)]) band_observations_.push_back(e);
    ParamVector& a = amplitude_start_[static_cast<std::size_t>(s)];
    a = joint_start(band_observations_, 0, &flags);
    const double ratio = a[index(Param::kRadius)] / start[index(Param::kRadius)];
    a[index(Param::kBulgeA)] *= ratio * ratio, a[index(Param::kDiscA)] *= ratio * ratio;
  }
  r = fit_joint(observations, start, amplitude_start_, slot_of_band_, band_of_slot_, bands);
  r.flags |= flags;
  return r;
}

FitResult ObjectFitter::fit_from(std::span<const Observation> observations, const ParamVector& start) {
  slot_of_band_.assign(1, 0);
  band_of_slot_.assign(1, 0);
  for (const Observation& e : observations)
    if (e.band != 0) throw std::invalid_argument("ObjectFitter::fit_from: one band's observations only");
  amplitude_start_.assign(1, start);
  return fit_joint(observations, start, amplitude_start_, slot_of_band_, band_of_slot_, {});
}

FitResult ObjectFitter::fit_joint(std::span<const Observation> observations, const ParamVector& start,
                                  std::span<const ParamVector> amplitude_start, std::span<const int> slot_of_band,
                                  std::span<const int> band_of_slot, std::span<BandFit> bands) {
  FitResult r;
  std::array<Param, kNumParams> free_all{};
  const int nf = options_.params.free_params(&free_all);
  const std::span<const Param> free(free_all.data(), static_cast<std::size_t>(nf));
  r.status = check_cutouts(observations, "ObjectFitter::fit");
  if (r.status != FitStatus::kOk) return r;
  for (const Observation& e : observations)
    if (e.weight_kind != WeightKind::kInverseVariance)
      throw std::invalid_argument("ObjectFitter::fit: a joint fit's observations need inverse-variance weights");
  const int slots = static_cast<int>(band_of_slot.size());
  problem_->reset(observations, start, free, slot_of_band, slots);
  if (problem_->num_pixels() == 0) {
    r.status = FitStatus::kNoData;
    return r;
  }
  // The fit runs in the object's units (the start converted exactly, powers of two), so the
  // solver's damping and tolerances see the same numbers whatever the data's scale; everything
  // reported below is back in data units.
  const FitUnits& units = problem_->units();
  const LmVector x0 = problem_->vector_of(start, amplitude_start);
  const bool coarse = any_surrogate(observations, [this](int box) -> Renderer& { return renderer_for(box); });
  SolveResult solved;
  if (project_) {
    slot_of_cutout_.clear();
    for (const Observation& e : observations) slot_of_cutout_.push_back(slot_of_band[static_cast<std::size_t>(e.band)]);
    projected_->reset(observations, start, free, slot_of_cutout_, slots,
                      [this](std::size_t a, int s) { return problem_->global(a, s); }, problem_->size());
    // The solver's vector is the shape alone: only chi2 has a unit.
    if (!solve(*projected_, projected_->shape_of(x0), options_, LmUnits{units.chi2(), LmVector()}, coarse, &r, &solved))
      return r;
  } else if (!solve(*problem_, x0, options_, problem_->lm_units(), coarse, &r, &solved)) {
    return r;
  }
  // Each band's optimum and signal (sum w m^2 over its cutouts).
  std::array<SolvedBand, kMaxBands> solved_bands;
  for (int s = 0; s < slots; ++s)
    solved_bands[static_cast<std::size_t>(s)] = {.band = band_of_slot[static_cast<std::size_t>(s)],
                                                  .params = problem_->full(solved.summary.x, s),
                                                  .signal = project_ ? projected_->signal(s) : problem_->signal(s)};
  assemble_fit_result({.solved = solved,
                       .free = free,
                       .bands = std::span<const SolvedBand>(solved_bands.data(), static_cast<std::size_t>(slots)),
                       .units = units,
                       .renderer = renderer_for(observations.front().box_size),
                       .ellipticity_mirror = options_.model.ellipticity_mirror},
                      bands, &r);
  return r;
}

}  // namespace stampede
