// Validation of MetadetectOptions; see metadetect_options.hpp.
#include "engine/metadetect/metadetect_options.hpp"

#include <cctype>
#include <cmath>
#include <initializer_list>
#include <sstream>
#include <string>
#include <utility>

#include "engine/metadetect/metadetect_row.hpp"

namespace stampede {

const char* metadetect_measurement_name(MetadetectMeasurement m) {
  switch (m) {
    case MetadetectMeasurement::kPgauss: return "pgauss";
    case MetadetectMeasurement::kExp: return "exp";
    case MetadetectMeasurement::kBd: return "bd";
    case MetadetectMeasurement::kGauss: return "gauss";
    case MetadetectMeasurement::kWmom: break;
  }
  return "wmom";
}

namespace {

// `name` is one of `values`, compared with their names in lower case whatever its case.
template <class T, class Name>
bool parse_name(std::string_view name, std::initializer_list<T> values, Name value_name, T* out) {
  for (T v : values) {
    const std::string_view known = value_name(v);
    bool same = name.size() == known.size();
    for (std::size_t i = 0; same && i < name.size(); ++i)
      same = std::tolower(static_cast<unsigned char>(name[i])) == known[i];
    if (same) {
      *out = v;
      return true;
    }
  }
  return false;
}

}  // namespace

bool parse_metadetect_measurement(std::string_view name, MetadetectMeasurement* out) {
  return parse_name(name,
                    {MetadetectMeasurement::kWmom, MetadetectMeasurement::kPgauss, MetadetectMeasurement::kExp,
                     MetadetectMeasurement::kBd, MetadetectMeasurement::kGauss},
                    metadetect_measurement_name, out);
}

const char* detector_kind_name(DetectorKind d) { return d == DetectorKind::kSep ? "sep" : "tree"; }

bool parse_detector_kind(std::string_view name, DetectorKind* out) {
  return parse_name(name, {DetectorKind::kTree, DetectorKind::kSep}, detector_kind_name, out);
}

double MetadetectOptions::weight_fwhm_arcsec() const {
  if (weight_fwhm != 0) return weight_fwhm;
  return measurement == MetadetectMeasurement::kPgauss ? 2.0 : 1.2;
}

namespace {

template <class T>
bool refuse(std::string* why, const char* option, T value, const char* rule) {
  if (why) {
    std::ostringstream s;
    s << option << " = " << value << ": " << rule;
    *why = s.str();
  }
  return false;
}

}  // namespace

bool MetadetectOptions::IsValid(std::string* why) const {
  if (cell_size < 16 || cell_size > 4096) return refuse(why, "cell_size", cell_size, "must be in [16, 4096] pixels");
  if (cell_buffer < 0 || cell_size - 2 * cell_buffer < kMinCellInterior) {
    const std::string rule = "must be >= 0 and leave an interior of at least " + std::to_string(kMinCellInterior) +
                             " pixels (cell_size " + std::to_string(cell_size) + " - 2 cell_buffer): detections are kept only there";
    return refuse(why, "cell_buffer", cell_buffer, rule.c_str());
  }
  if (!(step >= 1e-3 && step <= 0.1)) return refuse(why, "step", step, "must be in [0.001, 0.1]");
  if (!(psf_dilation == 0 || (psf_dilation >= 1 && psf_dilation <= 3)))
    return refuse(why, "psf_dilation", psf_dilation, "must be 0 (automatic) or in [1, 3]");
  if (measurement != MetadetectMeasurement::kWmom && measurement != MetadetectMeasurement::kPgauss &&
      measurement != MetadetectMeasurement::kExp && measurement != MetadetectMeasurement::kBd &&
      measurement != MetadetectMeasurement::kGauss)
    return refuse(why, "measurement", static_cast<int>(measurement), "must be wmom, pgauss, gauss, exp or bd");
  if (!(weight_fwhm >= 0 && std::isfinite(weight_fwhm)))
    return refuse(why, "weight_fwhm", weight_fwhm, "must be > 0 arcsec, or 0 for the measurement's default");
  if (per_object_metacal && measurement != MetadetectMeasurement::kWmom)
    return refuse(why, "measurement", metadetect_measurement_name(measurement),
                  "per_object_metacal measures with wmom only");
  if (weight_fwhm != 0 && is_model_fit(measurement))
    return refuse(why, "weight_fwhm", weight_fwhm,
                  "weighs wmom and pgauss; a model fit (gauss, exp or bd) has no weight");
  if (!(mfrac_fwhm > 0 && mfrac_fwhm <= 60)) return refuse(why, "mfrac_fwhm", mfrac_fwhm, "must be in (0, 60] arcsec");
  for (const auto& [field, mask] : {std::pair{"detect_bands", detect_bands}, std::pair{"shear_bands", shear_bands}})
    if (mask >= (1u << kMaxMetadetectBands))
      return refuse(why, field, static_cast<long long>(mask),
                    ("must name bands 0 to " + std::to_string(kMaxMetadetectBands - 1) + " (bit b: band b; 0 every band)").c_str());
  if (detection.detector != DetectorKind::kTree && detection.detector != DetectorKind::kSep)
    return refuse(why, "detector", static_cast<int>(detection.detector), "must be tree or sep");
  if (!(detection.threshold > 0 && std::isfinite(detection.threshold)))
    return refuse(why, "detect_threshold", detection.threshold, "must be > 0 (sigma)");
  if (detection.min_area < 1 || detection.min_area > 1000000)
    return refuse(why, "detect_min_area", detection.min_area, "must be in [1, 1000000] pixels");
  if (!(detection.deblend_contrast >= 0 && detection.deblend_contrast <= 1))
    return refuse(why, "deblend_contrast", detection.deblend_contrast, "must be in [0, 1]");
  if (detection.deblend_thresholds < 1 || detection.deblend_thresholds > 256)
    return refuse(why, "deblend_thresholds", detection.deblend_thresholds, "must be in [1, 256]");
  if (!(detection.filter_fwhm >= 0 && detection.filter_fwhm <= 20))
    return refuse(why, "filter_fwhm", detection.filter_fwhm, "must be in [0, 20] pixels (0: no filter)");
  if (detection.filter_size < 3 || detection.filter_size > 31 || detection.filter_size % 2 == 0)
    return refuse(why, "filter_size", detection.filter_size, "must be odd, in [3, 31]");
  if (stamp.size != 0 && (stamp.size < 8 || stamp.size > 255))
    return refuse(why, "stamp_size", stamp.size, "must be in [8, 255] pixels, or 0 for stamps sized by the isophote");
  if (stamp.box_min < 9 || stamp.box_min % 2 == 0)
    return refuse(why, "box_min", stamp.box_min, "must be odd and >= 9");
  if (stamp.box_max < stamp.box_min || stamp.box_max % 2 == 0 || stamp.box_max > 4095) {
    const std::string rule = "must be odd, >= box_min (" + std::to_string(stamp.box_min) + ") and <= 4095";
    return refuse(why, "box_max", stamp.box_max, rule.c_str());
  }
  if (seed > (std::uint64_t{1} << 62)) return refuse(why, "seed", seed, "must be in [0, 2^62]");
  return true;
}

}  // namespace stampede
