// The metadetection options' one table; see metadetect_option_keys.hpp.
#include "app/metadetect_option_keys.hpp"

#include <algorithm>

#include "io/option_text.hpp"

namespace stampede::app {
namespace {

using Kind = MetadetectOptionKey::Kind;

// The shortest text that reads back to exactly v ("0.8", not "0.80000000000000004").
std::string real_text(double v) { return io::format_double(v); }

// Entries over a field reached by `access`, a generic lambda `[](auto& o) -> auto& { return o.field; }`
// that serves the const reader and the setter alike.
template <class Access>
MetadetectOptionKey integer(const char* field, const char* flag, const char* metavar, const char* header, Access access,
                            const char* help) {
  return {field, flag, metavar, header, Kind::kInteger, true,
          [access](const MetadetectOptions& o) { return std::to_string(access(o)); },
          [access](MetadetectOptions& o, std::string_view text) {
            using Int = std::remove_reference_t<decltype(access(o))>;
            Int v = 0;
            std::string why = io::parse_integer(text, &v);
            if (why.empty()) access(o) = v;
            return why;
          },
          help};
}
template <class Access>
MetadetectOptionKey real(const char* field, const char* flag, const char* metavar, const char* header, Access access,
                         const char* help) {
  return {field, flag, metavar, header, Kind::kReal, true,
          [access](const MetadetectOptions& o) { return real_text(access(o)); },
          [access](MetadetectOptions& o, std::string_view text) {
            double v = 0;
            std::string why = io::parse_double(text, io::DoubleKind::kFinite, &v);
            if (why.empty()) access(o) = v;
            return why;
          },
          help};
}
template <class Access>
MetadetectOptionKey toggle(const char* field, const char* flag, bool sets, const char* header, Access access,
                           const char* help) {
  return {field, flag, "", header, Kind::kSwitch, sets,
          [access](const MetadetectOptions& o) { return std::string(access(o) ? "T" : "F"); },
          [access](MetadetectOptions& o, std::string_view text) {
            bool v = text == "T";  // as recorded
            std::string why = text == "T" || text == "F" ? std::string() : io::parse_bool(text, &v);
            if (why.empty()) access(o) = v;
            return why;
          },
          help};
}
// A named choice: `name` prints a value, `parse` reads one (false for an unknown name).
template <class Access, class Name, class Parse>
MetadetectOptionKey choice(const char* field, const char* flag, const char* metavar, const char* header, Access access,
                           Name name, Parse parse, const char* names, const char* help) {
  return {field, flag, metavar, header, Kind::kChoice, true,
          [access, name](const MetadetectOptions& o) { return std::string(name(access(o))); },
          [access, parse, names = std::string(names)](MetadetectOptions& o, std::string_view text) {
            return parse(text, &access(o)) ? std::string() : "must be " + names;
          },
          help};
}

std::vector<MetadetectOptionKey> make_table() {
  using O = MetadetectOptions;
  std::vector<MetadetectOptionKey> t = {
      integer("cell_size", "--cell-size", "N", "CELLSIZE", [](auto& o) -> auto& { return o.cell_size; }, "cell side, pixels (%s)"),
      integer("cell_buffer", "--cell-buffer", "N", "CELLBUF", [](auto& o) -> auto& { return o.cell_buffer; },
              "pixels at each cell edge whose detections are not the cell's (%s)"),
      real("step", "--step", "S", "MCSTEP", [](auto& o) -> auto& { return o.step; }, "metacal shear step (%s)"),
      real("psf_dilation", "--psf-dilation", "F", "MCPSFDIL", [](auto& o) -> auto& { return o.psf_dilation; },
           "reconvolution PSF FWHM over the PSF's; 0: the rule's own (%s)"),
      choice("reconvolution_psf", "--reconvolution-psf", "R", "MCRECONV", [](auto& o) -> auto& { return o.reconvolution; },
             reconvolution_rule_name, parse_reconvolution_rule, "auto, gauss or moffat",
             "metacal's reconvolution PSF: gauss (the PSF's adaptive Gaussian,\n"
             "round on its major axis, dilated by 1 + 2 step, as the reference\n"
             "package's fitgauss), moffat (a round Moffat widened until its\n"
             "filters are <= 1.01), auto: the Gaussian where its filters are\n"
             "<= 1.01 too (Gaussian-like PSFs), else moffat; gauss accepts up\n"
             "to 1.5 (%s)"),
      toggle("fixnoise", "--no-fixnoise", false, "FIXNOISE", [](auto& o) -> auto& { return o.fixnoise; },
             "do not add the rotated noise field"),
      toggle("symmetrise_mask", "--no-mask-symmetry", false, "MASKSYM", [](auto& o) -> auto& { return o.symmetrise_mask; },
             "keep the mask as given (by default a pixel is also masked when\n"
             "a quarter, half or three-quarter turn from it is, so the mask's\n"
             "shape has no quadrupole for metacal's shear to act on)"),
      toggle("fill_masked", "--no-mask-fill", false, "MASKFILL", [](auto& o) -> auto& { return o.fill_masked; },
             "zero the masked pixels (by default they are filled from the\n"
             "unmasked pixels around them, a plane fitted under a Gaussian\n"
             "weight, before the metacal images are made)"),
      real("mfrac_fwhm", "--mfrac-fwhm", "F", "MFRACFW", [](auto& o) -> auto& { return o.mfrac_fwhm; },
           "mfrac: the masked share of a Gaussian of this FWHM (arcsec) about\n"
           "each detection (%s)"),
      {"double_images", "--double-images", "", "IMGPREC", Kind::kSwitch, true,
       [](const O& o) { return std::string(o.double_images ? "double" : "single"); },
       [](O& o, std::string_view text) {
         if (text != "double" && text != "single") return io::parse_bool(text, &o.double_images);
         o.double_images = text == "double";  // as recorded
         return std::string();
       },
       "make the cells' metacal images in double precision (by default\n"
       "single: about half the time, within ~2e-7 of the images' peak)"},
      toggle("per_object_metacal", "--per-object-metacal", true, "PEROBJMC", [](auto& o) -> auto& { return o.per_object_metacal; },
             "not metadetection, for comparison: per-object metacal at the\n"
             "positions detected on the noshear image (each a 49 px stamp)"),
      toggle("noise_plane", "--no-noise-plane", false, "NOISEPLN", [](auto& o) -> auto& { return o.noise_plane; },
             "draw the fixnoise field from the weight even where the input has\n"
             "a NOISE HDU or noise cutouts (which are used by default)"),
      integer("seed", "--seed", "N", "MCSEED", [](auto& o) -> auto& { return o.seed; },
              "keys each cell's fixnoise field with the cell's number (%s)"),
      choice("measurement", "--measurement", "M", "MEASURE", [](auto& o) -> auto& { return o.measurement; },
             metadetect_measurement_name, parse_metadetect_measurement, "wmom, pgauss, gauss, exp or bd",
             "wmom: moments of the metacal image under a round Gaussian weight;\n"
             "pgauss: the moments of the galaxy before the reconvolution PSF\n"
             "(and pixel) under the weight, in Fourier space; T_ratio is then\n"
             "the pre-PSF T over the reconvolved PSF's weighted T (wmom);\n"
             "gauss, exp, bd: a fit of that model (gauss: a Gaussian, the\n"
             "reference package's) convolved with the reconvolution\n"
             "PSF (one band), T the model's, T_ratio over the same psf_T (%s)"),
      {"weight_fwhm", "--weight-fwhm", "F", "WFWHM", Kind::kReal, true,
       [](const O& o) { return real_text(o.weight_fwhm_arcsec()); },  // the weight used, its default resolved
       [](O& o, std::string_view text) { return io::parse_double(text, io::DoubleKind::kFinite, &o.weight_fwhm); },
       "the moments' weight FWHM, arcsec; 0: the measurement's (1.2 wmom,\n"
       "2.0 pgauss)"},
      toggle("recentre", "--recentre", true, "RECENTRE", [](auto& o) -> auto& { return o.recentre; },
             "wmom, pgauss: move the weight to the weighted centroid (six Newton\n"
             "steps); by default it stays at the detection's position"),
      toggle("keep_unlensed", "--keep-unlensed", true, "KEEPUNL", [](auto& o) -> auto& { return o.keep_unlensed; },
             "simulations: keep a detection by its position with the cell's\n"
             "recorded shear (G1, G2) undone too, as a tiled survey's cells\n"
             "keep what the shear moves across a lone cell's boundary"),
      choice("detector", "--detector", "D", "DETECTOR", [](auto& o) -> auto& { return o.detection.detector; },
             detector_kind_name, parse_detector_kind, "tree or sep",
             "tree: our implementation of Source Extractor's detection (one\n"
             "pass over each segment's pixels yields its components at every\n"
             "deblending level; an unclaimed pixel goes to its most probable\n"
             "child); sep: SEP's library, for comparison (%s)"),
      real("detect_threshold", "--detect-threshold", "T", "DETTHR", [](auto& o) -> auto& { return o.detection.threshold; },
           "detection threshold, noise sigma (%s)"),
      integer("detect_min_area", "--detect-min-area", "N", "DETMINA", [](auto& o) -> auto& { return o.detection.min_area; },
              "minimum pixels above the threshold (%s)"),
      real("deblend_contrast", "--deblend-contrast", "C", "DBLCONT", [](auto& o) -> auto& { return o.detection.deblend_contrast; },
           "minimum deblending contrast (%s)"),
      integer("deblend_thresholds", "--deblend-thresholds", "N", "DBLNTHR",
              [](auto& o) -> auto& { return o.detection.deblend_thresholds; }, "deblending levels (%s)"),
      real("filter_fwhm", "--filter-fwhm", "F", "FILTFWHM", [](auto& o) -> auto& { return o.detection.filter_fwhm; },
           "Gaussian detection filter FWHM, pixels; 0: none (%s)"),
      integer("filter_size", "--filter-size", "N", "FILTSIZE", [](auto& o) -> auto& { return o.detection.filter_size; },
              "the filter's odd side, pixels (%s)"),
      toggle("clean", "--no-clean", false, "CLEAN", [](auto& o) -> auto& { return o.detection.clean; },
             "do not clean spurious detections near bright objects"),
      real("clean_param", "", "", "CLEANPAR", [](auto& o) -> auto& { return o.detection.clean_param; }, ""),
      integer("stamp_size", "--stamp-size", "N", "STAMPSZ", [](auto& o) -> auto& { return o.stamp.size; },
              "every detection's stamp N x N pixels about its pixel; 0: sized\n"
              "from the isophotal area between --box-min and --box-max (%s)"),
      real("box_radius_factor", "", "", "BOXRFAC", [](auto& o) -> auto& { return o.stamp.radius_factor; }, ""),
      real("box_radius_min", "", "", "BOXRMIN", [](auto& o) -> auto& { return o.stamp.radius_min; }, ""),
      real("box_padding", "", "", "BOXPAD", [](auto& o) -> auto& { return o.stamp.padding; }, ""),
      integer("box_min", "--box-min", "N", "BOXMIN", [](auto& o) -> auto& { return o.stamp.box_min; },
              "--stamp-size 0: a stamp's least odd side, pixels (%s)"),
      integer("box_max", "--box-max", "N", "BOXMAX", [](auto& o) -> auto& { return o.stamp.box_max; },
              "--stamp-size 0: a stamp's largest odd side, pixels (%s)"),
  };
  return t;
}

}  // namespace

io::HeaderValueType MetadetectOptionKey::header_type() const {
  switch (kind) {
    case Kind::kInteger: return io::HeaderValueType::kInteger;
    case Kind::kReal: return io::HeaderValueType::kReal;
    default: return io::HeaderValueType::kText;
  }
}

const std::vector<MetadetectOptionKey>& metadetect_option_keys() {
  static const std::vector<MetadetectOptionKey> table = make_table();
  return table;
}

std::vector<std::pair<std::string, std::string>> metadetect_header_keys(const MetadetectOptions& options) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const MetadetectOptionKey& k : metadetect_option_keys()) out.emplace_back(k.header, k.recorded(options));
  return out;
}

std::map<std::string, io::HeaderValueType> metadetect_header_types() {
  std::map<std::string, io::HeaderValueType> out;
  for (const MetadetectOptionKey& k : metadetect_option_keys())
    if (k.header_type() != io::HeaderValueType::kText) out[k.header] = k.header_type();
  return out;
}

std::string with_metadetect_flags(std::string message) {
  const auto& keys = metadetect_option_keys();
  return io::fields_to_flags(message, [&](std::string_view field) {
    const auto k = std::find_if(keys.begin(), keys.end(), [&](const MetadetectOptionKey& e) { return e.field == field; });
    return k != keys.end() ? k->flag : std::string();
  });
}

}  // namespace stampede::app
