// Multi-epoch survey simulations (`stampede sim meds`; experiments in docs/meds.md): objects seen
// in several single-epoch cutouts under one constant shear, each cutout with a random affine WCS
// (any rotation, pixel scale within +-scale_jitter, a WCS shear up to wcs_shear), the PSF of its
// source image (a Moffat of its own FWHM and e; each object's epochs use distinct images), a zero
// point of its own, noise, optionally a bad column (bmask bit 1, garbage pixels) and a neighbour
// labelled in the seg map. Objects 2m and 2m+1 are a ring pair: the same galaxy turned by 90
// degrees, seen through the same epochs.
//
// Galaxies are drawn in (u, v) by the exact renderer through each cutout's Jacobian (its frame
// maths is checked against an independent pixel-frame derivation to 1e-10, render/exact_renderer)
// with the image PSF the tile's PSFEx file holds (the float32 samples), so a noise-free fit
// measures the fitter and the input path, not a PSF model error. Every random number comes from a
// stream keyed by (seed, pair or object, purpose): an object is the same for any thread count.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/render/exact_renderer.hpp"

namespace stampede {

struct MedsSimOptions {
  int objects = 100;  // even: ring pairs
  int epochs = 4;     // cutouts per object besides the coadd slot
  int images = 8;     // source images, each with its own PSF and zero point; >= epochs
  int box_size = 48;
  double pixel_scale = 0.263;   // arcsec
  double scale_jitter = 0.03;   // each cutout's scale within +- this fraction
  double wcs_shear = 0.02;      // each cutout's WCS shear components within +- this
  bool rotate = true;           // random rotations (false, with no jitter, shear or scale 1: J = 1)
  double psf_beta = 3;
  double psf_fwhm_min = 0.9, psf_fwhm_max = 1.2;  // arcsec (in pixels at pixel_scale)
  double psf_e_max = 0.06;                         // each PSF's e1, e2 within +- this
  int psf_size = 25;                               // PSFEx samples per side (odd)
  bool psf_cutouts = false;  // also write each cutout's PSF image into the tile (HDU 'psf')
  double g1 = 0.02, g2 = -0.015;                   // the shear
  double snr = 30;            // the object's S/N over all its epochs: sqrt(sum s^2 I^2) / noise_sigma
  double noise_sigma = 1;     // per pixel, every epoch
  bool noise_free = false;
  double hlr_min = 0.35, hlr_max = 0.7;  // disc half-light radius sqrt(ab), arcsec
  double bulge_fraction_max = 0.5;       // bulge flux fraction ~ U[0, max]
  double e_sigma = 0.25, e_max = 0.8;    // intrinsic e per component ~ N(0, e_sigma), |e| < e_max
  double centre_offset = 0.2;            // (u0, v0) ~ U(-offset, offset) arcsec
  double magzp = 30, magzp_jitter = 0.3; // each image's zero point: magzp + U(-jitter, jitter)
  double bad_column_fraction = 0;        // probability per cutout of one bad column
  double neighbour_fraction = 0;         // probability per ring pair of a neighbour in every epoch
  std::uint64_t seed = 11;
  // Multi-band tiles (`sim meds --bands`): band `band` of `bands` sees the same galaxies (shape,
  // size, position, neighbours) through its own images (PSFs narrower by up to 10 % towards the
  // last band, zero points 0.25 mag apart), epochs, WCSs and noise, with the bulge fraction
  // scaled from 0.5x (first band) to 1.5x (last band) and the flux set for --snr in each band.
  // Band 0 of 1 is the one-band tile, bit for bit.
  int band = 0, bands = 1;
  // Message names the option as on the command line (--objects, ...), its value and the rule.
  bool IsValid(std::string* why) const;
};

// One source image: its PSF (psf_size^2 pixel-integrated samples, unit sum) and zero point.
struct MedsSimImage {
  double psf_fwhm = 0, psf_e1 = 0, psf_e2 = 0;  // pixels, Moffat parameters
  std::vector<double> psf;                        // float32-rounded samples
  double magzp = 0;
};

struct MedsSimCutout {
  int image = 0;  // source image (file_id is image + 1: row 0 of image_info is the coadd)
  double dudrow = 0, dudcol = 0, dvdrow = 0, dvdcol = 0;
  double orig_row = 0, orig_col = 0;              // the object in its source image, 0-based
  long long orig_start_row = 0, orig_start_col = 0;  // the cutout's corner there (MEDS's conventions)
  double cutout_row = 0, cutout_col = 0;          // the object in the cutout
  std::vector<double> pixels, weight, seg, bmask;  // box_size^2 each; seg: 1 the object, 2 its neighbour
  int bad_column = -1;                             // -1: none
};

struct MedsSimObject {
  long long index = 0, pair = 0;
  double e1_int = 0, e2_int = 0, e1_obs = 0, e2_obs = 0, hlr = 0, flux = 0, bulge_frac = 0, u0 = 0, v0 = 0;
  bool neighbour = false;
  std::vector<MedsSimCutout> cutouts;  // the single epochs (the tile's coadd slot is left empty)
};

class MedsSimulator {
 public:
  explicit MedsSimulator(const MedsSimOptions& options);  // validates (std::invalid_argument)
  ~MedsSimulator();
  const MedsSimOptions& options() const { return options_; }
  const std::vector<MedsSimImage>& images() const { return images_; }
  // Object `index`; thread-safe given a workspace per thread (make_workspace).
  struct Workspace {
    std::unique_ptr<ExactRenderer> renderer;
    std::vector<std::shared_ptr<const PreparedPsf>> psfs;  // per image, prepared on first use
  };
  std::unique_ptr<Workspace> make_workspace() const;
  MedsSimObject simulate(long long index, Workspace& ws) const;
  // Object `index`'s cutouts' geometry (image, Jacobian, positions) without pixels: what a tile's
  // layout needs before any pixel is drawn. The same for both members of a ring pair.
  std::vector<MedsSimCutout> epochs(long long index) const;

 private:
  MedsSimOptions options_;
  std::vector<MedsSimImage> images_;
  std::vector<std::shared_ptr<const PsfImage>> psf_images_;
};

}  // namespace stampede
