// GREAT08-like simulations; see great08_sim.hpp.
#include "engine/sim/great08_sim.hpp"

#include <cmath>
#include <complex>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "engine/common/parallel_indices.hpp"
#include "engine/common/random_stream.hpp"
#include "kernels/math/lensing.hpp"

namespace stampede {
namespace {

// Purposes of the random streams (the last key of each).
enum StreamPurpose : std::uint64_t { kShearStream = 1, kGalaxyStream = 2, kNoiseStream = 3 };

// Intrinsic e: each component N(0, sigma), redrawn until |e| < e_max.
std::complex<double> draw_ellipticity(RandomStream& rng, double sigma, double e_max) {
  for (int attempt = 0; attempt < 10000; ++attempt) {
    const std::complex<double> e(sigma * rng.normal(), sigma * rng.normal());
    if (std::abs(e) < e_max) return e;
  }
  return 0.0;  // unreachable for valid options (P(|e| < e_max) > 1e-4 is checked)
}

}  // namespace

const char* sim_galaxy_type_name(SimGalaxyType t) {
  switch (t) {
    case SimGalaxyType::kBulgeDisc:
      return "bd";
    case SimGalaxyType::kBulgePlusDisc:
      return "b+d";
    case SimGalaxyType::kBulge:
      return "bulge";
    case SimGalaxyType::kDisc:
      return "disc";
  }
  return "?";
}

bool parse_sim_galaxy_type(const std::string& name, SimGalaxyType* out) {
  for (SimGalaxyType t :
       {SimGalaxyType::kBulgeDisc, SimGalaxyType::kBulgePlusDisc, SimGalaxyType::kBulge, SimGalaxyType::kDisc})
    if (name == sim_galaxy_type_name(t)) {
      *out = t;
      return true;
    }
  return false;
}

PsfModel Great08SimOptions::default_psf() {
  PsfModel p;
  p.kind = PsfKind::kMoffat;
  p.moffat = {3.0, 2.85, 0.0, 0.05, 0.0};
  return p;
}

bool Great08SimOptions::IsValid(std::string* why) const {
  std::ostringstream m;
  std::string psf_why;
  if (sets < 1 || sets > 10000)
    m << "sets " << sets << ": must be in [1, 10000]";
  else if (grid < 1 || grid > 1000)
    m << "grid " << grid << ": must be in [1, 1000]";
  else if (stamp_size < 8 || stamp_size > 512)
    m << "stamp_size " << stamp_size << ": must be in [8, 512]";
  else if (!(snr > 0 && std::isfinite(snr)))
    m << "snr " << snr << ": must be positive";
  else if (!(noise_sigma > 0 && std::isfinite(noise_sigma)))
    m << "noise_sigma " << noise_sigma << ": must be positive";
  else if (!(size_ratio > 1.0 && size_ratio <= 10.0))
    m << "size_ratio " << size_ratio << ": Rgp/Rp must be in (1, 10]";
  else if (psf.kind == PsfKind::kImage)
    m << "psf: the simulator draws analytic PSFs only (moffat, airy)";
  else if (!psf.IsValid(&psf_why))
    m << psf_why;
  else if (!(psf.fwhm() <= stamp_size))  // a PSF wider than the stamp draws nothing to measure, and slowly
    m << "psf_fwhm " << psf.fwhm() << ": the PSF's FWHM must be at most the stamp (" << stamp_size << " pixels)";
  // Below ~1.5 px the exact pixel-integrated draw's alias sum grows without bound in practice
  // (FWHM 1.1 with --size 2.85: a minute per stamp), and such a PSF is far below Nyquist sampling.
  else if (!(psf.fwhm() >= 1.5))
    m << "psf_fwhm " << psf.fwhm() << ": the simulator draws PSFs of FWHM >= 1.5 pixels (undersampled PSFs are "
      << "not supported)";
  else if (!(e_sigma >= 0 && e_sigma <= 1))
    m << "e_sigma " << e_sigma << ": must be in [0, 1]";
  else if (!(e_max > 0 && e_max <= 0.95))
    m << "e_max " << e_max << ": must be in (0, 0.95]";
  else if (e_sigma > 0 && e_max < 0.01 * e_sigma)
    m << "e_max " << e_max << ": too small for e_sigma " << e_sigma;
  else if (!(shear_max >= 0 && shear_max <= 0.2))
    m << "shear_max " << shear_max << ": must be in [0, 0.2]";
  else if (fixed_shear && !(std::abs(shear1) <= 0.2 && std::abs(shear2) <= 0.2))
    m << "shear " << shear1 << "," << shear2 << ": each component must be in [-0.2, 0.2]";
  else if (!(centre_offset >= 0 && centre_offset <= 0.25 * stamp_size))
    m << "centre_offset " << centre_offset << ": must be in [0, stamp/4]";
  else if (!(bulge_fraction_min >= 0 && bulge_fraction_min <= bulge_fraction_max && bulge_fraction_max <= 1))
    m << "bulge_fraction " << bulge_fraction_min << "," << bulge_fraction_max << ": need 0 <= min <= max <= 1";
  else if (!(bd_radius_ratio >= 0.1 && bd_radius_ratio <= 10))
    m << "bd_radius_ratio " << bd_radius_ratio << ": must be in [0.1, 10]";
  else if (!(bd_misalignment_deg >= 0 && bd_misalignment_deg <= 90))
    m << "bd_misalignment " << bd_misalignment_deg << ": must be in [0, 90] degrees";
  else if (!(bd_offset >= 0 && bd_offset <= 5))
    m << "bd_offset " << bd_offset << ": must be in [0, 5] pixels";
  if (m.str().empty()) return true;
  if (why) *why = m.str();
  return false;
}

double Great08Simulator::bulge_radius_ratio() const {
  return options_.galaxy_type == SimGalaxyType::kBulgePlusDisc ? options_.bd_radius_ratio : 1.0;
}

std::vector<SimComponent> Great08Simulator::round_components(double bulge_fraction, double disc_hlr) const {
  std::vector<SimComponent> c;
  if (bulge_fraction > 0) c.push_back({4.0, bulge_fraction, disc_hlr * bulge_radius_ratio(), 0, 0, 0, 0});
  if (bulge_fraction < 1) c.push_back({1.0, 1 - bulge_fraction, disc_hlr, 0, 0, 0, 0});
  return c;
}

double Great08Simulator::half_light_radius(double bulge_fraction) const {
  const double target = options_.size_ratio * psf_fwhm_;
  auto excess = [&](double h) {
    const std::vector<SimComponent> round = round_components(bulge_fraction, h);
    return (fwhm_solver_ ? (*fwhm_solver_)(round) : renderer_->round_fwhm(round)) - target;
  };
  // Bracket in h (FWHM grows monotonically with h), then Illinois regula falsi.
  double lo = 1e-3, hi = 1.0;
  double f_lo = excess(lo), f_hi = excess(hi);
  if (f_lo >= 0) throw std::invalid_argument("size_ratio reached by a point source: raise size_ratio");
  while (f_hi < 0) {
    lo = hi;
    f_lo = f_hi;
    hi *= 2;
    if (hi > 100) throw std::invalid_argument("size_ratio needs a half-light radius above 100 pixels");
    f_hi = excess(hi);
  }
  int side = 0;
  for (int it = 0; it < 200 && hi - lo > 1e-11 * hi; ++it) {
    const double h = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    const double f = excess(h);
    if (f == 0) return h;
    if ((f < 0) == (f_lo < 0)) {
      lo = h;
      f_lo = f;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = h;
      f_hi = f;
      if (side == 1) f_lo *= 0.5;
      side = 1;
    }
  }
  return 0.5 * (lo + hi);
}

Great08Simulator::Great08Simulator(const Great08SimOptions& options) : options_(options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  // A round-only renderer (cheap tables) finds the largest radius; the real one covers it at every
  // ellipticity drawn (|e_obs| < (e_max + g) / (1 + e_max g)).
  SimRenderer::Options ro;
  ro.max_e = 0.0;
  ro.max_half_light_radius = 30.0;
  renderer_ = std::make_unique<SimRenderer>(options.psf, ro);
  psf_fwhm_ = renderer_->round_fwhm({});
  double largest = 0;
  const bool two =
      options.galaxy_type == SimGalaxyType::kBulgeDisc || options.galaxy_type == SimGalaxyType::kBulgePlusDisc;
  const double bf_single = options.galaxy_type == SimGalaxyType::kBulge ? 1.0 : 0.0;
  for (double bf : two ? std::vector<double>{options.bulge_fraction_min, options.bulge_fraction_max}
                       : std::vector<double>{bf_single}) {
    const double h = half_light_radius(bf);
    largest = std::max({largest, h, h * bulge_radius_ratio()});
  }
  const double g = options.fixed_shear ? std::hypot(options.shear1, options.shear2) : std::sqrt(2.0) * options.shear_max;
  ro.max_e = std::min(0.98, (options.e_max + g) / (1 + options.e_max * g));
  ro.max_half_light_radius = 1.1 * largest;
  if (ro.max_half_light_radius > 100) throw std::invalid_argument("size_ratio needs galaxies larger than 100 pixels");
  renderer_ = std::make_unique<SimRenderer>(options.psf, ro);
  fwhm_solver_ = std::make_unique<RoundFwhmSolver>(*renderer_, true);  // every galaxy's radius is solved
}

SimSet Great08Simulator::simulate_set(int k) const {
  const Great08SimOptions& o = options_;
  SimSet set;
  set.index = k;
  // Every stream is keyed by the drawn set: with shear pairs, set 2j+1 redraws set 2j under -g.
  const std::uint64_t drawn = static_cast<std::uint64_t>(o.shear_pairs ? k & ~1 : k);
  const double shear_sign = o.shear_pairs && (k & 1) ? -1.0 : 1.0;
  RandomStream shear_rng({o.seed, drawn, kShearStream});
  set.shear1 = shear_sign * shear_rng.uniform(-o.shear_max, o.shear_max);
  set.shear2 = shear_sign * shear_rng.uniform(-o.shear_max, o.shear_max);
  if (o.fixed_shear) set.shear1 = shear_sign * o.shear1, set.shear2 = shear_sign * o.shear2;
  set.noise_seed = o.noise_free ? 0 : RandomStream({o.seed, drawn, kNoiseStream}).next() | 1;
  const int s = o.stamp_size;
  set.width = o.grid * s;
  set.image.assign(static_cast<std::size_t>(set.width) * set.width, 0.0);
  const long long n_objects = static_cast<long long>(o.grid) * o.grid;
  set.truth.resize(static_cast<std::size_t>(n_objects));
  const std::complex<double> g(set.shear1, set.shear2);
  const double centre = 0.5 * (s - 1);

  struct Scratch {
    std::unique_ptr<SimWorkspace> workspace = std::make_unique<SimWorkspace>();
    std::vector<double> stamp;
  };
  // A group is a ring pair, or with noise pairs a ring pair drawn twice with opposite noise.
  const int group = o.noise_pairs ? 4 : 2;
  const long long n_groups = (n_objects + group - 1) / group;
  double sm[3];  // positions are sheared like the profiles: by the area-preserving matrix of g
  shear_matrix(set.shear1, set.shear2, sm);
  // Single-component galaxies all have the same size: calibrate it once, not per pair.
  const bool fixed_fraction = o.galaxy_type == SimGalaxyType::kBulge || o.galaxy_type == SimGalaxyType::kDisc;
  const double fixed_hlr = fixed_fraction ? half_light_radius(o.galaxy_type == SimGalaxyType::kBulge ? 1.0 : 0.0) : NAN;
  // Each pair writes only its own stamps and truth rows.
  parallel_indices(
      n_groups, 1,
      [&] {
        Scratch scratch;
        scratch.stamp.resize(static_cast<std::size_t>(s) * s);
        return scratch;
      },
      [&](Scratch& scratch, long long pair) {  // pair: the group's index
        SimWorkspace& ws = *scratch.workspace;
        std::vector<double>& stamp = scratch.stamp;
        RandomStream rng({o.seed, drawn, static_cast<std::uint64_t>(pair), kGalaxyStream});
        double bf = 0;
        switch (o.galaxy_type) {
          case SimGalaxyType::kBulge:
            bf = 1;
            break;
          case SimGalaxyType::kDisc:
            bf = 0;
            break;
          default:
            bf = rng.uniform(o.bulge_fraction_min, o.bulge_fraction_max);
        }
        const std::complex<double> e_disc = draw_ellipticity(rng, o.e_sigma, o.e_max);
        std::complex<double> e_bulge = e_disc;
        std::complex<double> offset_bulge = 0;
        const double dx = rng.uniform(-o.centre_offset, o.centre_offset);
        const double dy = rng.uniform(-o.centre_offset, o.centre_offset);
        if (o.galaxy_type == SimGalaxyType::kBulgePlusDisc) {
          const double magnitude = std::abs(draw_ellipticity(rng, o.e_sigma, o.e_max));
          const double turn = o.bd_misalignment_deg * std::numbers::pi / 180 * rng.normal();
          e_bulge = std::polar(magnitude, std::arg(e_disc) + 2 * turn);
          offset_bulge = std::polar(o.bd_offset * std::sqrt(rng.uniform()), 2 * std::numbers::pi * rng.uniform());
        }
        const double hlr = fixed_fraction ? fixed_hlr : half_light_radius(bf);
        for (int member = 0; member < 2; ++member) {
          const long long index = group * pair + member;
          if (index >= n_objects) break;
          // The partner is the same galaxy turned by 90 degrees: e -> -e, offsets turned by 90.
          const double sign = member == 0 ? 1.0 : -1.0;
          const std::complex<double> turn90 = member == 0 ? 1.0 : std::complex<double>(0, 1);
          const std::complex<double> ed = sign * e_disc, eb = sign * e_bulge;
          const std::complex<double> ed_obs = kernels::lens_ellipticity(ed, g), eb_obs = kernels::lens_ellipticity(eb, g);
          const std::complex<double> ob = turn90 * offset_bulge;
          const std::complex<double> ob_obs(sm[0] * ob.real() + sm[1] * ob.imag(),
                                            sm[1] * ob.real() + sm[2] * ob.imag());
          SimObjectTruth& t = set.truth[static_cast<std::size_t>(index)];
          t.index = index;
          t.ix = index % o.grid;
          t.iy = index / o.grid;
          t.pair = pair;
          t.x_centre = centre + dx;
          t.y_centre = centre + dy;
          t.x_image = t.ix * s + t.x_centre;
          t.y_image = t.iy * s + t.y_centre;
          const bool bulge_only = o.galaxy_type == SimGalaxyType::kBulge;
          const std::complex<double> e_main = bulge_only ? eb : ed, e_main_obs = bulge_only ? eb_obs : ed_obs;
          t.e1_int = e_main.real();
          t.e2_int = e_main.imag();
          t.g1 = set.shear1;
          t.g2 = set.shear2;
          t.e1_obs = e_main_obs.real();
          t.e2_obs = e_main_obs.imag();
          t.hlr = bulge_only ? hlr * bulge_radius_ratio() : hlr;
          t.hlr_bulge = hlr * bulge_radius_ratio();
          t.bulge_frac = bf;
          t.e1_int_bulge = eb.real();
          t.e2_int_bulge = eb.imag();
          t.bulge_dx = ob_obs.real();
          t.bulge_dy = ob_obs.imag();
          // Drawn at unit flux, then scaled to the S/N (the drawing is linear in flux).
          std::vector<SimComponent> comps;
          if (bf > 0)
            comps.push_back(
                {4.0, bf, t.hlr_bulge, eb_obs.real(), eb_obs.imag(), t.x_centre + t.bulge_dx, t.y_centre + t.bulge_dy});
          if (bf < 1) comps.push_back({1.0, 1 - bf, hlr, ed_obs.real(), ed_obs.imag(), t.x_centre, t.y_centre});
          renderer_->render(comps, s, stamp, ws);
          double sum2 = 0;
          for (double v : stamp) sum2 += v * v;
          const double flux = o.snr * o.noise_sigma / std::sqrt(sum2);
          t.flux = flux;
          t.bulge_flux = flux * bf;
          t.disc_flux = flux * (1 - bf);
          double sum = 0, sum2_scaled = 0;
          for (double u : stamp) {
            const double v = flux * u;
            sum += v;
            sum2_scaled += v * v;
          }
          t.stamp_flux = sum;
          t.snr = std::sqrt(sum2_scaled) / o.noise_sigma;
          // Copy 0 gets noise n from the object's own stream; copy 1 (noise pairs) the same galaxy
          // with -n, so odd orders of noise cancel in the group mean.
          for (int copy = 0; copy < group / 2; ++copy) {
            const long long target = index + 2 * copy;
            if (target >= n_objects) break;
            SimObjectTruth& tc = set.truth[static_cast<std::size_t>(target)];
            if (copy > 0) {
              tc = t;
              tc.index = target;
              tc.ix = target % o.grid;
              tc.iy = target / o.grid;
              tc.x_image = tc.ix * s + tc.x_centre;
              tc.y_image = tc.iy * s + tc.y_centre;
            }
            const double noise_sign = copy == 0 ? 1.0 : -1.0;
            RandomStream noise({o.seed, drawn, static_cast<std::uint64_t>(index), kNoiseStream});
            for (int y = 0; y < s; ++y) {
              double* row = set.image.data() + (static_cast<std::size_t>(tc.iy) * s + y) * set.width + tc.ix * s;
              for (int x = 0; x < s; ++x) {
                const double v = flux * stamp[static_cast<std::size_t>(y) * s + x];
                row[x] = o.noise_free ? v : v + noise_sign * o.noise_sigma * noise.normal();
              }
            }
          }
        }
      });
  return set;
}

std::vector<double> Great08Simulator::psf_image() const {
  const int s = options_.stamp_size;
  std::vector<double> out(static_cast<std::size_t>(s) * s);
  SimWorkspace ws;
  const double c = 0.5 * (s - 1);
  renderer_->render_psf(s, 1.0, c, c, true, out, ws);
  return out;
}

std::vector<double> Great08Simulator::psf_oversampled(int oversampling) const {
  const int n = options_.stamp_size * oversampling;
  std::vector<double> out(static_cast<std::size_t>(n) * n);
  SimWorkspace ws;
  const double c = 0.5 * (n - 1);
  renderer_->render_psf(n, 1.0 / oversampling, c, c, false, out, ws);
  return out;
}

}  // namespace stampede
