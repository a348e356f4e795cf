// The result column table; see result_columns.hpp.
#include "io/result_columns.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <stdexcept>
#include <string_view>
#include <utility>

namespace stampede::io {
namespace {

using R = const ObjectRecord&;
using W = ObjectRecord&;

constexpr ResultColumn real(ResultField field, const char* name, const char* unit,
                            const char* description, double (*get)(R), void (*set)(W, double)) {
  return {field, name, ColumnType::kFloat64, unit, description, nullptr, get, nullptr, set};
}
constexpr ResultColumn integer(ResultField field, const char* name, ColumnType type,
                               const char* description, std::int64_t (*get)(R),
                               void (*set)(W, std::int64_t)) {
  return {field, name, type, "", description, get, nullptr, set, nullptr};
}

// A fitted parameter's column: FitResult::params[p].
template <Param p>
constexpr ResultColumn param(ResultField field, const char* name, const char* unit,
                             const char* description) {
  return real(
      field, name, unit, description, [](R r) { return r.fit.params[index(p)]; },
      [](W r, double v) { r.fit.params[index(p)] = v; });
}

using F = ResultField;
using T = ColumnType;

// Band B's columns (survey.bands[B]), named by pattern; ResultSchema names them per band.
template <int B>
constexpr std::array<ResultColumn, kNumBandFields> band_columns() {
  return {integer(F::kBandNEpochs, "n_epochs_BAND", T::kInt32, "cutouts fitted",
                  [](R r) -> std::int64_t { return r.survey.bands[B].n_epochs; },
                  [](W r, std::int64_t v) { r.survey.bands[B].n_epochs = static_cast<int>(v); }),
          real(F::kBandFlux, "flux_BAND", "", "total flux at the zero point magzp_ref",
               [](R r) { return r.survey.bands[B].flux; }, [](W r, double v) { r.survey.bands[B].flux = v; }),
          real(F::kBandBulgeFlux, "bulge_flux_BAND", "", "bulge flux at the zero point magzp_ref",
               [](R r) { return r.survey.bands[B].bulge_flux; }, [](W r, double v) { r.survey.bands[B].bulge_flux = v; }),
          real(F::kBandDiscFlux, "disc_flux_BAND", "", "disc flux at the zero point magzp_ref",
               [](R r) { return r.survey.bands[B].disc_flux; }, [](W r, double v) { r.survey.bands[B].disc_flux = v; }),
          real(F::kBandSnr, "snr_BAND", "", "S/N sqrt(sum w m^2) over its cutouts",
               [](R r) { return r.survey.bands[B].snr; }, [](W r, double v) { r.survey.bands[B].snr = v; })};
}

template <std::size_t... B>
constexpr std::array<std::array<ResultColumn, kNumBandFields>, sizeof...(B)> all_band_columns(std::index_sequence<B...>) {
  return {band_columns<static_cast<int>(B)>()...};
}
constexpr auto kBandColumns = all_band_columns(std::make_index_sequence<kMaxBands>{});

// Indexed by ResultField (checked below).
constexpr ResultColumn kColumns[] = {
    // The grid and the catalogue describe id differently; the grid's text is the one kept here,
    // the catalogue table overrides it.
    integer(F::kId, "id", T::kInt64, "object id: iy * nx + ix",
            [](R r) -> std::int64_t { return r.id; }, [](W r, std::int64_t v) { r.id = v; }),
    integer(F::kIx, "ix", T::kInt32, "stamp column in the grid, 0-based",
            [](R r) -> std::int64_t { return r.ix; },
            [](W r, std::int64_t v) { r.ix = static_cast<std::int32_t>(v); }),
    integer(F::kIy, "iy", T::kInt32, "stamp row in the grid, 0-based",
            [](R r) -> std::int64_t { return r.iy; },
            [](W r, std::int64_t v) { r.iy = static_cast<std::int32_t>(v); }),
    real(F::kXImage, "x_image", "pixel", "catalogue x position, FITS 1-based image pixels",
         [](R r) { return r.x_image; }, [](W r, double v) { r.x_image = v; }),
    real(F::kYImage, "y_image", "pixel", "catalogue y position, FITS 1-based image pixels",
         [](R r) { return r.y_image; }, [](W r, double v) { r.y_image = v; }),
    param<Param::kX0>(F::kX0, "x0", "pixel", "fitted centroid x, 0-based pixels within the stamp"),
    param<Param::kY0>(F::kY0, "y0", "pixel", "fitted centroid y, 0-based pixels within the stamp"),
    param<Param::kE1>(F::kE1, "e1", "", "ellipticity (a-b)/(a+b) along x, after the mirror"),
    param<Param::kE2>(F::kE2, "e2", "", "ellipticity along y = x, after the mirror"),
    param<Param::kRadius>(F::kRadius, "radius", "pixel",
                          "disc half-light radius sqrt(ab), after softening"),
    param<Param::kBulgeA>(F::kBulgeA, "bulge_A", "",
                          "bulge central intensity, data units per pixel^2"),
    param<Param::kDiscA>(F::kDiscA, "disc_A", "", "disc central intensity, data units per pixel^2"),
    real(F::kBulgeFlux, "bulge_flux", "", "bulge flux, data units",
         [](R r) { return r.fit.bulge_flux; }, [](W r, double v) { r.fit.bulge_flux = v; }),
    real(F::kDiscFlux, "disc_flux", "", "disc flux, data units",
         [](R r) { return r.fit.disc_flux; }, [](W r, double v) { r.fit.disc_flux = v; }),
    real(F::kFlux, "flux", "", "total flux, data units", [](R r) { return r.fit.flux; },
         [](W r, double v) { r.fit.flux = v; }),
    real(F::kE1Err, "e1_err", "", "error of e1 from (J^T W J)^-1",
         [](R r) { return r.fit.e1_err; }, [](W r, double v) { r.fit.e1_err = v; }),
    real(F::kE2Err, "e2_err", "", "error of e2 from (J^T W J)^-1",
         [](R r) { return r.fit.e2_err; }, [](W r, double v) { r.fit.e2_err = v; }),
    real(F::kSnr, "snr", "", "S/N sqrt(sum w m^2) of the best model",
         [](R r) { return r.fit.snr; }, [](W r, double v) { r.fit.snr = v; }),
    real(F::kChi2, "chi2", "", "sum w (d - m)^2 over used pixels", [](R r) { return r.fit.chi2; },
         [](W r, double v) { r.fit.chi2 = v; }),
    real(F::kLikelihood, "likelihood", "", "-chi2 / 2", [](R r) { return r.fit.likelihood; },
         [](W r, double v) { r.fit.likelihood = v; }),
    integer(F::kIterations, "n_iter", T::kInt32, "solver iterations (Jacobian evaluations)",
            [](R r) -> std::int64_t { return r.fit.iterations; },
            [](W r, std::int64_t v) { r.fit.iterations = static_cast<int>(v); }),
    integer(F::kEvaluations, "n_eval", T::kInt32, "model evaluations",
            [](R r) -> std::int64_t { return r.fit.evaluations; },
            [](W r, std::int64_t v) { r.fit.evaluations = static_cast<int>(v); }),
    integer(F::kStopReason, "stop_reason", T::kInt32, "StopReason: the rule that stopped the solver",
            [](R r) -> std::int64_t { return static_cast<int>(r.fit.stop_reason); },
            [](W r, std::int64_t v) { r.fit.stop_reason = static_cast<StopReason>(v); }),
    integer(F::kStatus, "status", T::kInt32, "FitStatus, named by header keys STATUSn",
            [](R r) -> std::int64_t { return static_cast<int>(r.fit.status); },
            [](W r, std::int64_t v) { r.fit.status = static_cast<FitStatus>(v); }),
    integer(F::kFlags, "flags", T::kUInt32, "fit and input flag bits, see COMMENT cards",
            [](R r) -> std::int64_t { return r.flags; },
            [](W r, std::int64_t v) { r.flags = static_cast<std::uint32_t>(v); }),
    real(F::kTimeUs, "time_us", "us", "wall time of the fit", [](R r) { return r.time_us; },
         [](W r, double v) { r.time_us = v; }),
    real(F::kPsfE1, "psf_e1", "", "PSF ellipticity e1", [](R r) { return r.psf_e1; },
         [](W r, double v) { r.psf_e1 = v; }),
    real(F::kPsfE2, "psf_e2", "", "PSF ellipticity e2", [](R r) { return r.psf_e2; },
         [](W r, double v) { r.psf_e2 = v; }),
    real(F::kPsfFwhm, "psf_fwhm", "pixel", "PSF FWHM", [](R r) { return r.psf_fwhm; },
         [](W r, double v) { r.psf_fwhm = v; }),
    real(F::kR11, "R11", "", "metacal response de1/dg1", [](R r) { return r.metacal.r11; }, [](W r, double v) { r.metacal.r11 = v; }),
    real(F::kR12, "R12", "", "metacal response de1/dg2", [](R r) { return r.metacal.r12; }, [](W r, double v) { r.metacal.r12 = v; }),
    real(F::kR21, "R21", "", "metacal response de2/dg1", [](R r) { return r.metacal.r21; }, [](W r, double v) { r.metacal.r21 = v; }),
    real(F::kR22, "R22", "", "metacal response de2/dg2", [](R r) { return r.metacal.r22; }, [](W r, double v) { r.metacal.r22 = v; }),
    real(F::kE1_1p, "e1_1p", "", "metacal 1p image: fitted e1", [](R r) { return r.metacal.e1[0]; },
         [](W r, double v) { r.metacal.e1[0] = v; }),
    real(F::kE2_1p, "e2_1p", "", "metacal 1p image: fitted e2", [](R r) { return r.metacal.e2[0]; },
         [](W r, double v) { r.metacal.e2[0] = v; }),
    real(F::kSnr_1p, "snr_1p", "", "metacal 1p image: fit S/N", [](R r) { return r.metacal.snr[0]; },
         [](W r, double v) { r.metacal.snr[0] = v; }),
    real(F::kRadius_1p, "radius_1p", "pixel", "metacal 1p image: fitted radius", [](R r) { return r.metacal.radius[0]; },
         [](W r, double v) { r.metacal.radius[0] = v; }),
    real(F::kE1_1m, "e1_1m", "", "metacal 1m image: fitted e1", [](R r) { return r.metacal.e1[1]; },
         [](W r, double v) { r.metacal.e1[1] = v; }),
    real(F::kE2_1m, "e2_1m", "", "metacal 1m image: fitted e2", [](R r) { return r.metacal.e2[1]; },
         [](W r, double v) { r.metacal.e2[1] = v; }),
    real(F::kSnr_1m, "snr_1m", "", "metacal 1m image: fit S/N", [](R r) { return r.metacal.snr[1]; },
         [](W r, double v) { r.metacal.snr[1] = v; }),
    real(F::kRadius_1m, "radius_1m", "pixel", "metacal 1m image: fitted radius", [](R r) { return r.metacal.radius[1]; },
         [](W r, double v) { r.metacal.radius[1] = v; }),
    real(F::kE1_2p, "e1_2p", "", "metacal 2p image: fitted e1", [](R r) { return r.metacal.e1[2]; },
         [](W r, double v) { r.metacal.e1[2] = v; }),
    real(F::kE2_2p, "e2_2p", "", "metacal 2p image: fitted e2", [](R r) { return r.metacal.e2[2]; },
         [](W r, double v) { r.metacal.e2[2] = v; }),
    real(F::kSnr_2p, "snr_2p", "", "metacal 2p image: fit S/N", [](R r) { return r.metacal.snr[2]; },
         [](W r, double v) { r.metacal.snr[2] = v; }),
    real(F::kRadius_2p, "radius_2p", "pixel", "metacal 2p image: fitted radius", [](R r) { return r.metacal.radius[2]; },
         [](W r, double v) { r.metacal.radius[2] = v; }),
    real(F::kE1_2m, "e1_2m", "", "metacal 2m image: fitted e1", [](R r) { return r.metacal.e1[3]; },
         [](W r, double v) { r.metacal.e1[3] = v; }),
    real(F::kE2_2m, "e2_2m", "", "metacal 2m image: fitted e2", [](R r) { return r.metacal.e2[3]; },
         [](W r, double v) { r.metacal.e2[3] = v; }),
    real(F::kSnr_2m, "snr_2m", "", "metacal 2m image: fit S/N", [](R r) { return r.metacal.snr[3]; },
         [](W r, double v) { r.metacal.snr[3] = v; }),
    real(F::kRadius_2m, "radius_2m", "pixel", "metacal 2m image: fitted radius", [](R r) { return r.metacal.radius[3]; },
         [](W r, double v) { r.metacal.radius[3] = v; }),
    integer(F::kNumber, "number", T::kInt64, "the object's label in the seg map",
            [](R r) -> std::int64_t { return r.survey.number; }, [](W r, std::int64_t v) { r.survey.number = v; }),
    real(F::kRa, "ra", "deg", "right ascension", [](R r) { return r.survey.ra; }, [](W r, double v) { r.survey.ra = v; }),
    real(F::kDec, "dec", "deg", "declination", [](R r) { return r.survey.dec; }, [](W r, double v) { r.survey.dec = v; }),
    real(F::kPsfSize, "psf_size", "pixel", "mean PSF sqrt((Ixx + Iyy) / 2) over the fitted cutouts",
         [](R r) { return r.survey.psf_size; }, [](W r, double v) { r.survey.psf_size = v; }),
    integer(F::kNEpochs, "n_epochs", T::kInt32, "cutouts fitted",
            [](R r) -> std::int64_t { return r.survey.n_epochs; },
            [](W r, std::int64_t v) { r.survey.n_epochs = static_cast<std::int32_t>(v); }),
    real(F::kMaskedFraction, "masked_frac", "", "masked fraction of the usable cutouts' pixels",
         [](R r) { return r.survey.masked_fraction; }, [](W r, double v) { r.survey.masked_fraction = v; }),
    integer(F::kIsBulge, "is_bulge", T::kInt32, "bord: 1 the pure bulge won, 0 the disc; bd: -1",
            [](R r) -> std::int64_t { return r.survey.is_bulge; },
            [](W r, std::int64_t v) { r.survey.is_bulge = static_cast<std::int32_t>(v); }),
    real(F::kOtherLikelihood, "other_likelihood", "", "bord: the losing model's log-likelihood; bd: NaN",
         [](R r) { return r.survey.other_likelihood; }, [](W r, double v) { r.survey.other_likelihood = v; }),
    real(F::kGammaFwhm, "gamma_fwhm", "arcsec", "metacal reconvolution PSF FWHM, round on the sky",
         [](R r) { return r.survey.gamma_fwhm; }, [](W r, double v) { r.survey.gamma_fwhm = v; }),
    band_columns<0>()[0], band_columns<0>()[1], band_columns<0>()[2], band_columns<0>()[3], band_columns<0>()[4],
};

constexpr bool indexed_by_field() {
  if (std::size(kColumns) != static_cast<std::size_t>(kNumResultFields)) return false;
  for (std::size_t i = 0; i < std::size(kColumns); ++i) {
    if (static_cast<std::size_t>(kColumns[i].field) != i) return false;
  }
  return true;
}
static_assert(indexed_by_field(), "kColumns must list every ResultField in enum order");

constexpr int kFirstFitField = static_cast<int>(F::kX0);
constexpr int kFirstMetacalField = static_cast<int>(F::kR11);
constexpr int kFirstSurveyField = static_cast<int>(F::kNumber);
constexpr std::size_t kTableColumns = 3 + kFirstMetacalField - kFirstFitField;
constexpr std::size_t kMetacalTableColumns = kTableColumns + kNumMetacalFields;

// A table: three position columns, then every fit column, then (metacal) the metacal columns.
template <std::size_t N>
constexpr std::array<ResultColumn, N> table(PositionColumns positions) {
  std::array<ResultColumn, N> out{};
  std::size_t n = 0;
  if (positions == PositionColumns::kGrid) {
    for (F f : {F::kId, F::kIx, F::kIy}) out[n++] = kColumns[static_cast<int>(f)];
  } else {
    for (F f : {F::kId, F::kXImage, F::kYImage}) out[n++] = kColumns[static_cast<int>(f)];
    out[0].description = "object id from the input catalogue";
  }
  const int last = N == kTableColumns ? kFirstMetacalField : kFirstSurveyField;
  for (int f = kFirstFitField; f < last; ++f) out[n++] = kColumns[f];
  return out;
}

constexpr auto kGridTable = table<kTableColumns>(PositionColumns::kGrid);
constexpr auto kCatalogueTable = table<kTableColumns>(PositionColumns::kCatalogue);
constexpr auto kGridMetacalTable = table<kMetacalTableColumns>(PositionColumns::kGrid);
constexpr auto kCatalogueMetacalTable = table<kMetacalTableColumns>(PositionColumns::kCatalogue);

// A survey table: id number ra dec, the fit columns in sky units with psf_size for psf_fwhm, then
// n_epochs masked_frac is_bulge other_likelihood.
constexpr std::size_t kSurveyTableColumns = 4 + kFirstMetacalField - kFirstFitField + 4;
constexpr std::size_t kSurveyMetacalTableColumns = kSurveyTableColumns + kNumMetacalFields + 1;
template <std::size_t N>
constexpr std::array<ResultColumn, N> survey_table() {
  std::array<ResultColumn, N> out{};
  std::size_t n = 0;
  for (F f : {F::kId, F::kNumber, F::kRa, F::kDec}) out[n++] = kColumns[static_cast<int>(f)];
  out[0].description = "the MEDS object's id (object_data)";
  for (int f = kFirstFitField; f < kFirstMetacalField; ++f) {
    ResultColumn c = kColumns[f == static_cast<int>(F::kPsfFwhm) ? static_cast<int>(F::kPsfSize) : f];
    switch (c.field) {
      case F::kX0: c.unit = "arcsec", c.description = "fitted centroid u offset from ra, dec"; break;
      case F::kY0: c.unit = "arcsec", c.description = "fitted centroid v offset from ra, dec"; break;
      case F::kE1: c.description = "ellipticity (a-b)/(a+b) along u, after the mirror"; break;
      case F::kE2: c.description = "ellipticity along u = v, after the mirror"; break;
      case F::kRadius: c.unit = "arcsec"; break;
      case F::kBulgeA: c.description = "bulge central intensity, flux units per arcsec^2"; break;
      case F::kDiscA: c.description = "disc central intensity, flux units per arcsec^2"; break;
      case F::kBulgeFlux: c.description = "bulge flux at the zero point magzp_ref"; break;
      case F::kDiscFlux: c.description = "disc flux at the zero point magzp_ref"; break;
      case F::kFlux: c.description = "total flux at the zero point magzp_ref"; break;
      case F::kPsfE1: c.description = "mean PSF e1 over the fitted cutouts, pixel frames"; break;
      case F::kPsfE2: c.description = "mean PSF e2 over the fitted cutouts, pixel frames"; break;
      default: break;
    }
    out[n++] = c;
  }
  for (F f : {F::kNEpochs, F::kMaskedFraction, F::kIsBulge, F::kOtherLikelihood}) out[n++] = kColumns[static_cast<int>(f)];
  if (N == kSurveyTableColumns) return out;
  for (int f = kFirstMetacalField; f < kFirstMetacalField + kNumMetacalFields; ++f) {
    ResultColumn c = kColumns[f];
    if (std::string_view(c.name).starts_with("radius_")) c.unit = "arcsec";
    out[n++] = c;
  }
  out[n++] = kColumns[static_cast<int>(F::kGammaFwhm)];
  return out;
}
constexpr auto kSurveyTable = survey_table<kSurveyTableColumns>();
constexpr auto kSurveyMetacalTable = survey_table<kSurveyMetacalTableColumns>();

}  // namespace

const char* position_name(PositionColumns positions) {
  switch (positions) {
    case PositionColumns::kGrid: return "grid";
    case PositionColumns::kCatalogue: return "catalogue";
    case PositionColumns::kSurvey: return "survey";
  }
  return "?";
}

std::span<const ResultColumn> result_columns(PositionColumns positions, bool metacal) {
  if (positions == PositionColumns::kSurvey)
    return metacal ? std::span<const ResultColumn>(kSurveyMetacalTable) : std::span<const ResultColumn>(kSurveyTable);
  if (metacal)
    return positions == PositionColumns::kGrid ? std::span<const ResultColumn>(kGridMetacalTable)
                                               : std::span<const ResultColumn>(kCatalogueMetacalTable);
  return positions == PositionColumns::kGrid ? std::span<const ResultColumn>(kGridTable)
                                             : std::span<const ResultColumn>(kCatalogueTable);
}

const ResultColumn& result_column(ResultField field) { return kColumns[static_cast<int>(field)]; }

const char* column_name(ResultField field) { return result_column(field).name; }

bool is_band_name(const std::string& band, std::string* why) {
  const bool chars = std::all_of(band.begin(), band.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
  if (band.empty() || band.size() > 16 || !chars) {
    *why = "band name '" + band + "' is not 1..16 letters, digits or '_' (it ends column names: flux_<band>)";
    return false;
  }
  return true;
}

bool are_band_names(const std::vector<std::string>& bands, std::string* why) {
  const auto lower = [](std::string s) {
    for (char& c : s)
      if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    return s;
  };
  for (std::size_t b = 0; b < bands.size(); ++b) {
    if (!is_band_name(bands[b], why)) return false;
    for (std::size_t a = 0; a < b; ++a) {
      if (bands[a] == bands[b]) {
        *why = "band '" + bands[b] + "' is given twice";
        return false;
      }
      if (lower(bands[a]) == lower(bands[b])) {
        *why = "bands '" + bands[a] + "' and '" + bands[b] + "' differ only in case, which FITS column names ignore (flux_" +
               bands[a] + " is flux_" + bands[b] + "); name them apart";
        return false;
      }
    }
  }
  return true;
}

ResultSchema::ResultSchema(PositionColumns positions, bool metacal, const std::vector<std::string>& bands) : bands_(bands) {
  const std::span<const ResultColumn> base = result_columns(positions, metacal);
  columns_.assign(base.begin(), base.end());
  if (bands.size() > static_cast<std::size_t>(kMaxBands))
    throw std::invalid_argument(std::to_string(bands.size()) + " bands: at most " + std::to_string(kMaxBands));
  if (std::string why; !are_band_names(bands, &why)) throw std::invalid_argument(why);
  for (std::size_t b = 0; b < bands.size(); ++b) {
    for (ResultColumn c : kBandColumns[b]) {
      std::string name(c.name);
      name.replace(name.size() - 4, 4, bands[b]);
      text_.push_back(std::make_unique<std::string>(std::move(name)));
      c.name = text_.back()->c_str();
      std::string description = "band " + bands[b] + ": " + c.description;  // <= 68 characters: a name <= 16
      text_.push_back(std::make_unique<std::string>(std::move(description)));
      c.description = text_.back()->c_str();
      columns_.push_back(c);
    }
  }
}

std::vector<std::string> catalog_columns(PositionColumns positions, bool metacal) {
  std::vector<std::string> names;
  for (const ResultColumn& c : result_columns(positions, metacal)) names.emplace_back(c.name);
  return names;
}

}  // namespace stampede::io
