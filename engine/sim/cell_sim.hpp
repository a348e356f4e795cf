// Test cells for metadetection (`stampede sim cells`; the shear test's simulation in
// ../shared/reference/metadetection.md): square cells of galaxies on a grid or at Poisson random
// positions (so that blends occur), one constant lensing shear (of the shapes and of the positions,
// about the cell's centre), a Gaussian or Moffat PSF per band,
// white noise set by a per-object S/N, in one or several bands. A shear pair is the same cell
// drawn under -g: the same galaxies and noise, the scene (positions too) sheared the other way.
//
// Each galaxy is drawn by SimRenderer (exact PSF-convolved pixel integrals) into a stamp of its
// own, its radius the one holding all but 1e-5 of each component's light (cell_light_radius) plus
// the PSF's reach (SimRenderer::psf_tail_radius), capped at 255 pixels (a de Vaucouleurs bulge of
// 2 px loses ~3e-4 of its light to the cap), and added into the cell: pixel values do not depend
// on where a stamp lies, so overlapping stamps sum to the exact blend.
// Numerics only, no I/O (io/cell_image_writer writes the files, app/cell_simulation runs them).
//
// Every random number comes from a stream keyed by (seed, purpose, cell[, object or band]):
// a cell is the same whatever the thread count, the other cells and the sign of the shear.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/sim/sim_renderer.hpp"

namespace stampede {

enum class CellLayout {
  kGrid,    // grid x grid objects evenly inside the buffer, each shifted by U(-shift, shift) px per axis
  kRandom,  // a Poisson number (density per arcmin^2 x the cell's area) at uniform positions over the cell
};
enum class CellGalaxyModel {
  kExponential,  // "exp": an exponential disc
  kBulgeDisc,    // "bd": co-elliptical de Vaucouleurs bulge + exponential disc, one radius and centre
};
enum class CellPsfKind { kGaussian, kMoffat };
const char* cell_layout_name(CellLayout v);
const char* cell_galaxy_model_name(CellGalaxyModel v);
const char* cell_psf_kind_name(CellPsfKind v);
bool parse_cell_layout(const std::string& name, CellLayout* out);
bool parse_cell_galaxy_model(const std::string& name, CellGalaxyModel* out);
bool parse_cell_psf_kind(const std::string& name, CellPsfKind* out);

// Defaults: the metadetection shear test's cell.
struct CellSimOptions {
  int size = 251;             // pixels per side
  double pixel_scale = 0.25;  // arcsec per pixel
  int buffer = 34;            // pixels at each edge where detections are dropped (the grid stays inside)
  CellLayout layout = CellLayout::kGrid;
  int grid = 7;               // kGrid: objects per side
  double grid_shift = 1.0;    // kGrid: each position shifted by U(-shift, shift) pixels per axis
  double density = 100;       // kRandom: mean objects per arcmin^2
  // kRandom: no object within keep_clear px of the lines of the buffer's inner edge. An object there
  // moves in or out of the region a cell keeps under the shear: a single-cell test (no neighbouring
  // cell to take it) reads that as noise in <e>; a band of a few pixels removes it.
  double keep_clear = 0;
  // Positions as the reference package's shear test draws them: kGrid spans the inner region edge
  // to edge (object i at c + (i - (grid - 1) / 2) / ((grid - 1) / 2) x h, h the inner half-width
  // (size - 2 buffer) / 2); kRandom has int(density x the inner region's area) objects uniform over
  // the inner region; each then shifted by U(-grid_shift, grid_shift) px per axis.
  bool reference_positions = false;
  CellGalaxyModel model = CellGalaxyModel::kExponential;
  double hlr = 0.5;           // half-light radius sqrt(ab), arcsec (both components of bd)
  double flux = 1000;         // each galaxy's total flux in the first band (counts)
  double bulge_fraction_max = 0.5;  // bd: bulge flux fraction ~ U[0, max]
  double shape_noise = 0.2;   // intrinsic e per component ~ N(0, shape_noise), redrawn until |e| < e_max; 0: round
  double e_max = 0.8;
  CellPsfKind psf = CellPsfKind::kGaussian;
  double psf_fwhm = 0.9;      // arcsec, the first band's
  double psf_beta = 2.5;      // kMoffat
  int psf_size = 51;          // the PSF image's side (odd), pixels
  double g1 = 0.02, g2 = 0.0; // the shear (reduced), applied to every galaxy's intrinsic shape
  // The per-object S/N: noise sigma = sqrt(sum_bands sum_pixels I^2) / snr for the reference
  // galaxy (round, the model's mean bulge fraction, drawn alone with each band's PSF): one sigma for
  // every band, so the S/N over all bands is snr.
  double snr = 20;
  // The scene turned by 90 degrees about the cell's centre (intrinsic shapes negated, positions
  // rotated; noise unchanged): with the unrotated scene it cancels the intrinsic shapes' share of a
  // shear test's variance, blends and objects at the cells' edges included, as ring pairs do.
  bool rotate = false;
  bool noise_free = false;    // noise sigma 1e-6 of the S/N's: a noiseless cell with consistent weights
  // Bright stars per cell (issue 56's masked shear tests): unlensed point sources at whole pixels
  // anywhere in the cell, the same under any shear (turned with the scene), each flux
  // log-uniform in [10, star_flux] x the galaxies' flux.
  int stars = 0;
  double star_flux = 1000;
  // Bad columns per cell (detector defects): vertical runs of hot pixels (1e3 sigma), at least a
  // quarter of the cell long, the same under any shear (turned with the scene), each pixel flagged
  // in BMASK (bit 1).
  int bad_columns = 0;
  int bands = 1;              // band b of B: flux x (1 + 0.5 b / (B - 1)), PSF FWHM x (1 - 0.1 b / (B - 1)),
                              // bd bulge fraction x (0.5 + b / (B - 1)) (capped at 1)
  std::uint64_t seed = 42;
  // Message names the option as on the command line (--size, --snr, ...), its value and the rule.
  bool IsValid(std::string* why) const;
};

// One galaxy (the truth).
struct CellObject {
  long long id = 0;          // index within its cell
  double x = 0, y = 0;       // centre in the cell, pixels, 0-based (pixel centres at integers)
  double flux = 0;           // in the first band; band b's is flux x bands()[b].flux_scale
  double hlr = 0;            // arcsec
  double bulge_frac = 0;     // in the first band (0 for exp)
  double e1_int = 0, e2_int = 0, e1_obs = 0, e2_obs = 0;
  double snr = 0;            // sqrt(sum_bands sum I^2) / noise sigma of the galaxy drawn alone
};

// One star (the truth; the cell image's STARS table): its mask radius the distance at which its
// light in the brightest band falls below the noise's sigma, plus a pixel.
struct CellStar {
  double x = 0, y = 0;  // 0-based pixels of the cell (whole pixels)
  double flux = 0;      // in the first band
  double radius = 0;    // pixels
};

// One bad column: pixels (x, y0) .. (x, y1) of the cell, 0-based (with rotate, a row: (x0, y) .. (x1, y)).
struct CellDefect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive corners of a one-pixel-wide run
};

struct CellBandImage {
  std::vector<double> image;  // size^2 row-major (x fastest): galaxies + noise
  std::vector<double> noise;  // size^2: an independent noise field of the same sigma
};

struct SimCell {
  int index = 0;
  double g1 = 0, g2 = 0;            // the shear this cell was drawn with
  std::vector<CellObject> objects;
  std::vector<CellStar> stars;
  std::vector<CellDefect> defects;  // its bad columns, flagged in BMASK

  // Its BMASK plane (size x size, row-major): 1 on its defects' pixels, else 0.
  std::vector<double> bmask(int size) const;
  std::vector<CellBandImage> bands;
};

// Band-level constants (the same for every cell).
struct CellBand {
  double psf_fwhm = 0;       // pixels
  double flux_scale = 1;     // the band's flux over the first band's
  double bulge_scale = 1;    // bd: the band's bulge fraction over the first band's (before the cap at 1)
  double noise_sigma = 0;    // per pixel
  std::vector<double> psf;   // psf_size^2 pixel-integrated samples centred on the middle one (unit sum of the profile)
};

class CellSimulator {
 public:
  explicit CellSimulator(const CellSimOptions& options);  // validates (std::invalid_argument)
  ~CellSimulator();
  const CellSimOptions& options() const { return options_; }
  const std::vector<CellBand>& bands() const { return bands_; }
  // Per-thread scratch: the renderers' FFT plans and buffers, one galaxy's stamp.
  struct Workspace {
    SimWorkspace sim;
    std::vector<double> stamp;
  };
  std::unique_ptr<Workspace> make_workspace() const;
  // The galaxies of cell `cell` (positions, shapes, fluxes; snr left 0): what simulate draws.
  std::vector<CellObject> objects(int cell, double g1, double g2) const;
  // Its stars (positions, fluxes, mask radii): the same under any shear.
  std::vector<CellStar> stars(int cell) const;
  // Its bad columns: the same under any shear.
  std::vector<CellDefect> defects(int cell) const;
  // Cell `cell` under the shear (g1, g2) (the options' or its negative for a shear pair).
  // Thread-safe given a workspace per thread.
  SimCell simulate(int cell, double g1, double g2, Workspace& ws) const;
  SimCell simulate(int cell, Workspace& ws) const { return simulate(cell, options_.g1, options_.g2, ws); }

 private:
  CellSimOptions options_;
  std::vector<CellBand> bands_;
  std::vector<std::unique_ptr<SimRenderer>> renderers_;  // per band
};

// The radius (pixels) holding all but `epsilon` of a Sérsic component's light (n with 2n an
// integer: exponential, de Vaucouleurs), along the major axis of ellipticity |e|: the enclosed
// fraction is P(2n, b_n (r / r_e)^(1/n)), solved by bisection.
double cell_light_radius(double sersic_n, double hlr, double e, double epsilon);

}  // namespace stampede
