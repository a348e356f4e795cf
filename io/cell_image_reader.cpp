// Reading an image for metadetection; see cell_image_reader.hpp.
#include "io/cell_image_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>
#include <stdexcept>

#include "io/fits_file.hpp"

namespace stampede::io {
namespace {

[[noreturn]] void fail(FitsFile& f, const std::string& what) { throw FitsError(f.describe() + ": " + what); }

// A plane given twice (two WEIGHT HDUs) is refused rather than one of them silently used.
void refuse_repeated_planes(FitsFile& f) {
  const int here = f.hdu_index();
  std::set<std::string> seen;
  for (int k = 1; k < f.hdu_count(); ++k) {
    f.move_to(k);
    std::string name = f.read_key_string("EXTNAME").value_or("");
    for (char& c : name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    for (const char* plane : {"WEIGHT", "BMASK", "ORMASK", "MFRAC", "NOISE", "PSF"})
      if (name == plane && !seen.insert(name).second) fail(f, std::string("a second ") + plane + " HDU: give each plane once");
  }
  f.move_to(here);
}

CellImageShape primary_shape(FitsFile& f) {
  f.move_to(0);
  if (f.hdu_kind() != FitsFile::HduKind::kImage) fail(f, "HDU 0 must hold the image (a 2-D image HDU)");
  const FitsFile::ImageShape s = f.image_shape();
  return {s.nx, s.ny, 0.0};
}

// Arcsec per pixel: SCALE, else the WCS's sqrt|det CD| (or |CDELT1| with |CDELT2| equal).
double pixel_scale(FitsFile& f) {
  if (auto scale = f.read_key_double("SCALE")) {
    if (!(*scale > 0) || !std::isfinite(*scale)) fail(f, "keyword 'SCALE' must be a positive number of arcsec per pixel");
    return *scale;
  }
  auto cd11 = f.read_key_double("CD1_1"), cd12 = f.read_key_double("CD1_2"), cd21 = f.read_key_double("CD2_1"),
       cd22 = f.read_key_double("CD2_2");
  if (cd11 && cd22) {
    const double det = *cd11 * *cd22 - cd12.value_or(0) * cd21.value_or(0);
    if (!(std::abs(det) > 0) || !std::isfinite(det)) fail(f, "the WCS CD matrix is singular");
    return std::sqrt(std::abs(det)) * 3600.0;
  }
  auto d1 = f.read_key_double("CDELT1"), d2 = f.read_key_double("CDELT2");
  if (d1 && d2) {
    if (!(std::abs(*d1) > 0) || std::abs(std::abs(*d1) / std::abs(*d2) - 1) > 1e-6)
      fail(f, "CDELT1 and CDELT2 must be non-zero and of equal size (square pixels)");
    return std::abs(*d1) * 3600.0;
  }
  fail(f, "no pixel scale: header keyword 'SCALE' (arcsec per pixel) or a WCS (CD1_1..CD2_2 or CDELT1, CDELT2)");
}

std::vector<double> plane(FitsFile& f, const CellImageShape& shape) {
  const FitsFile::ImageShape s = f.image_shape();
  if (s.nx != shape.width || s.ny != shape.height) {
    std::ostringstream m;
    m << "is " << s.nx << " x " << s.ny << " pixels, the image " << shape.width << " x " << shape.height;
    fail(f, m.str());
  }
  return f.read_image();
}

}  // namespace

void apply_cell_masks(std::span<const double> bmask, CellImage* image) {
  for (double w : image->weight)
    if (w < 0) throw std::invalid_argument("negative weights: the weights must be inverse variances (0 masks)");
  image->masked = 0;
  const bool noise = !image->noise.empty();
  for (std::size_t i = 0; i < image->pixels.size(); ++i) {
    const bool by_bmask = !bmask.empty() && bmask[i] != 0;
    const bool not_finite = !std::isfinite(image->pixels[i]) || !std::isfinite(image->weight[i]) ||
                            (noise && !std::isfinite(image->noise[i]));
    if (by_bmask || not_finite) image->weight[i] = 0;
    if (image->weight[i] == 0) {
      image->pixels[i] = 0, ++image->masked;
      if (noise) image->noise[i] = 0;
      ++(by_bmask ? image->masked_by_bmask : not_finite ? image->masked_not_finite : image->masked_by_weight);
    }
  }
}

CellImageShape read_cell_image_shape(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  CellImageShape shape = primary_shape(f);
  shape.pixel_scale = pixel_scale(f);
  return shape;
}

void mask_bits(std::span<const double> plane, std::span<std::int32_t> out) {
  for (std::size_t i = 0; i < plane.size(); ++i) {
    const double v = plane[i];
    out[i] = v >= -2147483648.0 && v < 4294967296.0 && v == std::floor(v)
                 ? static_cast<std::int32_t>(static_cast<std::uint32_t>(static_cast<std::int64_t>(v)))
                 : 0;
  }
}

std::string mfrac_problem(std::span<const double> plane, long width) {
  for (std::size_t i = 0; i < plane.size(); ++i)
    if (!(plane[i] >= 0 && plane[i] <= 1)) {
      std::ostringstream m;
      m << "masked fraction " << plane[i] << " at pixel (" << static_cast<long>(i) % width << ", "
        << static_cast<long>(i) / width << ") (0-based x, y): an MFRAC plane holds fractions in [0, 1]";
      return m.str();
    }
  return "";
}

std::vector<std::int32_t> mask_bits(std::span<const double> plane) {
  std::vector<std::int32_t> bits(plane.size());
  mask_bits(plane, bits);
  return bits;
}

std::string CellImage::masked_text() const {
  std::string out;
  const auto add = [&out](long long n, const char* why) {
    if (n > 0) out += (out.empty() ? "" : ", ") + std::to_string(n) + why;
  };
  add(masked_by_bmask, " by BMASK");
  add(masked_not_finite, " NaN or infinite");
  add(masked_by_weight, " of zero weight");
  return out;
}

std::string cell_psf_problem(const PsfImage& psf) {
  double sum = 0, sx = 0, sy = 0;
  for (int y = 0; y < psf.ny; ++y)
    for (int x = 0; x < psf.nx; ++x) {
      const double v = psf.pixels[static_cast<std::size_t>(y) * psf.nx + x];
      sum += v, sx += v * x, sy += v * y;
    }
  if (!(sum > 0) || !std::isfinite(sum)) return "the PSF image's sum is not positive and finite";
  if (psf.nx % 2 == 0 || psf.ny % 2 == 0)
    return "the PSF image is " + std::to_string(psf.nx) + " x " + std::to_string(psf.ny) +
           " pixels: its sides must be odd, the PSF centred on the middle pixel";
  // To a millionth of a pixel: the sums' rounding is not an offset worth printing.
  const double dx = std::round((sx / sum - 0.5 * (psf.nx - 1)) * 1e6) / 1e6 + 0.0,
               dy = std::round((sy / sum - 0.5 * (psf.ny - 1)) * 1e6) / 1e6 + 0.0;
  if (std::hypot(dx, dy) > 0.5) {
    std::ostringstream m;
    m << "the PSF image's centroid is (" << dx << ", " << dy << ") pixels from its middle pixel: it must be centred "
      << "there (every position would move by the offset)";
    return m.str();
  }
  return "";
}

std::string cell_noise_problem(const CellImage& image) {
  // The mean of noise^2 x weight over the unmasked pixels: 1 for a realisation of the weights' noise
  // (masked pixels have weight 0 and add nothing; no division per pixel).
  double sum = 0;
  long long unmasked = 0;
  for (std::size_t i = 0; i < image.noise.size(); ++i) {
    sum += image.noise[i] * image.noise[i] * image.weight[i];
    unmasked += image.weight[i] > 0;
  }
  if (image.noise.empty() || unmasked == 0) return "";
  const double ratio = std::sqrt(sum / static_cast<double>(unmasked));
  if (ratio >= 0.5 && ratio <= 2) return "";
  std::ostringstream m;
  m << "the NOISE plane's rms is " << ratio << " times the noise the weights state: it must be a realisation of "
    << "the image's noise (ratio in [0.5, 2])";
  return m.str();
}

namespace {

// z with 0.5 erfc(z / sqrt 2) = p: the unit Gaussian's quantile p lies z below its mean.
double gaussian_depth(double p) {
  double lo = 0, hi = 10;
  for (int i = 0; i < 60; ++i) {
    const double z = 0.5 * (lo + hi);
    (0.5 * std::erfc(z / std::sqrt(2.0)) > p ? lo : hi) = z;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

double cell_sky_level(std::span<const double> pixels, std::span<const double> weight, std::vector<double>* scratch) {
  scratch->clear();
  for (std::size_t i = 0; i < pixels.size(); ++i)
    if (weight[i] > 0) scratch->push_back(pixels[i] * std::sqrt(weight[i]));
  const double n = static_cast<double>(scratch->size());
  if (n < 64) return NAN;
  // Two low quantiles, p small enough that the sources' light hardly reaches it (with at least 8
  // pixels below: a scatter of ~0.1 sigma) and one 2 sigma below the sky: their distance gives the
  // pixels' own noise, at most the weights' (an image without noise is its sky at p).
  const double p = std::max(0.001, 8 / n), p2 = std::max(0.0228, 4 * p);
  const double z = gaussian_depth(p), z2 = gaussian_depth(p2);
  const auto k2 = scratch->begin() + static_cast<std::ptrdiff_t>(p2 * (n - 1));
  std::nth_element(scratch->begin(), k2, scratch->end());
  const auto k = scratch->begin() + static_cast<std::ptrdiff_t>(p * (n - 1));
  std::nth_element(scratch->begin(), k, k2);
  const double sigma = std::clamp((*k2 - *k) / (z - z2), 0.0, 1.0);
  return *k + z * sigma;
}

std::string cell_sky_problem(double sky_level) {
  if (!(std::abs(sky_level) > kMaxCellSkyLevel)) return "";
  std::ostringstream m;
  m << "the cell's faintest pixels put its sky at " << std::showpos << std::fixed << std::setprecision(2) << sky_level
    << std::noshowpos << std::defaultfloat << " sigma of its noise (at most " << kMaxCellSkyLevel << " in magnitude): "
    << "metadetection needs a background-subtracted image whose sources leave some sky";
  return m.str();
}

SceneRecord read_scene_record(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  SceneRecord r;
  r.g1 = f.read_key_double("G1").value_or(NAN), r.g2 = f.read_key_double("G2").value_or(NAN);
  if (const auto seed = f.read_key_long("SEED")) r.seed = std::to_string(*seed);
  if (const auto rotated = f.read_key_long("ROTATED")) r.rotated = std::to_string(*rotated);
  return r;
}

CellImage read_cell_image(const std::string& path, bool with_psf) {
  FitsFile f = FitsFile::open_read(path);
  CellImage out;
  const CellImageShape shape = primary_shape(f);
  out.width = shape.width, out.height = shape.height;
  out.pixel_scale = pixel_scale(f);
  out.wcs = read_celestial_wcs(f);
  out.g1 = f.read_key_double("G1").value_or(NAN), out.g2 = f.read_key_double("G2").value_or(NAN);
  out.pixels = f.read_image();
  refuse_repeated_planes(f);
  if (!f.move_to_if_present("WEIGHT"))
    fail(f, "no WEIGHT HDU (inverse variance): detection needs the noise level");
  out.weight = plane(f, shape);
  std::vector<double> mask;
  if (f.move_to_if_present("BMASK")) mask = plane(f, shape), out.bmask = mask_bits(mask);
  if (f.move_to_if_present("ORMASK")) out.ormask = mask_bits(plane(f, shape));
  if (f.move_to_if_present("MFRAC")) {
    out.mfrac = plane(f, shape);
    if (const std::string why = mfrac_problem(out.mfrac, out.width); !why.empty()) fail(f, why);
  }
  if (f.move_to_if_present("NOISE")) out.noise = plane(f, shape);
  f.move_to("WEIGHT");
  try {
    apply_cell_masks(mask, &out);
  } catch (const std::invalid_argument& e) {
    fail(f, e.what());
  }
  if (const std::string why = cell_noise_problem(out); !why.empty()) {
    f.move_to("NOISE");
    fail(f, why);
  }
  if (!with_psf) return out;
  if (!f.move_to_if_present("PSF")) {
    f.move_to(0);  // the file lacks it: named at its primary HDU, not the last one read
    fail(f, "no PSF HDU (a centred PSF image at the image's pixel scale)");
  }
  if (auto scale = f.read_key_double("SCALE"); scale && std::abs(*scale / out.pixel_scale - 1) > 1e-6) {
    std::ostringstream m;
    m << "the PSF's SCALE " << *scale << " arcsec/px differs from the image's " << out.pixel_scale
      << ": the PSF must be sampled at the image's pixel scale";
    fail(f, m.str());
  }
  const FitsFile::ImageShape ps = f.image_shape();
  auto psf = std::make_shared<PsfImage>();
  psf->nx = static_cast<int>(ps.nx), psf->ny = static_cast<int>(ps.ny);
  psf->pixels = f.read_image();
  if (const std::string why = cell_psf_problem(*psf); !why.empty()) fail(f, why);
  out.psf = std::move(psf);
  return out;
}

}  // namespace stampede::io
