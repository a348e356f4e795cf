// Reading an image for metadetection; see cell_image_reader.hpp.
#include "io/cell_image_reader.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "io/fits_file.hpp"

namespace stampede::io {
namespace {

[[noreturn]] void fail(FitsFile& f, const std::string& what) { throw FitsError(f.describe() + ": " + what); }

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
    if (!bmask.empty() && bmask[i] != 0) image->weight[i] = 0;
    if (!std::isfinite(image->pixels[i]) || !std::isfinite(image->weight[i])) image->weight[i] = 0;
    if (noise && !std::isfinite(image->noise[i])) image->weight[i] = 0;
    if (image->weight[i] == 0) {
      image->pixels[i] = 0, ++image->masked;
      if (noise) image->noise[i] = 0;
    }
  }
}

CellImageShape read_cell_image_shape(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  CellImageShape shape = primary_shape(f);
  shape.pixel_scale = pixel_scale(f);
  return shape;
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
  out.g1 = f.read_key_double("G1").value_or(NAN), out.g2 = f.read_key_double("G2").value_or(NAN);
  out.pixels = f.read_image();
  if (!f.move_to_if_present("WEIGHT"))
    fail(f, "no WEIGHT HDU (inverse variance): detection needs the noise level");
  out.weight = plane(f, shape);
  std::vector<double> mask;
  if (f.move_to_if_present("BMASK")) mask = plane(f, shape);
  if (f.move_to_if_present("NOISE")) out.noise = plane(f, shape);
  f.move_to("WEIGHT");
  try {
    apply_cell_masks(mask, &out);
  } catch (const std::invalid_argument& e) {
    fail(f, e.what());
  }
  if (!with_psf) return out;
  if (!f.move_to_if_present("PSF")) fail(f, "no PSF HDU (a centred PSF image at the image's pixel scale)");
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
  double sum = 0;
  for (double v : psf->pixels) sum += v;
  if (!(sum > 0) || !std::isfinite(sum)) fail(f, "the PSF image's sum is not positive and finite");
  out.psf = std::move(psf);
  return out;
}

}  // namespace stampede::io
