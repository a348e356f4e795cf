// Reads an image for metadetection (`stampede metadetect IMAGE.fits`): HDU 0 the image, with the
// pixel scale in header keyword SCALE (arcsec per pixel) or a WCS (CD matrix or CDELT, degrees);
// extensions found by EXTNAME: WEIGHT (inverse variance, required: detection thresholds on the
// noise), BMASK (non-zero masks a pixel; its bits are reported per detection), ORMASK (bits reported
// per detection, masking nothing), MFRAC (each pixel's masked fraction in [0, 1], which mfrac
// averages), NOISE (a realisation of the image's noise: metacal's
// fixnoise field, else one is drawn from the weight), PSF (a centred PSF image at the image's pixel
// scale, required; a SCALE keyword there must equal the image's), each at most once. NaN or infinite pixels, weights
// and noise values are masked (weight 0). What `stampede sim cells` writes (io/cell_image_writer) reads back.
//
// Every failure throws FitsError naming the file, the HDU and the keyword or the rule.
#pragma once
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "io/celestial_wcs.hpp"

namespace stampede::io {

struct CellImageShape {
  long width = 0, height = 0;
  double pixel_scale = 0;  // arcsec per pixel
};

struct CellImage {
  long width = 0, height = 0;
  double pixel_scale = 0;  // arcsec per pixel
  std::vector<double> pixels, weight;  // width x height, row-major; weight 0 masks
  std::vector<double> noise;           // the NOISE plane (0 where masked); empty: none
  // The BMASK plane's bits (which mask) and the ORMASK plane's (which do not: reported only), as
  // 32-bit patterns; empty: no such plane.
  std::vector<std::int32_t> bmask, ormask;
  // The MFRAC plane: each pixel's masked fraction in [0, 1] (e.g. of the epochs a coadd pixel
  // combines); empty: none.
  std::vector<double> mfrac;
  std::shared_ptr<const PsfImage> psf;  // null when read without it
  long long masked = 0;  // pixels masked (weight 0, BMASK, non-finite)
  // Why, each pixel counted once in this order: a BMASK bit, a NaN or infinite value (pixel,
  // weight or noise), a zero (or NaN) weight.
  long long masked_by_bmask = 0, masked_not_finite = 0, masked_by_weight = 0;
  // "N by BMASK, M NaN or infinite, K of zero weight" (the non-zero counts), for messages.
  std::string masked_text() const;
  // The shear a simulation drew the scene with (HDU 0's G1, G2, as `sim cells` writes them); NaN
  // when absent.
  double g1 = NAN, g2 = NAN;
  // HDU 0's celestial WCS (RA---TAN, DEC--TAN), which places a star catalogue's ra, dec; nullopt
  // without CTYPE1.
  std::optional<CelestialWcs> wcs;
};

// The masking rules a read applies, for an image built in memory (Python): a non-zero bmask value
// (bmask empty: none), a non-finite pixel, weight or noise value, or a zero weight masks the pixel:
// its weight, value and noise become 0, and `masked` counts it. Throws std::invalid_argument for a negative weight.
void apply_cell_masks(std::span<const double> bmask, CellImage* image);
// A mask plane's values as 32-bit patterns (an integer in [-2^31, 2^32) keeps its bits; anything
// else reads as 0).
std::vector<std::int32_t> mask_bits(std::span<const double> plane);
// Why an MFRAC plane is not one: a value outside [0, 1] or not finite (its first, with its pixel);
// "" when it is.
std::string mfrac_problem(std::span<const double> plane, long width);
void mask_bits(std::span<const double> plane, std::span<std::int32_t> out);  // out: plane's size

// Why `psf` cannot be a cell's PSF image: its sum is not positive and finite, a side is even (no
// centre pixel), or its centroid is more than half a pixel from the centre pixel (every position
// would move by the offset); "" when it can.
std::string cell_psf_problem(const PsfImage& psf);
// Why the image's NOISE plane is not a realisation of the noise its weights state: its rms over the
// unmasked pixels outside [0.5, 2] times the weights' (fixnoise would add the wrong noise); "" when
// it is, or there is none.
std::string cell_noise_problem(const CellImage& image);

// The sky level of a cell's unmasked pixels in units of their noise (each pixel times the square
// root of its weight): from the distribution's lowest quantile (0.1 %, or 8 pixels), which the
// sources' light hardly reaches, and the pixels' noise (from a second quantile; at most the
// weights'); NaN under 64 unmasked pixels. `scratch` is reused.
double cell_sky_level(std::span<const double> pixels, std::span<const double> weight, std::vector<double>* scratch);
// The largest |sky level| a cell may have (its noise's units): metadetection measures on
// background-subtracted images; a sky beyond this lifts every pixel over the detection threshold
// and moves every detection's moments. Not lower: the faintest pixels of a noise-free simulation's
// crowded cell lie up to about 1 sigma above zero (docs/reliability.md).
inline constexpr double kMaxCellSkyLevel = 2.0;
// Why a cell with that sky level cannot be measured ("" when it can).
std::string cell_sky_problem(double sky_level);

// HDU 0's size and pixel scale alone (cheap: the run lays out its cells, and checks that several
// bands' images match, before reading pixels).
CellImageShape read_cell_image_shape(const std::string& path);

// What a simulated image records of its scene in HDU 0 (as `sim cells` writes it: G1, G2, SEED,
// ROTATED): how metrics tells the images of a shear pair apart. Absent: NaN, "".
struct SceneRecord {
  double g1 = NAN, g2 = NAN;
  std::string seed, rotated;  // the integers' text
};
SceneRecord read_scene_record(const std::string& path);

// with_psf false: the PSF HDU is neither required nor read (a PSFEx model gives the PSF).
CellImage read_cell_image(const std::string& path, bool with_psf = true);

}  // namespace stampede::io
