// The one assembly of a FitResult from a solve; see fit_result_assembly.hpp.
#include "engine/fit/fit_result_assembly.hpp"

#include <cmath>

namespace stampede {
namespace {

bool is_amplitude(Param p) { return p == Param::kBulgeA || p == Param::kDiscA; }

}  // namespace

void assemble_fit_result(const SolvedFit& fit, std::span<BandFit> band_fits, FitResult* r) {
  const FitUnits& units = fit.units;
  const SolveResult& solved = fit.solved;
  const bool per_band = fit.bands.size() > 1;
  // The shape is every band's; the first band's vector stands for it.
  const ParamVector& p = fit.bands.front().params;
  std::uint32_t flags = fit.flags;
  if (!solved.cov_ok) flags |= kFlagNoErrors;
  // cov is in internal units: chi2 = units.chi2() chi2_internal, so
  // cov(x_data) = unit_k unit_l cov(x_internal) / units.chi2().
  for (std::size_t k = 0; k < fit.free.size(); ++k) {
    const Param q = fit.free[k];
    const int i = index(q);
    const int kk = static_cast<int>(k);
    if (solved.cov_ok && !(per_band && is_amplitude(q))) r->errors[i] = units.error(q, solved.cov(kk, kk));
    if (fit.lower && fit.upper) {
      const double unit = units.of(q);
      if (std::abs(p[i] - (*fit.lower)[i] / unit) < 1e-6 || std::abs(p[i] - (*fit.upper)[i] / unit) < 1e-6)
        flags |= kFlagAtBound;
    }
  }
  // Report the effective (mirrored, softened) values the model was drawn with, in data units.
  if (std::hypot(p[index(Param::kE1)], p[index(Param::kE2)]) > fit.ellipticity_mirror) flags |= kFlagMirrored;
  ParamVector effective{};
  fit.renderer.effective_params(p, &effective);
  r->params = units.to_data(effective);
  r->e1_err = r->errors[index(Param::kE1)];
  r->e2_err = r->errors[index(Param::kE2)];
  // Fluxes and signal: the first band's, plus the others'.
  double signal = NAN;
  for (std::size_t s = 0; s < fit.bands.size(); ++s) {
    const SolvedBand& band = fit.bands[s];
    double bulge_flux = NAN, disc_flux = NAN;
    fit.renderer.component_fluxes(band.params, &bulge_flux, &disc_flux);
    bulge_flux *= units.data, disc_flux *= units.data;
    if (s == 0) {
      r->bulge_flux = bulge_flux, r->disc_flux = disc_flux;
      signal = band.signal;
    } else {
      r->bulge_flux += bulge_flux, r->disc_flux += disc_flux;
      signal += band.signal;
    }
    if (per_band && !band_fits.empty()) {
      BandFit& out = band_fits[static_cast<std::size_t>(band.band)];
      ParamVector band_effective{};
      fit.renderer.effective_params(band.params, &band_effective);
      out.bulge_a = band_effective[index(Param::kBulgeA)] * units.data;
      out.disc_a = band_effective[index(Param::kDiscA)] * units.data;
      out.bulge_flux = bulge_flux, out.disc_flux = disc_flux;
      out.flux = bulge_flux + disc_flux;
      out.snr = std::sqrt(band.signal * units.chi2());
    }
  }
  if (per_band) r->params[index(Param::kBulgeA)] = r->params[index(Param::kDiscA)] = NAN;
  r->flux = r->bulge_flux + r->disc_flux;
  r->chi2 = solved.chi2 * units.chi2();
  r->likelihood = -0.5 * r->chi2;
  r->snr = std::sqrt(signal * units.chi2());
  r->status = status_of_stop(solved.summary.reason, &flags);
  r->flags = flags;
}

}  // namespace stampede
