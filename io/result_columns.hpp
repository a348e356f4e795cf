// The result column schema: every column of the RESULTS table that `stampede fit` writes (name,
// FITS type, unit, description, and how it maps to an ObjectRecord), the one list from which the
// writer (catalog_writer) writes and the reader (catalog_reader) reads, so the two and the tools
// that consume fit tables cannot disagree about a column's name or type.
//
// A table has the position columns of its input (grid or catalogue) followed by the fit columns:
//   positions   grid: id (K), ix, iy (J), the stamp's grid indices;
//               catalogue: id (K), x_image, y_image (D), FITS 1-based image pixels
//   x0 y0       fitted centroid in 0-based pixel coordinates *of the stamp* (pixel centres at
//               integers), as fitted; the stamp's origin is the caller's (grid: ix, iy times the
//               stamp size; catalogue: the cutout around x_image, y_image)
//   e1 e2 radius bulge_A disc_A   effective fitted values (FitResult::params)
//   bulge_flux disc_flux flux e1_err e2_err snr chi2 likelihood   (D)
//   n_iter n_eval stop_reason status (J)   stop_reason: StopReason value; status: FitStatus value
//   flags (1V: unsigned 32-bit, stored as J with TZERO = 2^31)
//   time_us psf_e1 psf_e2 psf_fwhm (D)
//   metacal runs: R11 R12 R21 R22, e1_T e2_T snr_T radius_T for T = 1p 1m 2p 2m (D); the fit
//               columns above are then the noshear image's
//   survey (MEDS) input: positions id number (K) ra dec (D, degrees); the fit columns in sky
//               units (x0 y0 the (u, v) offset and radius in arcsec, e in (u, v), fluxes at
//               magzp_ref), psf_fwhm replaced by psf_size, then n_epochs (J) masked_frac (D)
//               is_bulge (J) other_likelihood (D); a metacal run's adds the metacal columns (radius_T
//               in arcsec, e_T in (u, v)) and gamma_fwhm (D, arcsec: the object's reconvolution PSF)
// NaN means "not computed" in every D column, as in FitResult.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/pipeline/object_record.hpp"

namespace stampede::io {

enum class PositionColumns {
  kGrid,       // id ix iy
  kCatalogue,  // id x_image y_image
  kSurvey,     // id number ra dec (MEDS objects; the fit in sky units)
};
const char* position_name(PositionColumns positions);  // "grid", "catalogue", "survey"

// Every column a result table can have, grid and catalogue positions together; one value per
// column, so consumers name columns by value rather than by a re-typed string.
enum class ResultField : int {
  kId, kIx, kIy, kXImage, kYImage,
  kX0, kY0, kE1, kE2, kRadius, kBulgeA, kDiscA,
  kBulgeFlux, kDiscFlux, kFlux, kE1Err, kE2Err, kSnr, kChi2, kLikelihood,
  kIterations, kEvaluations, kStopReason, kStatus, kFlags,
  kTimeUs, kPsfE1, kPsfE2, kPsfFwhm,
  // metacal tables only (result_columns(positions, true)): the response, then per sheared image
  // 1p 1m 2p 2m its fit's e1 e2 snr radius
  kR11, kR12, kR21, kR22,
  kE1_1p, kE2_1p, kSnr_1p, kRadius_1p, kE1_1m, kE2_1m, kSnr_1m, kRadius_1m,
  kE1_2p, kE2_2p, kSnr_2p, kRadius_2p, kE1_2m, kE2_2m, kSnr_2m, kRadius_2m,
  // survey tables only (PositionColumns::kSurvey)
  kNumber, kRa, kDec, kPsfSize, kNEpochs, kMaskedFraction, kIsBulge, kOtherLikelihood,
  // survey metacal tables only
  kGammaFwhm,
  // multi-band survey tables only, once per band (ResultSchema): names end in _<band>; the entries
  // of result_column() are band 0's
  kBandNEpochs, kBandFlux, kBandBulgeFlux, kBandDiscFlux, kBandSnr,
};
inline constexpr int kNumResultFields = static_cast<int>(ResultField::kBandSnr) + 1;
inline constexpr int kNumBandFields = static_cast<int>(ResultField::kBandSnr) - static_cast<int>(ResultField::kBandNEpochs) + 1;
inline constexpr int kNumMetacalFields = static_cast<int>(ResultField::kRadius_2m) - static_cast<int>(ResultField::kR11) + 1;

// On-disk type: FITS TFORM 1K, 1J, 1V (unsigned, stored as J with TZERO = 2^31) and 1D.
enum class ColumnType { kInt64, kInt32, kUInt32, kFloat64 };

// One column of the table and of the text catalogue. Integer columns go through `integer` /
// `set_integer` (widened to 64 bits; every record field fits its FITS type exactly), kFloat64
// columns through `real` / `set_real`; the other pair is null.
struct ResultColumn {
  ResultField field;
  const char* name;         // TTYPEn
  ColumnType type;
  const char* unit;         // TUNITn; "" = dimensionless or data units
  const char* description;  // TCOMMn, at most 68 characters (one FITS string card)
  std::int64_t (*integer)(const ObjectRecord&);
  double (*real)(const ObjectRecord&);
  void (*set_integer)(ObjectRecord&, std::int64_t);
  void (*set_real)(ObjectRecord&, double);
};

// The columns of a table with these positions, in table order; a metacal run's table adds the
// metacal columns (R11 R12 R21 R22, then e1_1p e2_1p snr_1p radius_1p ... radius_2m) at the end.
// A survey metacal table ends with gamma_fwhm after them.
std::span<const ResultColumn> result_columns(PositionColumns positions, bool metacal = false);
// The column of `field`. Grid and catalogue tables share every column they both have; only the
// description of `id` differs (result_columns() has each table's).
const ResultColumn& result_column(ResultField field);
// Its TTYPE, e.g. "psf_e1".
const char* column_name(ResultField field);

// Column names in table order, for documentation and tests.
std::vector<std::string> catalog_columns(PositionColumns positions, bool metacal = false);

// The header key of a multi-band table that lists its bands, comma-separated (CatalogWriter).
inline constexpr const char* kBandsKey = "BANDS";

// A band's name as a column suffix: 1..16 of [A-Za-z0-9_]. False with *why naming the rule.
bool is_band_name(const std::string& band, std::string* why);

// The bands of one table: each is_band_name, none repeated, and no two that differ only in case
// (FITS column lookup ignores case: flux_G and flux_g would be one column to every reader and
// merge). False with *why naming the name or the two names.
bool are_band_names(const std::vector<std::string>& bands, std::string* why);

// A table's columns with those of its bands: result_columns(positions, metacal), then for each band
// b (multi-band survey tables) n_epochs_<b> flux_<b> bulge_flux_<b> disc_flux_<b> snr_<b>, read from
// and written to record.survey.bands[k] for the k-th band. Owns the band columns' names, so it
// is neither copied nor moved.
class ResultSchema {
 public:
  // Throws std::invalid_argument for more than kMaxBands bands or names are_band_names refuses,
  // naming them.
  ResultSchema(PositionColumns positions, bool metacal, const std::vector<std::string>& bands = {});
  ResultSchema(const ResultSchema&) = delete;
  ResultSchema& operator=(const ResultSchema&) = delete;
  std::span<const ResultColumn> columns() const { return columns_; }
  const std::vector<std::string>& bands() const { return bands_; }

 private:
  std::vector<std::string> bands_;
  std::vector<std::unique_ptr<std::string>> text_;  // band columns' names and descriptions
  std::vector<ResultColumn> columns_;
};

}  // namespace stampede::io
