// GREAT08-like constant-shear simulations (Bridle et al. 2010), in the layout of the GalSim sets
// in shared/data/galsim-great08-mini: each set is a grid of stamps of galaxies sharing one shear,
// objects 2m and 2m+1 a 90-degree-rotated ring pair (intrinsic shapes opposite, so shape noise
// cancels in the pair mean), every galaxy scaled to the same matched-filter S/N.
//
// Galaxies are drawn by SimRenderer (exact pixel integrals to ~1e-6 of the peak), so a
// noise-free fit of a simulation measures the fitter, not the simulator. Every random number comes
// from a stream keyed by (seed, set, pair or object, purpose): a set is identical for any thread
// count and any subset of sets.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/sim/sim_renderer.hpp"

namespace stampede {

// The GREAT08 branch types.
enum class SimGalaxyType {
  kBulgeDisc,      // "bd": co-elliptical bulge + disc, equal half-light radii, common centre
  kBulgePlusDisc,  // "b+d": bulge + disc with different radii, misaligned shapes, offset centres
  kBulge,          // "bulge": de Vaucouleurs only
  kDisc,           // "disc": exponential only
};
const char* sim_galaxy_type_name(SimGalaxyType t);
bool parse_sim_galaxy_type(const std::string& name, SimGalaxyType* out);

struct Great08SimOptions {
  int sets = 2;
  int grid = 20;         // stamps per side: grid^2 objects per set
  int stamp_size = 39;   // pixels per stamp side
  double snr = 40.0;     // sqrt(sum_pixels I^2) / noise_sigma of each noise-free stamp
  double noise_sigma = 1.0;  // Gaussian sigma per pixel; also the flux reference when noise_free
  bool noise_free = false;
  // Noise pairs: objects 4q..4q+3 are a ring pair drawn twice, the second time with the first
  // time's noise negated (4q+2 = 4q with -n, 4q+3 = 4q+1 with -n), all with pair label q. The
  // group mean cancels shape noise and odd orders of pixel noise, leaving the noise bias with a
  // far smaller scatter; expectations are unchanged (the noise is symmetric).
  bool noise_pairs = false;
  // Shear pairs: set 2j+1 is set 2j (same galaxies, same noise) under the opposite shear -g. Half
  // the difference of the pair's estimates is (1 + m) g with the noise common to both cancelling,
  // so m is measured with far fewer galaxies than from independent sets (Sheldon & Huff 2017).
  bool shear_pairs = false;
  double size_ratio = 1.4;   // Rgp/Rp: FWHM(round galaxy (x) PSF) / FWHM(PSF), no pixel; > 1
  PsfModel psf = default_psf();
  SimGalaxyType galaxy_type = SimGalaxyType::kBulgeDisc;
  double e_sigma = 0.25;   // intrinsic e per component ~ N(0, e_sigma), redrawn until |e| < e_max
  double e_max = 0.9;
  double shear_max = 0.05;  // each set's g1, g2 ~ U(-shear_max, shear_max)
  // When set, every set's shear instead (negated in the odd set of a shear pair): a fixed |g| gives
  // m the leverage of the largest shear in every pair.
  bool fixed_shear = false;
  double shear1 = 0, shear2 = 0;
  double centre_offset = 0.5;  // galaxy centre ~ stamp centre + U[-centre_offset, centre_offset) per axis
  double bulge_fraction_min = 0.0, bulge_fraction_max = 1.0;  // bd and b+d: U[min, max] of the flux
  // b+d only: bulge / disc half-light radius; sigma (degrees) of the bulge's position angle about
  // the disc's; bulge centre offset uniform in a disc of this radius (pixels) before shear.
  double bd_radius_ratio = 0.6;
  double bd_misalignment_deg = 20.0;
  double bd_offset = 0.3;
  std::uint64_t seed = 7;

  static PsfModel default_psf();  // Moffat beta 3, FWHM 2.85 px, e = (0, 0.05), as GREAT08-mini
  // Message names the field (snr, stamp_size, ...; Python's keywords), its value and the rule;
  // front ends translate fields to their own spelling (the command line: tools/sim_command).
  bool IsValid(std::string* why) const;
};

// One row of the truth table (columns as in the GalSim sets). The galaxy-level shape columns
// (e*_int, e*_obs, hlr) describe the disc, or the bulge for bulge-only galaxies.
struct SimObjectTruth {
  long long index = 0, ix = 0, iy = 0, pair = 0;
  double x_centre = 0, y_centre = 0;  // in the stamp (0-based, pixel centres at integers)
  double x_image = 0, y_image = 0;    // in the whole set image
  double e1_int = 0, e2_int = 0, g1 = 0, g2 = 0, e1_obs = 0, e2_obs = 0;
  double hlr = 0, bulge_frac = 0, flux = 0, bulge_flux = 0, disc_flux = 0;
  double stamp_flux = 0;  // sum of the noise-free stamp
  double snr = 0;         // sqrt(sum I^2) / noise reference of the noise-free stamp
  double hlr_bulge = 0, e1_int_bulge = 0, e2_int_bulge = 0;
  double bulge_dx = 0, bulge_dy = 0;  // bulge centre minus disc centre in the image (after shear)
};

struct SimSet {
  int index = 0;
  double shear1 = 0, shear2 = 0;
  std::uint64_t noise_seed = 0;       // 0 when noise-free
  int width = 0;                      // grid * stamp_size pixels per side
  std::vector<double> image;          // width x width, row-major
  std::vector<SimObjectTruth> truth;  // grid^2 rows, index = iy * grid + ix
};

class Great08Simulator {
 public:
  // Validates (throws std::invalid_argument with IsValid's message) and builds the renderer.
  explicit Great08Simulator(const Great08SimOptions& options);

  const Great08SimOptions& options() const { return options_; }
  // Draws set k, in parallel over ring pairs on the calling TBB arena.
  SimSet simulate_set(int k) const;
  // The PSF as a stamp_size^2 pixel-integrated image centred on the middle pixel (unit flux profile).
  std::vector<double> psf_image() const;
  // The PSF without the pixel at `oversampling` samples per pixel, (stamp_size * oversampling)^2,
  // values = surface brightness x sample area, centre on the middle sample.
  std::vector<double> psf_oversampled(int oversampling) const;
  // Half-light radius of the disc (the bulge's follows the type's radius ratio) at which a round
  // galaxy with this bulge fraction has the requested size ratio.
  double half_light_radius(double bulge_fraction) const;
  const SimRenderer& renderer() const { return *renderer_; }

 private:
  Great08SimOptions options_;
  double psf_fwhm_ = 0;
  std::unique_ptr<SimRenderer> renderer_;
  std::unique_ptr<RoundFwhmSolver> fwhm_solver_;  // renderer_'s, for half_light_radius (once built)
  double bulge_radius_ratio() const;
  std::vector<SimComponent> round_components(double bulge_fraction, double disc_hlr) const;
};

}  // namespace stampede
