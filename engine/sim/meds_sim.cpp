// Multi-epoch survey simulations; see meds_sim.hpp.
#include "engine/sim/meds_sim.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "engine/common/random_stream.hpp"
#include "engine/model/parameters.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/render/exact_renderer.hpp"
#include "engine/sim/sim_renderer.hpp"

namespace stampede {

namespace {

// Stream purposes (the second key).
enum Purpose : std::uint64_t { kImagePurpose = 1, kGalaxy, kEpochs, kNeighbour, kBadColumn, kNoise };

std::string text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// A band's own stream of (purpose, index): band 0's is the one-band tile's, so that tile is
// unchanged; other bands key theirs by the band too.
RandomStream band_stream(const MedsSimOptions& o, std::uint64_t purpose, std::uint64_t index) {
  if (o.band == 0) return RandomStream({o.seed, purpose, index});
  return RandomStream({o.seed, purpose, index, static_cast<std::uint64_t>(o.band)});
}

// Band b's PSF FWHM relative to the first band's: 1 down to 0.9 for the last.
double psf_scale(const MedsSimOptions& o) { return o.bands > 1 ? 1.0 - 0.1 * o.band / (o.bands - 1) : 1.0; }

}  // namespace

bool MedsSimOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& w) {
    *why = w;
    return false;
  };
  if (objects < 2 || objects % 2) return fail("objects " + std::to_string(objects) + ": must be even and >= 2 (ring pairs)");
  if (epochs < 1 || epochs > 64) return fail("epochs " + std::to_string(epochs) + ": must be in [1, 64]");
  if (images < epochs || images > 100000) return fail("images " + std::to_string(images) + ": must be >= epochs and <= 100000");
  if (box_size < 16 || box_size > 512) return fail("box_size " + std::to_string(box_size) + ": must be in [16, 512]");
  if (!(pixel_scale > 0)) return fail("pixel_scale " + text(pixel_scale) + ": must be > 0");
  if (!(scale_jitter >= 0 && scale_jitter < 0.5)) return fail("scale_jitter " + text(scale_jitter) + ": must be in [0, 0.5)");
  if (!(wcs_shear >= 0 && wcs_shear < 0.3)) return fail("wcs_shear " + text(wcs_shear) + ": must be in [0, 0.3)");
  if (!(psf_fwhm_min > 0 && psf_fwhm_max >= psf_fwhm_min))
    return fail("psf_fwhm_min, psf_fwhm_max " + text(psf_fwhm_min) + "," + text(psf_fwhm_max) + ": must be 0 < min <= max");
  if (!(psf_e_max >= 0 && psf_e_max < 0.3)) return fail("psf_e_max " + text(psf_e_max) + ": must be in [0, 0.3)");
  if (!(psf_beta > 1.5)) return fail("psf_beta " + text(psf_beta) + ": must be > 1.5");
  if (psf_size < 5 || psf_size % 2 == 0 || psf_size > box_size) return fail("psf_size " + std::to_string(psf_size) + ": must be odd, >= 5 and <= box_size");
  if (!(std::hypot(g1, g2) < 0.3)) return fail("g1, g2 " + text(g1) + "," + text(g2) + ": |g| must be < 0.3");
  if (!(snr > 0)) return fail("snr " + text(snr) + ": must be > 0");
  if (!(noise_sigma > 0)) return fail("noise_sigma " + text(noise_sigma) + ": must be > 0");
  if (!(hlr_min > 0 && hlr_max >= hlr_min)) return fail("hlr_min, hlr_max " + text(hlr_min) + "," + text(hlr_max) + ": must be 0 < min <= max");
  if (!(bulge_fraction_max >= 0 && bulge_fraction_max <= 1)) return fail("bulge_fraction_max " + text(bulge_fraction_max) + ": must be in [0, 1]");
  if (!(e_sigma >= 0 && e_max > 0 && e_max < 0.95)) return fail("e_sigma, e_max " + text(e_sigma) + "," + text(e_max) + ": need e_sigma >= 0 and 0 < e_max < 0.95");
  if (!(centre_offset >= 0 && centre_offset < 1)) return fail("centre_offset " + text(centre_offset) + ": must be in [0, 1) arcsec");
  if (!(magzp_jitter >= 0 && magzp_jitter < 3)) return fail("magzp_jitter " + text(magzp_jitter) + ": must be in [0, 3)");
  if (!(bad_column_fraction >= 0 && bad_column_fraction <= 1)) return fail("bad_column_fraction " + text(bad_column_fraction) + ": must be in [0, 1]");
  if (!(neighbour_fraction >= 0 && neighbour_fraction <= 1)) return fail("neighbour_fraction " + text(neighbour_fraction) + ": must be in [0, 1]");
  if (bands < 1 || bands > 8 || band < 0 || band >= bands)
    return fail("band, bands " + std::to_string(band) + "," + std::to_string(bands) + ": band must be in [0, bands), bands in [1, 8]");
  return true;
}

MedsSimulator::MedsSimulator(const MedsSimOptions& options) : options_(options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  const int n = options.psf_size, c = n / 2;
  SimRenderer::Options so;
  so.sersic_indices = {1.0};  // only the PSF is drawn here: no Sersic table to build
  for (int i = 0; i < options.images; ++i) {
    RandomStream rng = band_stream(options, kImagePurpose, static_cast<std::uint64_t>(i));
    MedsSimImage im;
    im.psf_fwhm = rng.uniform(options.psf_fwhm_min, options.psf_fwhm_max) * psf_scale(options) / options.pixel_scale;
    im.psf_e1 = rng.uniform(-options.psf_e_max, options.psf_e_max);
    im.psf_e2 = rng.uniform(-options.psf_e_max, options.psf_e_max);
    // float32, as image_info holds it, so that the fit's flux scale is the one drawn with.
    im.magzp = static_cast<float>(options.magzp + 0.25 * options.band +
                                  rng.uniform(-options.magzp_jitter, options.magzp_jitter));
    PsfModel psf;
    psf.kind = PsfKind::kMoffat;
    psf.moffat = {options.psf_beta, im.psf_fwhm, im.psf_e1, im.psf_e2, 0.0};
    SimRenderer sim(psf, so);
    SimWorkspace ws;
    im.psf.resize(static_cast<std::size_t>(n) * n);
    sim.render_psf(n, 1.0, c, c, true, im.psf, ws);
    for (double& v : im.psf) v = static_cast<float>(v);  // what the PSFEx file holds
    auto image = std::make_shared<PsfImage>();
    image->nx = image->ny = n;
    image->pixels = im.psf;
    image->centre_x = image->centre_y = c;
    psf_images_.push_back(std::move(image));
    images_.push_back(std::move(im));
  }
}

MedsSimulator::~MedsSimulator() = default;

std::unique_ptr<MedsSimulator::Workspace> MedsSimulator::make_workspace() const {
  auto ws = std::make_unique<Workspace>();
  RenderOptions ro;
  ro.stamp_size = options_.box_size;
  ws->renderer = std::make_unique<ExactRenderer>(ro, ModelOptions{});
  ws->psfs.resize(images_.size());
  return ws;
}

std::vector<MedsSimCutout> MedsSimulator::epochs(long long index) const {
  const MedsSimOptions& o = options_;
  RandomStream ep = band_stream(o, kEpochs, static_cast<std::uint64_t>(index / 2));
  std::vector<int> pick(static_cast<std::size_t>(o.images));
  std::iota(pick.begin(), pick.end(), 0);
  const int box = o.box_size;
  std::vector<MedsSimCutout> out;
  for (int k = 0; k < o.epochs; ++k) {
    const std::size_t j = static_cast<std::size_t>(k) + static_cast<std::size_t>(ep.uniform() * (o.images - k));
    std::swap(pick[static_cast<std::size_t>(k)], pick[std::min(j, pick.size() - 1)]);
    MedsSimCutout c;
    c.image = pick[static_cast<std::size_t>(k)];
    const double drawn = ep.uniform(-std::numbers::pi, std::numbers::pi);  // drawn either way: streams stay aligned
    const double angle = o.rotate ? drawn : 0.0;
    const double scale = o.pixel_scale * (1 + ep.uniform(-o.scale_jitter, o.scale_jitter));
    const double w1 = ep.uniform(-o.wcs_shear, o.wcs_shear), w2 = ep.uniform(-o.wcs_shear, o.wcs_shear);
    const double co = std::cos(angle), si = std::sin(angle);
    // J = scale R(angle) [[1 + w1, w2], [w2, 1 - w1]] on (x, y) = (col, row).
    c.dudcol = scale * (co * (1 + w1) - si * w2), c.dudrow = scale * (co * w2 - si * (1 - w1));
    c.dvdcol = scale * (si * (1 + w1) + co * w2), c.dvdrow = scale * (si * w2 + co * (1 - w1));
    c.orig_row = ep.uniform(100, 3900), c.orig_col = ep.uniform(100, 1900);
    c.orig_start_row = static_cast<long long>(std::floor(c.orig_row)) - box / 2 + 1;
    c.orig_start_col = static_cast<long long>(std::floor(c.orig_col)) - box / 2 + 1;
    c.cutout_row = c.orig_row - static_cast<double>(c.orig_start_row);
    c.cutout_col = c.orig_col - static_cast<double>(c.orig_start_col);
    out.push_back(std::move(c));
  }
  return out;
}

MedsSimObject MedsSimulator::simulate(long long object_index, Workspace& ws) const {
  const MedsSimOptions& o = options_;
  MedsSimObject out;
  out.index = object_index;
  out.pair = object_index / 2;
  const std::uint64_t pair = static_cast<std::uint64_t>(out.pair), object = static_cast<std::uint64_t>(object_index);

  // The galaxy: shared by the ring pair, its intrinsic e turned by 90 degrees for the odd member.
  RandomStream g({o.seed, kGalaxy, pair});
  out.hlr = g.uniform(o.hlr_min, o.hlr_max);
  out.bulge_frac = g.uniform(0, o.bulge_fraction_max);
  if (o.bands > 1) out.bulge_frac = std::min(1.0, out.bulge_frac * (0.5 + static_cast<double>(o.band) / (o.bands - 1)));
  do {
    out.e1_int = o.e_sigma * g.normal();
    out.e2_int = o.e_sigma * g.normal();
  } while (std::hypot(out.e1_int, out.e2_int) >= o.e_max);
  out.u0 = g.uniform(-o.centre_offset, o.centre_offset);
  out.v0 = g.uniform(-o.centre_offset, o.centre_offset);
  if (object_index % 2) out.e1_int = -out.e1_int, out.e2_int = -out.e2_int;
  const std::complex<double> es(out.e1_int, out.e2_int), gs(o.g1, o.g2);
  const std::complex<double> eo = (es + gs) / (1.0 + std::conj(gs) * es);
  out.e1_obs = eo.real(), out.e2_obs = eo.imag();

  // Its neighbour, if any (shared by the pair).
  RandomStream nb({o.seed, kNeighbour, pair});
  out.neighbour = nb.uniform() < o.neighbour_fraction;
  const double nb_hlr = nb.uniform(0.3, 0.6), nb_flux_ratio = nb.uniform(0.5, 1.0), nb_dist = nb.uniform(2.2, 3.0),
               nb_angle = nb.uniform(0, 2 * std::numbers::pi), nb_e1 = nb.uniform(-0.3, 0.3), nb_e2 = nb.uniform(-0.3, 0.3);

  ExactRenderer& r = *ws.renderer;
  ParamVector p = ParameterSet::default_values();
  p[index(Param::kX0)] = out.u0, p[index(Param::kY0)] = out.v0;
  p[index(Param::kE1)] = out.e1_obs, p[index(Param::kE2)] = out.e2_obs, p[index(Param::kRadius)] = out.hlr;
  p[index(Param::kBulgeA)] = 1, p[index(Param::kDiscA)] = 1;
  double fb = 0, fd = 0;
  r.component_fluxes(p, &fb, &fd);  // flux per unit amplitude (sky units: frame-independent)
  p[index(Param::kBulgeA)] = out.bulge_frac / fb, p[index(Param::kDiscA)] = (1 - out.bulge_frac) / fd;
  ParamVector q = ParameterSet::default_values();
  q[index(Param::kX0)] = out.u0 + nb_dist * std::cos(nb_angle), q[index(Param::kY0)] = out.v0 + nb_dist * std::sin(nb_angle);
  q[index(Param::kE1)] = nb_e1, q[index(Param::kE2)] = nb_e2, q[index(Param::kRadius)] = nb_hlr;
  q[index(Param::kBulgeA)] = 0, q[index(Param::kDiscA)] = 1;
  r.component_fluxes(q, &fb, &fd);
  q[index(Param::kDiscA)] = nb_flux_ratio / fd;

  out.cutouts = epochs(object_index);
  const int box = o.box_size;
  const std::size_t npix = static_cast<std::size_t>(box) * box;
  double signal2 = 0;  // sum over epochs and pixels of (s m)^2 at unit flux
  for (MedsSimCutout& cut : out.cutouts) {
    cut.pixels.assign(npix, 0.0);
    cut.weight.assign(npix, 1.0 / (o.noise_sigma * o.noise_sigma));
    cut.seg.assign(npix, 0.0);
    cut.bmask.assign(npix, 0.0);
    const std::size_t image = static_cast<std::size_t>(cut.image);
    std::shared_ptr<const PreparedPsf>& psf = ws.psfs[image];
    if (!psf) {
      std::string why;
      psf = r.prepare_psf(PsfModel::Image(psf_images_[image]), &why);
      if (!psf) throw std::runtime_error("MedsSimulator: PSF: " + why);
    }
    r.set_psf(psf);
    r.set_frame(PixelFrame::from_meds(cut.dudrow, cut.dudcol, cut.dvdrow, cut.dvdcol, cut.cutout_row, cut.cutout_col));
    if (r.render(p, cut.pixels) != RenderStatus::kOk) throw std::runtime_error("MedsSimulator: the galaxy could not be drawn");
    const double s = std::pow(10.0, 0.4 * (images_[image].magzp - o.magzp));
    for (double& v : cut.pixels) v *= s, signal2 += v * v;
    if (out.neighbour) {
      // Drawn into the seg array, which holds it until the flux is known and the labels replace it.
      if (r.render(q, cut.seg) != RenderStatus::kOk) throw std::runtime_error("MedsSimulator: the neighbour could not be drawn");
      for (double& v : cut.seg) v *= s;
    }
  }
  out.flux = o.snr * o.noise_sigma / std::sqrt(signal2);
  for (int k = 0; k < o.epochs; ++k) {
    MedsSimCutout& c = out.cutouts[static_cast<std::size_t>(k)];
    for (std::size_t i = 0; i < npix; ++i) {
      const double gal = out.flux * c.pixels[i], nbr = out.neighbour ? out.flux * c.seg[i] : 0.0;
      // seg: the object's number (1) or its neighbour's (2) where its light exceeds the noise.
      c.seg[i] = gal >= nbr && gal >= o.noise_sigma ? 1.0 : nbr > gal && nbr >= o.noise_sigma ? 2.0 : 0.0;
      c.pixels[i] = gal + nbr;
    }
    if (!o.noise_free) {
      RandomStream noise = o.band == 0 ? RandomStream({o.seed, kNoise, object, static_cast<std::uint64_t>(k)})
                                       : RandomStream({o.seed, kNoise, object, static_cast<std::uint64_t>(k),
                                                       static_cast<std::uint64_t>(o.band)});
      for (double& v : c.pixels) v += o.noise_sigma * noise.normal();
    }
    RandomStream bad = o.band == 0 ? RandomStream({o.seed, kBadColumn, object, static_cast<std::uint64_t>(k)})
                                   : RandomStream({o.seed, kBadColumn, object, static_cast<std::uint64_t>(k),
                                                   static_cast<std::uint64_t>(o.band)});
    if (bad.uniform() < o.bad_column_fraction) {
      c.bad_column = static_cast<int>(bad.uniform() * box);
      for (int y = 0; y < box; ++y) {
        const std::size_t i = static_cast<std::size_t>(y) * box + static_cast<std::size_t>(c.bad_column);
        c.bmask[i] = 1;
        c.pixels[i] = 1000 * o.noise_sigma;  // a hot column: ruinous unless masked
      }
    }
  }
  return out;
}

}  // namespace stampede
