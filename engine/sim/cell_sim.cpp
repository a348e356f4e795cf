// Metadetection test cells; see cell_sim.hpp.
#include "engine/sim/cell_sim.hpp"

#include <array>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <complex>
#include <cstdio>
#include <stdexcept>
#include <string_view>

#include "engine/common/random_stream.hpp"
#include "kernels/sersic.hpp"

namespace stampede {

namespace {

// Stream purposes (the second key).
enum Purpose : std::uint64_t { kLayoutPurpose = 1, kGalaxyPurpose, kNoisePurpose, kNoisePlanePurpose, kStarPurpose, kDefectPurpose };

constexpr double kLightEpsilon = 1e-5;  // light of a component left outside its stamp (at most)
constexpr int kMaxStamp = 255;          // stamp side cap: a large bulge's far wings are cut (cell_sim.hpp)
constexpr double kNoiseFreeFactor = 1e-6;

std::string text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

bool equal_nocase(std::string_view a, std::string_view b) {
  return a.size() == b.size() &&
         std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) { return std::tolower(x) == std::tolower(y); });
}

}  // namespace

const char* cell_layout_name(CellLayout v) { return v == CellLayout::kGrid ? "grid" : "random"; }
const char* cell_galaxy_model_name(CellGalaxyModel v) { return v == CellGalaxyModel::kExponential ? "exp" : "bd"; }
const char* cell_psf_kind_name(CellPsfKind v) { return v == CellPsfKind::kGaussian ? "gauss" : "moffat"; }

bool parse_cell_layout(const std::string& name, CellLayout* out) {
  for (CellLayout v : {CellLayout::kGrid, CellLayout::kRandom})
    if (equal_nocase(name, cell_layout_name(v))) return *out = v, true;
  return false;
}
bool parse_cell_galaxy_model(const std::string& name, CellGalaxyModel* out) {
  for (CellGalaxyModel v : {CellGalaxyModel::kExponential, CellGalaxyModel::kBulgeDisc})
    if (equal_nocase(name, cell_galaxy_model_name(v))) return *out = v, true;
  return false;
}
bool parse_cell_psf_kind(const std::string& name, CellPsfKind* out) {
  for (CellPsfKind v : {CellPsfKind::kGaussian, CellPsfKind::kMoffat})
    if (equal_nocase(name, cell_psf_kind_name(v))) return *out = v, true;
  if (equal_nocase(name, "gaussian")) return *out = CellPsfKind::kGaussian, true;
  return false;
}

bool CellSimOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (size < 16 || size > 4096) return fail("size " + std::to_string(size) + ": must be in [16, 4096] pixels");
  if (!(pixel_scale > 0 && pixel_scale <= 10)) return fail("pixel_scale " + text(pixel_scale) + ": must be in (0, 10] arcsec");
  if (buffer < 0 || 2 * buffer >= size)
    return fail("buffer " + std::to_string(buffer) + ": must be >= 0 and leave an interior (2 x buffer < size " +
                std::to_string(size) + ")");
  if (grid < 1 || grid > 1000) return fail("grid " + std::to_string(grid) + ": must be in [1, 1000]");
  if (!(grid_shift >= 0 && grid_shift <= 10)) return fail("grid_shift " + text(grid_shift) + ": must be in [0, 10] pixels");
  if (!(density > 0 && density <= 10000)) return fail("density " + text(density) + ": must be in (0, 10000] per arcmin^2");
  if (!(hlr > 0 && hlr / pixel_scale <= 50)) return fail("hlr " + text(hlr) + ": must be > 0 and at most 50 pixels");
  if (!(flux > 0 && std::isfinite(flux))) return fail("flux " + text(flux) + ": must be > 0");
  if (!(bulge_fraction_max >= 0 && bulge_fraction_max <= 1))
    return fail("bulge_fraction_max " + text(bulge_fraction_max) + ": must be in [0, 1]");
  if (!(shape_noise >= 0 && shape_noise <= 1)) return fail("shape_noise " + text(shape_noise) + ": must be in [0, 1]");
  if (!(keep_clear >= 0 && keep_clear <= buffer)) return fail("keep_clear " + text(keep_clear) + ": must be in [0, buffer]");
  if (!(e_max > 0 && e_max <= 0.9)) return fail("e_max " + text(e_max) + ": must be in (0, 0.9]");
  if (!(psf_fwhm > 0 && psf_fwhm / pixel_scale >= 1 && psf_fwhm / pixel_scale <= 50))
    return fail("psf_fwhm " + text(psf_fwhm) + ": must be between 1 and 50 pixels (" + text(pixel_scale) + " arcsec each)");
  if (!(psf_beta > 1.5 && psf_beta <= 100)) return fail("psf_beta " + text(psf_beta) + ": must be in (1.5, 100]");
  if (psf_size < 5 || psf_size % 2 == 0 || psf_size > 255)
    return fail("psf_size " + std::to_string(psf_size) + ": must be odd and in [5, 255]");
  if (!(std::hypot(g1, g2) < 0.3)) return fail("g1, g2 " + text(g1) + "," + text(g2) + ": |g| must be < 0.3");
  if (!(snr > 0 && std::isfinite(snr))) return fail("snr " + text(snr) + ": must be > 0");
  if (bands < 1 || bands > 8) return fail("bands " + std::to_string(bands) + ": must be in [1, 8]");
  if (stars < 0 || stars > 1000) return fail("stars " + std::to_string(stars) + ": must be in [0, 1000] per cell");
  if (!(star_flux >= 10 && star_flux <= 1e8)) return fail("star_flux " + text(star_flux) + ": must be in [10, 1e8]");
  if (bad_columns < 0 || bad_columns > 100)
    return fail("bad_columns " + std::to_string(bad_columns) + ": must be in [0, 100] per cell");
  return true;
}

double cell_light_radius(double sersic_n, double hlr, double e, double epsilon) {
  const double a = 2 * sersic_n, b = kernels::sersic_b(sersic_n);
  if (a != std::round(a)) throw std::invalid_argument("cell_light_radius: 2n must be an integer");
  // Outside fraction 1 - P(a, x) falls monotonically in x = b (r / r_e)^(1/n).
  double lo = 0, hi = 1;
  while (1 - kernels::regularized_gamma_p(a, hi) > epsilon) hi *= 2;
  for (int it = 0; it < 100 && hi - lo > 1e-10 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (1 - kernels::regularized_gamma_p(a, mid) > epsilon ? lo : hi) = mid;
  }
  return hlr * std::pow(hi / b, sersic_n) * std::sqrt((1 + e) / (1 - e));
}

CellSimulator::CellSimulator(const CellSimOptions& options) : options_(options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  const CellSimOptions& o = options_;
  SimRenderer::Options ro;
  ro.sersic_indices = o.model == CellGalaxyModel::kExponential ? std::vector<double>{1.0} : std::vector<double>{1.0, 4.0};
  ro.max_half_light_radius = o.hlr / o.pixel_scale;
  const double g = std::hypot(o.g1, o.g2);
  ro.max_e = (o.e_max + g) / (1 + o.e_max * g);  // the largest |e_obs| a shear of |g| makes of |e| <= e_max
  SimWorkspace ws;
  const int n = o.psf_size, c = n / 2;
  for (int b = 0; b < o.bands; ++b) {
    CellBand band;
    const double t = o.bands > 1 ? static_cast<double>(b) / (o.bands - 1) : 0.0;
    band.psf_fwhm = o.psf_fwhm / o.pixel_scale * (1 - 0.1 * t);
    band.flux_scale = 1 + 0.5 * t;
    band.bulge_scale = 0.5 + t;
    if (o.bands == 1) band.bulge_scale = 1;
    std::unique_ptr<SimRenderer> r;
    if (o.psf == CellPsfKind::kGaussian) {
      r = std::make_unique<SimRenderer>(SimGaussianPsf{band.psf_fwhm, 0, 0}, ro);
    } else {
      PsfModel psf;
      psf.kind = PsfKind::kMoffat;
      psf.moffat = {o.psf_beta, band.psf_fwhm, 0.0, 0.0, 0.0};
      r = std::make_unique<SimRenderer>(psf, ro);
    }
    band.psf.resize(static_cast<std::size_t>(n) * n);
    r->render_psf(n, 1.0, c, c, true, band.psf, ws);
    renderers_.push_back(std::move(r));
    bands_.push_back(std::move(band));
  }
  // The noise: the reference galaxy (round, centred, the mean bulge fraction) has S/N snr over all bands.
  const double hlr = o.hlr / o.pixel_scale;
  const double radius = cell_light_radius(o.model == CellGalaxyModel::kExponential ? 1.0 : 4.0, hlr, 0, kLightEpsilon);
  double signal2 = 0;
  for (int b = 0; b < o.bands; ++b) {
    const SimRenderer& r = *renderers_[static_cast<std::size_t>(b)];
    const int side = std::min(kMaxStamp, 2 * static_cast<int>(std::ceil(radius + r.psf_tail_radius())) + 3);
    const double mid = side / 2;
    const double flux = o.flux * bands_[static_cast<std::size_t>(b)].flux_scale;
    std::vector<SimComponent> comps;
    if (o.model == CellGalaxyModel::kExponential) {
      comps.push_back({1.0, flux, hlr, 0, 0, mid, mid});
    } else {
      const double bf = std::min(1.0, 0.5 * o.bulge_fraction_max * bands_[static_cast<std::size_t>(b)].bulge_scale);
      comps.push_back({4.0, flux * bf, hlr, 0, 0, mid, mid});
      comps.push_back({1.0, flux * (1 - bf), hlr, 0, 0, mid, mid});
    }
    std::vector<double> stamp(static_cast<std::size_t>(side) * side);
    r.render(comps, side, stamp, ws);
    for (double v : stamp) signal2 += v * v;
  }
  const double sigma = std::sqrt(signal2) / o.snr * (o.noise_free ? kNoiseFreeFactor : 1.0);
  for (CellBand& band : bands_) band.noise_sigma = sigma;
}

CellSimulator::~CellSimulator() = default;

std::unique_ptr<CellSimulator::Workspace> CellSimulator::make_workspace() const { return std::make_unique<Workspace>(); }

std::vector<CellObject> CellSimulator::objects(int cell, double g1, double g2) const {
  const CellSimOptions& o = options_;
  const std::uint64_t key = static_cast<std::uint64_t>(cell);
  RandomStream layout({o.seed, kLayoutPurpose, key});
  std::vector<CellObject> out;
  if (o.reference_positions) {
    const double c = 0.5 * (o.size - 1), h = 0.5 * (o.size - 2 * o.buffer);
    auto add = [&](double x, double y) {
      CellObject obj;
      obj.x = x + layout.uniform(-o.grid_shift, o.grid_shift);
      obj.y = y + layout.uniform(-o.grid_shift, o.grid_shift);
      out.push_back(obj);
    };
    if (o.layout == CellLayout::kGrid) {
      const double mid = 0.5 * (o.grid - 1);
      for (int j = 0; j < o.grid; ++j)
        for (int i = 0; i < o.grid; ++i)
          add(o.grid > 1 ? c + (i - mid) / mid * h : c, o.grid > 1 ? c + (j - mid) / mid * h : c);
    } else {
      const double side_arcmin = 2 * h * o.pixel_scale / 60.0;
      const int count = static_cast<int>(o.density * side_arcmin * side_arcmin);
      for (int k = 0; k < count; ++k) {
        const double x = layout.uniform(c - h, c + h);
        add(x, layout.uniform(c - h, c + h));
      }
    }
  } else if (o.layout == CellLayout::kGrid) {
    // Object (i, j) at the centre of its 1/grid of the interior [buffer - 0.5, size - buffer - 0.5).
    const double step = static_cast<double>(o.size - 2 * o.buffer) / o.grid;
    for (int j = 0; j < o.grid; ++j)
      for (int i = 0; i < o.grid; ++i) {
        CellObject obj;
        obj.x = o.buffer - 0.5 + (i + 0.5) * step + layout.uniform(-o.grid_shift, o.grid_shift);
        obj.y = o.buffer - 0.5 + (j + 0.5) * step + layout.uniform(-o.grid_shift, o.grid_shift);
        out.push_back(obj);
      }
  } else {
    // A Poisson count by exponential arrival times on [0, 1) at rate = the mean (exact for any mean).
    const double side_arcmin = o.size * o.pixel_scale / 60.0;
    const double mean = o.density * side_arcmin * side_arcmin;
    for (double t = -std::log(1.0 - layout.uniform()) / mean; t < 1.0; t -= std::log(1.0 - layout.uniform()) / mean) {
      CellObject obj;
      obj.x = layout.uniform(-0.5, o.size - 0.5);
      obj.y = layout.uniform(-0.5, o.size - 0.5);
      const double lo = o.buffer - 0.5, hi = o.size - o.buffer - 0.5;
      if (std::min({std::abs(obj.x - lo), std::abs(obj.x - hi), std::abs(obj.y - lo), std::abs(obj.y - hi)}) < o.keep_clear)
        continue;
      out.push_back(obj);
    }
  }
  const std::complex<double> gs(g1, g2);
  for (std::size_t k = 0; k < out.size(); ++k) {
    CellObject& obj = out[k];
    obj.id = static_cast<long long>(k);
    RandomStream gal({o.seed, kGalaxyPurpose, key, static_cast<std::uint64_t>(k)});
    if (o.shape_noise > 0) {
      do {
        obj.e1_int = o.shape_noise * gal.normal();
        obj.e2_int = o.shape_noise * gal.normal();
      } while (std::hypot(obj.e1_int, obj.e2_int) >= o.e_max);
    }
    if (o.rotate) {
      // The scene turned by 90 degrees about the cell's centre: every intrinsic shape's e negated
      // (spin 2), positions rotated; the shear is applied after.
      const double c = 0.5 * (o.size - 1), dx = obj.x - c, dy = obj.y - c;
      obj.x = c - dy, obj.y = c + dx;
      obj.e1_int = -obj.e1_int, obj.e2_int = -obj.e2_int;
    }
    const double bulge = gal.uniform(0, o.bulge_fraction_max);  // drawn for every model: streams stay aligned
    obj.bulge_frac = o.model == CellGalaxyModel::kBulgeDisc ? bulge * bands_[0].bulge_scale : 0.0;
    obj.bulge_frac = std::min(1.0, obj.bulge_frac);
    obj.flux = o.flux;
    obj.hlr = o.hlr;
    // Lensing shear of the intrinsic shape (reduced shear, complex e).
    const std::complex<double> es(obj.e1_int, obj.e2_int);
    const std::complex<double> eo = (es + gs) / (1.0 + std::conj(gs) * es);
    obj.e1_obs = eo.real(), obj.e2_obs = eo.imag();
    // The lens shears the whole scene, positions too (about the cell's centre): a blend's geometry
    // responds to the shear as metacal's sheared images of the cell make it respond.
    const double c = 0.5 * (o.size - 1), dx = obj.x - c, dy = obj.y - c;
    // The unit-determinant matrix of reduced shear g (g1 > 0 stretches along x).
    const double n = 1.0 / std::sqrt(1.0 - g1 * g1 - g2 * g2);
    obj.x = c + n * ((1 + g1) * dx + g2 * dy);
    obj.y = c + n * (g2 * dx + (1 - g1) * dy);
  }
  return out;
}

std::vector<CellStar> CellSimulator::stars(int cell) const {
  const CellSimOptions& o = options_;
  RandomStream draw({o.seed, kStarPurpose, static_cast<std::uint64_t>(cell)});
  std::vector<CellStar> out;
  const double c = 0.5 * (o.size - 1);
  for (int k = 0; k < o.stars; ++k) {
    CellStar s;
    s.x = std::floor(draw.uniform(0, o.size)), s.y = std::floor(draw.uniform(0, o.size));
    s.x = std::min(s.x, o.size - 1.0), s.y = std::min(s.y, o.size - 1.0);
    if (o.rotate) {  // turned with the scene (about the centre, as the galaxies)
      const double dx = s.x - c, dy = s.y - c;
      s.x = c - dy, s.y = c + dx;
    }
    s.flux = o.flux * 10 * std::pow(o.star_flux / 10, draw.uniform());
    // The mask radius: beyond it every band's PSF image times the star's flux is below sigma.
    const int half = o.psf_size / 2;
    double reach = 0;
    for (const CellBand& band : bands_)
      for (int y = 0; y < o.psf_size; ++y)
        for (int x = 0; x < o.psf_size; ++x)
          if (s.flux * band.flux_scale * band.psf[static_cast<std::size_t>(y) * o.psf_size + x] > band.noise_sigma)
            reach = std::max(reach, std::hypot(x - half, y - half));
    s.radius = reach + 1;
    out.push_back(s);
  }
  return out;
}

std::vector<double> SimCell::bmask(int size) const {
  const auto n = static_cast<std::size_t>(size);
  std::vector<double> plane(n * n, 0.0);
  for (const CellDefect& d : defects)
    for (int y = d.y0; y <= d.y1; ++y)
      for (int x = d.x0; x <= d.x1; ++x) plane[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x)] = 1;
  return plane;
}

std::vector<CellDefect> CellSimulator::defects(int cell) const {
  const CellSimOptions& o = options_;
  RandomStream draw({o.seed, kDefectPurpose, static_cast<std::uint64_t>(cell)});
  std::vector<CellDefect> out;
  for (int k = 0; k < o.bad_columns; ++k) {
    const int x = std::min(o.size - 1, static_cast<int>(draw.uniform(0, o.size)));
    const int length = std::min(o.size, static_cast<int>(draw.uniform(0.25 * o.size, o.size + 1.0)));
    const int y0 = std::min(o.size - length, static_cast<int>(draw.uniform(0, o.size - length + 1.0)));
    CellDefect d{x, y0, x, y0 + length - 1};
    if (o.rotate) {  // turned with the scene: (x, y) -> (size - 1 - y, x)
      d = {o.size - 1 - d.y1, d.x0, o.size - 1 - d.y0, d.x1};
    }
    out.push_back(d);
  }
  return out;
}

SimCell CellSimulator::simulate(int cell, double g1, double g2, Workspace& ws) const {
  const CellSimOptions& o = options_;
  SimCell out;
  out.index = cell;
  out.g1 = g1, out.g2 = g2;
  out.objects = objects(cell, g1, g2);
  const int size = o.size;
  const std::size_t npix = static_cast<std::size_t>(size) * size;
  out.bands.resize(bands_.size());
  for (CellBandImage& b : out.bands) b.image.assign(npix, 0.0), b.noise.assign(npix, 0.0);
  const double hlr = o.hlr / o.pixel_scale;
  const bool bd = o.model == CellGalaxyModel::kBulgeDisc;
  std::vector<SimComponent> comps;
  for (CellObject& obj : out.objects) {
    const double e = std::hypot(obj.e1_obs, obj.e2_obs);
    const double light = std::max(cell_light_radius(1.0, hlr, e, kLightEpsilon),
                                  bd ? cell_light_radius(4.0, hlr, e, kLightEpsilon) : 0.0);
    const double cx = std::round(obj.x), cy = std::round(obj.y);
    double signal2 = 0;
    for (std::size_t b = 0; b < bands_.size(); ++b) {
      const SimRenderer& r = *renderers_[b];
      const CellBand& band = bands_[b];
      const int side = std::min(kMaxStamp, 2 * static_cast<int>(std::ceil(light + r.psf_tail_radius())) + 3);
      const int half = side / 2;
      // The stamp's pixel (half, half) is the cell's pixel (cx, cy).
      const double sx = obj.x - cx + half, sy = obj.y - cy + half;
      const double flux = obj.flux * band.flux_scale;
      comps.clear();
      if (bd) {
        const double bf = std::min(1.0, obj.bulge_frac / bands_[0].bulge_scale * band.bulge_scale);
        comps.push_back({4.0, flux * bf, hlr, obj.e1_obs, obj.e2_obs, sx, sy});
        comps.push_back({1.0, flux * (1 - bf), hlr, obj.e1_obs, obj.e2_obs, sx, sy});
      } else {
        comps.push_back({1.0, flux, hlr, obj.e1_obs, obj.e2_obs, sx, sy});
      }
      ws.stamp.resize(static_cast<std::size_t>(side) * side);
      r.render(comps, side, ws.stamp, ws.sim);
      std::vector<double>& image = out.bands[b].image;
      const int x0 = static_cast<int>(cx) - half, y0 = static_cast<int>(cy) - half;
      for (int y = 0; y < side; ++y) {
        const double* row = ws.stamp.data() + static_cast<std::size_t>(y) * side;
        for (int x = 0; x < side; ++x) signal2 += row[x] * row[x];
        const int yy = y0 + y;
        if (yy < 0 || yy >= size) continue;
        const int xa = std::max(0, -x0), xb = std::min(side, size - x0);
        double* dst = image.data() + static_cast<std::size_t>(yy) * size + x0;
        for (int x = xa; x < xb; ++x) dst[x] += row[x];
      }
    }
    obj.snr = std::sqrt(signal2) / bands_[0].noise_sigma;
  }
  // Stars: each band's PSF image times the star's flux, centred on its pixel.
  out.stars = stars(cell);
  const int half = o.psf_size / 2;
  for (const CellStar& s : out.stars)
    for (std::size_t b = 0; b < bands_.size(); ++b) {
      std::vector<double>& image = out.bands[b].image;
      const double flux = s.flux * bands_[b].flux_scale;
      for (int y = 0; y < o.psf_size; ++y) {
        const int yy = static_cast<int>(s.y) - half + y;
        if (yy < 0 || yy >= size) continue;
        for (int x = 0; x < o.psf_size; ++x) {
          const int xx = static_cast<int>(s.x) - half + x;
          if (xx >= 0 && xx < size)
            image[static_cast<std::size_t>(yy) * size + xx] += flux * bands_[b].psf[static_cast<std::size_t>(y) * o.psf_size + x];
        }
      }
    }
  for (std::size_t b = 0; b < bands_.size(); ++b) {
    const double sigma = bands_[b].noise_sigma;
    const std::uint64_t key = static_cast<std::uint64_t>(cell), band = static_cast<std::uint64_t>(b);
    RandomStream noise({o.seed, kNoisePurpose, key, band}), plane({o.seed, kNoisePlanePurpose, key, band});
    for (double& v : out.bands[b].image) v += sigma * noise.normal();
    for (double& v : out.bands[b].noise) v = sigma * plane.normal();
  }
  // Bad columns: hot pixels over whatever was there (BMASK flags them).
  out.defects = defects(cell);
  for (const CellDefect& d : out.defects)
    for (std::size_t b = 0; b < bands_.size(); ++b)
      for (int y = d.y0; y <= d.y1; ++y)
        for (int x = d.x0; x <= d.x1; ++x)
          out.bands[b].image[static_cast<std::size_t>(y) * size + x] = 1e3 * bands_[b].noise_sigma;
  return out;
}

}  // namespace stampede
