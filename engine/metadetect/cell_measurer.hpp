// Metadetection of one cell (Sheldon et al. 2020): its five metacal images (noshear, 1p, 1m, 2p,
// 2m; fixnoise), detection on each (Source Extractor's algorithm, ObjectDetector), and each
// detection measured on the image it was found on with weighted moments under a round Gaussian
// weight (wmom) or with pre-PSF Gaussian moments (pgauss: the same kind of weight applied before
// the reconvolution PSF), or fitted with a model convolved with it (exp, bd; one band). Several
// bands: each band's metacal images (one reconvolution PSF for all), detection on their sum
// weighted by each band's inverse noise variance, wmom over every band's stamp together, flux and
// S/N per band. Or, for comparison, per-object metacal at the positions detected on the noshear
// image (per_object_metacal). One per thread: it owns the FFT plans and every buffer, so a run of
// cells of one size allocates nothing (with --detector sep, but SEP's own work).
#pragma once
#include <array>
#include <complex>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/common/fftw_support.hpp"
#include "engine/fit/object_fitter.hpp"
#include "engine/fit/observation.hpp"
#include "engine/metacal/metacal_filters.hpp"
#include "engine/metacal/metacal_image_set.hpp"
#include "engine/metadetect/metadetect_options.hpp"
#include "engine/metadetect/metadetect_row.hpp"
#include "engine/metadetect/object_detector.hpp"
#include "engine/metadetect/star_disc.hpp"
#include "engine/model/psf_model.hpp"
#include "kernels/mask_fill.hpp"
#include "kernels/prepsf_moments.hpp"
#include "kernels/weighted_moments.hpp"

namespace stampede {

// One band of a cell: its image in the cell's pixel grid (box_size the cell's side, inverse-variance
// weights, 0 masking; psf_model in the cell's pixels) and a realisation of its noise.
struct MetadetectBand {
  Observation image;
  // A realisation of the pixels' noise (the input's NOISE plane), fixnoise's field; empty: a field
  // drawn from the weight with the cell's stream.
  std::span<const double> noise{};
};

struct MetadetectCell {
  long long index = 0;  // the cell's number in the run: keys its fixnoise field
  // Every band, the first first (1 to kMaxMetadetectBands), each of the cell's side.
  std::span<const MetadetectBand> bands{};
  double origin_x = 0, origin_y = 0;  // the input image's pixel of the cell's (0, 0)
  double pixel_scale = 0;             // arcsec per pixel
  // Detections kept: barycentre, carried back through the image's metacal shear to the unsheared
  // cell, in [keep_x0, keep_x1) x [keep_y0, keep_y1) (cell pixels); the rest belong to a
  // neighbouring cell or to the image's buffer.
  double keep_x0 = 0, keep_x1 = 0, keep_y0 = 0, keep_y1 = 0;
  // The scene's shear to undo as well when deciding that (MetadetectOptions::keep_unlensed): 0 none.
  double lens_g1 = 0, lens_g2 = 0;
  // Bright stars' discs reaching the cell (its pixels): masked, and no detection kept inside.
  std::span<const StarDisc> stars{};
  // The input's BMASK and ORMASK bits in the cell's pixels (its bands' OR'ed; empty: none), which
  // rows report at their detection's unsheared pixel.
  std::span<const std::int32_t> bmask{}, ormask{};
  // The input's masked fraction per pixel (an MFRAC plane or mfrac cutouts, its bands' mean; empty:
  // none): mfrac is then its Gaussian-weighted mean, a pixel of the cell's mask counting 1.
  std::span<const double> mfrac{};

  // The cell's side, pixels: its first band's box (0 without bands).
  int size() const { return bands.empty() ? 0 : bands.front().image.box_size; }
};

class CellMeasurer {
 public:
  explicit CellMeasurer(const MetadetectOptions& options, FftPlanning planning = FftPlanning::kEstimate);
  // Appends the cell's rows (noshear, 1p, 1m, 2p, 2m; detections in Source Extractor's order) to
  // `rows`; a cell that cannot be measured (its PSF gives no bounded metacal filters, SEP fails)
  // appends one row flagged kMetadetectCellFailed and returns false with *problem.
  bool measure(const MetadetectCell& cell, std::vector<MetadetectRow>* rows, std::string* problem);
  // The last cell's reconvolution PSF's T under the weight (pixels^2), for tests.
  double psf_t_pixels() const { return psf_t_; }

 private:
  // The reconvolution filters of the cell's PSFs: kept while they are the last cell's (a failure
  // too, with its reason); prepare_new_psf makes them.
  bool prepare_psf(double pixel_scale, std::string* problem);
  bool prepare_new_psf(double pixel_scale, std::string* problem);
  // A band of a cell with masked pixels: the cell's mask's pixels (and noise plane) filled from
  // the unmasked ones, with the unmasked mean weight (fill_masked; without, they are zeroed). The
  // spans then point at the copies made here.
  void prepare_masked(int side, std::span<const double>* pixels, std::span<const double>* weight,
                      std::span<const double>* noise);
  // Detections of image `type` (every band's) measured into rows; `variances` per band.
  void measure_image(const MetadetectCell& cell, int type, std::vector<MetadetectRow>* rows);
  // The masked share (the cell's mask, and beyond its edge) of a round Gaussian of
  // options.mfrac_fwhm about (x, y), cell pixels.
  double masked_share(const MetadetectCell& cell, double x, double y);
  // Detection d of image `type` carried back through the image's metacal shear (and, with_lens, the
  // scene's recorded shear) to the unsheared cell, cell pixels.
  std::array<double, 2> unsheared(const MetadetectCell& cell, int type, const Detection& d, bool with_lens) const;
  // A row's unsheared position (cell pixels x, y) in the input's pixels, and its mask bits there.
  static void set_unsheared_position(const MetadetectCell& cell, double x, double y, MetadetectRow* r);
  // Whether the cell keeps detection d of image `type` (its unsheared position in the keep region).
  bool owns(const MetadetectCell& cell, int type, const Detection& d) const;
  // The weighted moments of a box x box stamp whose pixel (0, 0) is the cell's (x0, y0) into *r.
  void fill_moments(const MetadetectCell& cell, std::span<const double> stamp, int box, int x0, int y0,
                    double variance, const Detection& d, MetadetectRow* r);
  // Several bands: the moments of the bands' stamps together (stamps_), each band's flux and S/N.
  void fill_band_moments(const MetadetectCell& cell, int box, int x0, int y0, const Detection& d, MetadetectRow* r);
  // pgauss: the pre-PSF moments of `stamp` (of noise variance `variance`; made with band `band`'s
  // Gamma) about the wmom centroid `centre` (the detection where that failed).
  kernels::PrepsfMoments prepsf(std::span<const double> stamp, int box, const kernels::WeightedMoments& centre,
                                int x0, int y0, double variance, const Detection& d, std::size_t band);
  // exp, bd: the model fit of `stamp` with Gamma (weights 1 / variance) into *r.
  void fill_fit(const MetadetectCell& cell, std::span<const double> stamp, int box, int x0, int y0, double variance,
                const Detection& d, MetadetectRow* r);
  // The weight's Newton steps toward the centroid: 0 where it stays at the detection.
  int centroid_iterations() const { return options_.recentre ? 6 : 0; }
  // Band `band`'s reconvolution PSF x pixel's transform on a box x box stamp's DFT grid, made once
  // per box side and PSF (the shape bands' Gamma or the other bands').
  std::span<const double> psf_transform(int box, std::size_t band);
  // options.per_object_metacal: each noshear detection's metacal stamps, five rows each.
  void per_object_rows(const MetadetectCell& cell, std::vector<MetadetectRow>* rows);

  MetadetectOptions options_;
  FftPlanning planning_;
  std::unique_ptr<MetacalImageSet> images_set_;
  bool cell_masked_ = false;  // some band's weight is not positive somewhere in the cell
  // Where it is: the cell's mask (every band's masked pixels and, with symmetrise_mask, their
  // quarter turns), which the fill and the rows' masked flags and fractions follow.
  std::vector<std::uint8_t> mask_, mask_turned_;
  // The bands of the cell being measured, their PSFs' filters (one Gamma for the shape bands, one
  // for the others) and images.
  std::span<const MetadetectBand> bands_;
  // The cell's band roles (options' detect_bands, shear_bands; 0 there: every band) and the first
  // shape band, whose Gamma is the shapes'.
  std::uint32_t detect_mask_ = 0, shear_mask_ = 0;
  std::size_t shape_band_ = 0;
  std::vector<std::shared_ptr<const MetacalFilters>> filters_;
  std::vector<PsfModel> psfs_;
  bool have_psf_ = false;
  std::string psf_problem_;  // why the PSFs prepared last serve no reconvolution ("" when they do)
  double psf_scale_ = 0, psf_t_ = 0, weight_fwhm_px_ = 0;
  // The reconvolved PSF's e and the original PSFs' e and T (pixels^2) under the weight.
  double psf_rec_e1_ = NAN, psf_rec_e2_ = NAN, psf_orig_e1_ = NAN, psf_orig_e2_ = NAN, psf_orig_t_ = NAN;
  std::vector<float> image_f_;
  ObjectDetector detector_;
  std::vector<std::vector<double>> images_;  // per band: kNumMetacalTypes x size^2
  std::vector<double> variances_;            // per band: its images' noise variance per pixel
  std::vector<double> stamp_, scratch_, detection_image_;
  std::vector<std::vector<double>> band_stamps_;
  std::vector<kernels::MomentsStamp> stamps_;
  std::unique_ptr<MetacalImageSet> stamp_set_;  // per_object_metacal
  std::shared_ptr<const MetacalFilters> stamp_filters_;
  std::vector<double> stamp_images_, stamp_pixels_, stamp_weight_, stamp_noise_;
  std::vector<Detection> detections_;
  std::vector<double> share_x_, share_y_;  // masked_share's Gaussian, per column and per row
  // prepare_masked's copies.
  std::vector<double> masked_pixels_, masked_weight_, masked_noise_;
  std::vector<std::span<double>> fill_planes_;
  kernels::MaskFillScratch fill_scratch_;
  // pgauss: psf_k_[role][box / 2] the transform for that box side (empty until needed; role 0 the
  // shape bands' Gamma, 1 the other bands'), the kernel's scratch, the bands' stamps combined.
  std::array<std::vector<std::vector<double>>, 2> psf_k_;
  std::vector<std::complex<double>> prepsf_scratch_;
  std::vector<double> combined_;
  // exp, bd: the fitter (its renderers per box side), Gamma prepared per box side (fit_psfs_[box / 2],
  // null until needed), the stamp's weights.
  std::unique_ptr<ObjectFitter> fitter_;
  std::vector<std::shared_ptr<const PreparedPsf>> fit_psfs_;
  std::vector<double> fit_weight_;
  std::vector<std::array<double, 2>> fit_neighbours_;  // detections near the stamp, cell pixels
};

}  // namespace stampede
