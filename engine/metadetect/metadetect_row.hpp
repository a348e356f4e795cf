// One row of a metadetection catalogue: a detection on one of a cell's five metacal images, measured
// on that image. Objects are never matched between images (each image's catalogue stands alone).
#pragma once
#include <array>
#include <cmath>
#include <cstdint>

namespace stampede {

// The bands a metadetection row carries flux and S/N for.
inline constexpr int kMaxMetadetectBands = 8;

enum MetadetectFlag : std::uint32_t {
  // The measurement failed: moments not valid (no positive flux or T, |e| >= 1), a fit not converged.
  kMetadetectMomentsFailed = 1u << 0,
  kMetadetectEdge = 1u << 1,           // the detection's stamp reaches beyond the cell
  kMetadetectMasked = 1u << 2,         // the detection's pixel is masked (the cell's mask)
  kMetadetectCellFailed = 1u << 3,     // nothing could be detected in the cell: a row with id -1 says why
};

struct MetadetectRow {
  std::int64_t cell = 0;
  std::int32_t shear_type = 0;  // MetacalType
  std::int32_t id = -1;         // the detection's number in its cell and image; -1: the cell failed
  double x = NAN, y = NAN;      // 0-based pixels of the input image (the weighted centroid; exp, bd: the fit's)
  // The detection carried back through its image's metacal shear (about the cell's centre) to the
  // unsheared image: 0-based pixels of the input image (the reference package's sx_col/row_noshear).
  double x_noshear = NAN, y_noshear = NAN;
  double u = NAN, v = NAN;      // arcsec from the input image's pixel (0, 0) along x and y
  double e1 = NAN, e2 = NAN, e1_err = NAN, e2_err = NAN;
  double t = NAN;               // T = Mxx + Myy, arcsec^2: weighted (pgauss: pre-PSF), or the model's (gauss, exp, bd)
  double t_ratio = NAN;         // T over psf_t
  double psf_t = NAN;           // Gamma x pixel's T under the weight (wmom's for the fits), arcsec^2
  // For PSF-leakage tests: the cell's original PSF's e and T under the same weight (the shape
  // bands' averaged; T in arcsec^2), and the reconvolved PSF's e (round: 0 to rounding).
  double psf_orig_e1 = NAN, psf_orig_e2 = NAN, psf_orig_t = NAN;
  double psf_rec_e1 = NAN, psf_rec_e2 = NAN;
  double flux = NAN, snr = NAN;  // several bands: the bands' stamps measured together
  // Per band (several bands; the first band's for one): its stamp's weighted flux and S/N about its
  // own centroid under the same weight.
  std::array<double, kMaxMetadetectBands> band_flux{NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN};
  std::array<double, kMaxMetadetectBands> band_snr{NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN};
  double mfrac = 0;             // masked share of a Gaussian about the detection (MetadetectOptions::mfrac_fwhm)
  // The input's BMASK and ORMASK bits at the detection's unsheared pixel, its bands' OR'ed (0 where
  // the input has none).
  std::int32_t bmask = 0, ormask = 0;
  std::int32_t box_size = 0;
  std::int32_t isophotal_area = 0;
  std::int32_t sep_flags = 0;
  std::uint32_t flags = 0;      // MetadetectFlag
};

}  // namespace stampede
