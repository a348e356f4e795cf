// What a metadetection run chooses (`stampede metadetect`; docs/metadetect.md). The defaults are
// the reference package's settings as DES runs it (../shared/reference/metadetection.md).
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

#include "engine/metacal/metacal_options.hpp"

namespace stampede {

// How each detection is measured (docs/metadetect.md, "Measurements").
enum class MetadetectMeasurement {
  kWmom,    // weighted moments of the metacal image under a round Gaussian weight
  kPgauss,  // pre-PSF Gaussian moments: the same weight applied before the reconvolution PSF
  kExp,     // a fit of an exponential disc convolved with the reconvolution PSF (engine/fit)
  kBd,      // a fit of a bulge + disc, as `stampede fit --metacal` with metacal_model = bd
  kGauss,   // a fit of a Gaussian (a Sersic n = 0.5), the reference package's maximum-likelihood "gauss"
};
// "wmom", "pgauss", "exp", "bd", "gauss"; the table's MEASURE key.
const char* metadetect_measurement_name(MetadetectMeasurement m);
// Case-insensitive inverse of metadetect_measurement_name; false for anything else.
bool parse_metadetect_measurement(std::string_view name, MetadetectMeasurement* out);
// gauss, exp or bd: a model fitted to one band's stamp, with no weight function.
inline bool is_model_fit(MetadetectMeasurement m) {
  return m == MetadetectMeasurement::kExp || m == MetadetectMeasurement::kBd || m == MetadetectMeasurement::kGauss;
}

// Which implementation detects (docs/metadetect.md, "Detection"): ours, from a component tree,
// or SEP's library. Both are Source Extractor's algorithm.
enum class DetectorKind { kTree, kSep };
// "tree", "sep"; the table's DETECTOR key.
const char* detector_kind_name(DetectorKind d);
// Case-insensitive inverse of detector_kind_name; false for anything else.
bool parse_detector_kind(std::string_view name, DetectorKind* out);

// Source Extractor's extraction ("sxdes" settings): a threshold in units of the image's noise
// sigma, on the image convolved with a normalised Gaussian filter.
struct DetectionOptions {
  DetectorKind detector = DetectorKind::kTree;
  double threshold = 0.8;       // sigma
  int min_area = 4;             // pixels above the threshold
  double deblend_contrast = 1e-5;
  int deblend_thresholds = 32;
  double filter_fwhm = 3.0;     // pixels; 0: no filter
  int filter_size = 7;          // odd side of the filter kernel
  bool clean = true;
  double clean_param = 1.0;
};

// The stamp cut around each detection: `size` x `size` about the detection's pixel (the reference
// package's shear test: 32), or, with size 0, "iso_radius" sizing: radius = max(radius_min,
// radius_factor x sqrt(isophotal area / pi)) + padding, side 2 radius + 1 between box_min and
// box_max. A fixed size selects nothing by the isophote, which at high S/N changes between the
// sheared images (docs/metadetect.md, "Stamps and the weight's centre").
struct DetectionStampOptions {
  int size = 32;
  double radius_factor = 2.0;
  double radius_min = 4.0;
  double padding = 2.0;
  int box_min = 33;
  int box_max = 255;
};

struct MetadetectOptions {
  int cell_size = 251;    // pixels: an image larger than a cell is cut into cells of this side
  int cell_buffer = 34;   // pixels at each cell edge whose detections another cell (or none) keeps
  // The fewest pixels a cell's interior (cell_size - 2 cell_buffer) may have: its detections alone
  // are kept, so a thinner one keeps next to nothing.
  static constexpr int kMinCellInterior = 16;
  double step = 0.01;     // metacal shear
  double psf_dilation = 0.0;  // reconvolution PSF FWHM over the PSF's (0: the rule's own)
  ReconvolutionRule reconvolution = ReconvolutionRule::kAuto;  // Gamma's rule (engine/metacal/reconvolution_psf)
  // wmom and pgauss: the weight's centre moved to the weighted centroid by six Newton steps; false:
  // held at the detection's position, as the reference package measures (docs/metadetect.md).
  bool recentre = false;
  // Simulations only: keep a detection by its position with the scene's recorded shear undone as
  // well as metacal's (the cells' G1, G2): a lone simulated cell then keeps the same objects under
  // +g and -g, as a tiled survey's cells hand each other the objects the shear moves across their
  // boundaries (docs/metadetect.md, "The random test's m").
  bool keep_unlensed = false;
  bool fixnoise = true;
  // Masked pixels (weight 0): the mask made symmetric under quarter turns about the cell's centre
  // (its shape then has no quadrupole for the shear to act on), and the masked pixels filled from
  // the unmasked ones around them before the metacal images are made (no hole to deconvolve), as
  // the reference package does (docs/survey_metadetect.md). Off: the masked pixels are zeroed.
  bool symmetrise_mask = true;
  bool fill_masked = true;
  // arcsec: each detection's mfrac is the masked share (the cell's mask; beyond the cell's edge
  // too) of a round Gaussian of this FWHM about it, as the reference package measures it (DES Y6
  // cuts mfrac < 0.1).
  double mfrac_fwhm = 2.0;
  // The cells' metacal images made in double precision; false: in single precision (half the time;
  // the images within ~2e-7 of their peak of the double ones: docs/metadetect.md, "Single-precision
  // images").
  bool double_images = false;
  // Fixnoise's field from the input's noise realisation (an image file's NOISE HDU, a tile's
  // noise cutouts) where it has one, as the reference package does; false, or no such plane: a
  // field drawn from the weight, keyed by the cell's number (and band).
  bool noise_plane = true;
  std::uint64_t seed = 20170101;  // keys each cell's fixnoise field with the cell's index
  // Band roles, bit b for band b in the run's order (0: every band): the bands whose metacal images
  // are summed for detection, and the bands whose moments give the row's shape (e, T, flux, S/N).
  // Every band's flux and S/N are measured whatever its role (DES Y6 detects and measures shapes
  // on r, i, z). The shape bands share one reconvolution PSF, the widest they need; other bands
  // have the widest every band needs.
  std::uint32_t detect_bands = 0;
  std::uint32_t shear_bands = 0;
  MetadetectMeasurement measurement = MetadetectMeasurement::kWmom;
  // arcsec: the measurement's round Gaussian weight; 0: its default (weight_fwhm_arcsec()).
  double weight_fwhm = 0;
  // Not metadetection: per-object metacal at the positions detected on the noshear image (each
  // detection's own 49 px stamp cut from the cell, its five metacal images, wmom), the estimator
  // metadetection replaces, kept to measure the bias it leaves in blends (docs/metadetect.md).
  bool per_object_metacal = false;
  DetectionOptions detection;
  DetectionStampOptions stamp;
  int inner_size() const { return cell_size - 2 * cell_buffer; }
  // weight_fwhm, or the measurement's default where it is 0: the reference package's 1.2" for
  // wmom, DES Y6's 2.0" for pgauss (a wider pre-PSF weight: the deconvolution's noise at high k is
  // what the weight's transform cuts).
  double weight_fwhm_arcsec() const;
  // Message names the field as Python's keyword does ("cell_size = 3: must be ..."), its value and
  // the rule; front ends translate fields to their own spelling (app/metadetect_option_keys).
  bool IsValid(std::string* why) const;
};

}  // namespace stampede
