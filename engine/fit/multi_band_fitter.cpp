// Joint fits over bands; see multi_band_fitter.hpp.
#include "engine/fit/multi_band_fitter.hpp"

#include "engine/fit/joint_fit_solve.hpp"
#include "engine/fit/projected_joint_problem.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace stampede {
namespace {

bool is_amplitude(Param p) { return p == Param::kBulgeA || p == Param::kDiscA; }

}  // namespace

class MultiBandFitter::Problem final : public SolveProblem {
 public:
  explicit Problem(MultiBandFitter& f)
      : cutouts_([&f](int box) -> Renderer& { return f.renderer_for(box); },
                 kernels::least_squares_kernels(f.options_.render.simd)) {}

  // The fit's cutouts, the full parameter vector of fixed values, the single-band free list and
  // the slot of each band in the solver's vector (-1: not fitted).
  void reset(std::span<const Observation> epochs, const ParamVector& base, std::span<const Param> free,
             std::span<const int> slot_of_band, int slots) {
    cutouts_.reset(epochs);
    base_ = base;
    free_ = free;
    slot_of_band_.assign(slot_of_band.begin(), slot_of_band.end());
    slots_ = slots;
    n_shape_ = n_amp_ = 0;
    for (std::size_t a = 0; a < free.size(); ++a) {
      if (is_amplitude(free[a]))
        local_[a] = {false, n_amp_++};
      else
        local_[a] = {true, n_shape_++};
    }
  }
  int size() const { return n_shape_ + slots_ * n_amp_; }
  int num_pixels() const override { return cutouts_.pixels(); }
  double negligible_chi2() const override { return cutouts_.negligible_chi2(); }

  // The solver's index of single-band free parameter a in the band at `slot`.
  int global(std::size_t a, int slot) const {
    return local_[a].shape ? local_[a].k : n_shape_ + slot * n_amp_ + local_[a].k;
  }
  // Band slot s's full parameter vector at x.
  ParamVector full(const LmVector& x, int slot) const {
    ParamVector p = base_;
    for (std::size_t a = 0; a < free_.size(); ++a) p[index(free_[a])] = x[global(a, slot)];
    return p;
  }
  // x from a shape start and per-slot amplitude starts.
  LmVector vector_of(const ParamVector& shape, std::span<const ParamVector> amplitudes) const {
    LmVector x(size());
    for (std::size_t a = 0; a < free_.size(); ++a)
      for (int s = 0; s < slots_; ++s)
        x[global(a, s)] = (local_[a].shape ? shape : amplitudes[static_cast<std::size_t>(s)])[index(free_[a])];
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
          (*alpha)(g[static_cast<std::size_t>(a)], g[static_cast<std::size_t>(b)]) += sums_.alpha[static_cast<std::size_t>(a * nf + b)];
      }
    }
    *chi2 = sum;
    return std::isfinite(sum);
  }

  // sum w m^2 of slot s's cutouts at the last normal_equations.
  double signal(int slot) const { return signal_[static_cast<std::size_t>(slot)]; }
  void use_surrogates(bool on) override { cutouts_.use_surrogates(on); }

 private:
  struct Local {
    bool shape = true;
    int k = 0;  // index among the shape parameters, or among one band's amplitudes
  };

  int slot_of(std::size_t c) const { return slot_of_band_[static_cast<std::size_t>(cutouts_.epochs()[c].band)]; }

  JointCutouts cutouts_;
  ParamVector base_{};
  std::span<const Param> free_;
  std::array<Local, kNumParams> local_{};
  std::vector<int> slot_of_band_;
  int slots_ = 0, n_shape_ = 0, n_amp_ = 0;
  std::array<double, kMaxBands> signal_{};
  CutoutSums sums_;
};

MultiBandFitter::MultiBandFitter(const FitterOptions& options)
    : options_(options),
      single_(options),
      problem_(std::make_unique<Problem>(*this)),
      project_(projects_amplitudes(options)),
      projected_(std::make_unique<ProjectedJointProblem>([this](int box) -> Renderer& { return renderer_for(box); },
                                                         kernels::least_squares_kernels(options.render.simd))) {}

MultiBandFitter::~MultiBandFitter() = default;

MultiBandFitResult MultiBandFitter::fit(std::span<const Observation> epochs, int n_bands, std::size_t first) {
  if (n_bands < 1 || n_bands > kMaxBands)
    throw std::invalid_argument("MultiBandFitter::fit: " + std::to_string(n_bands) + " bands (1.." +
                                std::to_string(kMaxBands) + ")");
  if (first >= epochs.size()) throw std::invalid_argument("MultiBandFitter::fit: no epoch to start from");
  MultiBandFitResult out;
  out.bands.resize(static_cast<std::size_t>(n_bands));
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    const int b = epochs[k].band;
    if (b < 0 || b >= n_bands)
      throw std::invalid_argument("MultiBandFitter::fit: cutout " + std::to_string(k) + " has band " + std::to_string(b) +
                                  " of " + std::to_string(n_bands));
    ++out.bands[static_cast<std::size_t>(b)].n_epochs;
  }
  std::vector<int> slot_of_band(static_cast<std::size_t>(n_bands), -1), band_of_slot;
  for (int b = 0; b < n_bands; ++b)
    if (out.bands[static_cast<std::size_t>(b)].n_epochs > 0) {
      slot_of_band[static_cast<std::size_t>(b)] = static_cast<int>(band_of_slot.size());
      band_of_slot.push_back(b);
    }
  FitResult& r = out.fit;
  if (band_of_slot.size() == 1) {
    // One band: the multi-epoch fit itself (a one-band run's rows are then the single tile's).
    r = single_.fit(epochs, first);
    BandFit& band = out.bands[static_cast<std::size_t>(band_of_slot[0])];
    band.bulge_a = r.params[index(Param::kBulgeA)], band.disc_a = r.params[index(Param::kDiscA)];
    band.bulge_flux = r.bulge_flux, band.disc_flux = r.disc_flux, band.flux = r.flux, band.snr = r.snr;
    if (n_bands > 1) r.params[index(Param::kBulgeA)] = r.params[index(Param::kDiscA)] = NAN;
    return out;
  }
  r.status = check_cutouts(epochs, "MultiBandFitter::fit");
  if (r.status != FitStatus::kOk) return out;
  std::array<Param, kNumParams> free_all{};
  const int nf = options_.params.free_params(&free_all);
  const std::span<const Param> free(free_all.data(), static_cast<std::size_t>(nf));
  const int slots = static_cast<int>(band_of_slot.size());
  // The shape from every band's cutouts (MultiEpochFitter::joint_start); a projected fit solves
  // the amplitudes at every shape, a joint one starts each band's from its own cutouts' start at
  // that radius (flux ~ A r^2).
  std::uint32_t flags = 0;
  const ParamVector start = single_.joint_start(epochs, first, &flags);
  std::vector<ParamVector> amplitude_start(static_cast<std::size_t>(slots), start);
  std::vector<Observation> band;
  for (int s = 0; s < slots && !project_; ++s) {
    band.clear();
    for (const Observation& e : epochs)
      if (e.band == band_of_slot[static_cast<std::size_t>(s)]) band.push_back(e);
    ParamVector& a = amplitude_start[static_cast<std::size_t>(s)];
    a = single_.joint_start(band, 0, &flags);
    const double ratio = a[index(Param::kRadius)] / start[index(Param::kRadius)];
    a[index(Param::kBulgeA)] *= ratio * ratio, a[index(Param::kDiscA)] *= ratio * ratio;
  }
  problem_->reset(epochs, start, free, slot_of_band, slots);
  if (problem_->num_pixels() == 0) {
    r.status = FitStatus::kNoData;
    return out;
  }
  const LmVector x0 = problem_->vector_of(start, amplitude_start);
  const bool coarse = any_surrogate(epochs, [this](int box) -> Renderer& { return renderer_for(box); });
  SolveResult solved;
  if (project_) {
    slot_of_cutout_.clear();
    for (const Observation& e : epochs) slot_of_cutout_.push_back(slot_of_band[static_cast<std::size_t>(e.band)]);
    projected_->reset(epochs, start, free, slot_of_cutout_, slots, [this](std::size_t a, int s) { return problem_->global(a, s); },
                      problem_->size());
    if (!solve(*projected_, projected_->shape_of(x0), options_, LmUnits{}, coarse, &r, &solved)) return out;
  } else if (!solve(*problem_, x0, options_, LmUnits{}, coarse, &r, &solved)) {
    return out;
  }
  const LmSummary& sum = solved.summary;
  const double chi2 = solved.chi2;
  const bool cov_ok = solved.cov_ok;
  const LmMatrix& cov = solved.cov;
  if (!cov_ok) flags |= kFlagNoErrors;
  for (std::size_t a = 0; a < free.size(); ++a)
    if (cov_ok && !is_amplitude(free[a])) {
      const int g = problem_->global(a, 0);
      r.errors[index(free[a])] = std::sqrt(cov(g, g));
    }
  const ParamVector p0 = problem_->full(sum.x, 0);
  if (std::hypot(p0[index(Param::kE1)], p0[index(Param::kE2)]) > options_.model.ellipticity_mirror) flags |= kFlagMirrored;
  Renderer& any = renderer_for(epochs.front().box_size);
  any.effective_params(p0, &r.params);
  r.params[index(Param::kBulgeA)] = r.params[index(Param::kDiscA)] = NAN;
  r.e1_err = r.errors[index(Param::kE1)];
  r.e2_err = r.errors[index(Param::kE2)];
  r.bulge_flux = r.disc_flux = 0;
  double signal = 0;
  for (int s = 0; s < slots; ++s) {
    BandFit& band = out.bands[static_cast<std::size_t>(band_of_slot[static_cast<std::size_t>(s)])];
    ParamVector effective{};
    any.effective_params(problem_->full(sum.x, s), &effective);
    band.bulge_a = effective[index(Param::kBulgeA)], band.disc_a = effective[index(Param::kDiscA)];
    any.component_fluxes(problem_->full(sum.x, s), &band.bulge_flux, &band.disc_flux);
    band.flux = band.bulge_flux + band.disc_flux;
    const double band_signal = project_ ? projected_->signal(s) : problem_->signal(s);
    band.snr = std::sqrt(band_signal);
    r.bulge_flux += band.bulge_flux;
    r.disc_flux += band.disc_flux;
    signal += band_signal;
  }
  r.flux = r.bulge_flux + r.disc_flux;
  r.chi2 = chi2;
  r.likelihood = -0.5 * chi2;
  r.snr = std::sqrt(signal);
  r.status = status_of_stop(sum.reason, &flags);
  r.flags = flags;
  return out;
}

}  // namespace stampede
