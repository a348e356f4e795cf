// stampede.metadetect(): metadetection of an image held in numpy arrays (app/metadetect_run), the
// GIL released; the rows as a structured array with the METADETECT table's columns.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "app/metadetect_metrics.hpp"
#include "app/metadetect_option_keys.hpp"
#include "app/metadetect_run.hpp"
#include "io/option_text.hpp"
#include "arguments.hpp"
#include "engine/metacal/metacal_type.hpp"
#include "engine/metadetect/object_detector.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "io/cell_image_reader.hpp"
#include "io/config_error.hpp"
#include "io/metadetect_package_layout.hpp"
#include "numpy_arrays.hpp"

namespace py = pybind11;

namespace stampede::python {
namespace {

template <class T, class Get>
py::array_t<T> column(const std::vector<MetadetectRow>& rows, Get get) {
  py::array_t<T> a(static_cast<py::ssize_t>(rows.size()));
  T* p = a.mutable_data();
  for (std::size_t i = 0; i < rows.size(); ++i) p[i] = static_cast<T>(get(rows[i]));
  return a;
}

// With several bands, each band's flux_bK and snr_bK (the names a file run gives unnamed bands).
py::object rows_array(const std::vector<MetadetectRow>& rows, int bands) {
  const py::module_ np = py::module_::import("numpy");
  py::list fields;
  auto add = [&](const char* name, const char* format) { fields.append(py::make_tuple(name, format)); };
  add("cell", "i8"), add("shear_type", "U7"), add("id", "i4");
  for (const char* n : {"x", "y", "u", "v", "e1", "e2", "e1_err", "e2_err", "T", "T_ratio", "psf_T", "flux", "snr", "mfrac"})
    add(n, "f8");
  add("box_size", "i4"), add("isophotal_area", "i4"), add("sep_flags", "i4"), add("flags", "u4");
  for (const char* n : {"psf_orig_e1", "psf_orig_e2", "psf_orig_T", "psf_rec_e1", "psf_rec_e2", "x_noshear", "y_noshear"})
    add(n, "f8");
  add("bmask", "i4"), add("ormask", "i4");
  std::vector<std::string> band_names;
  for (int b = 0; bands > 1 && b < bands; ++b) band_names.push_back("b" + std::to_string(b));
  for (const std::string& b : band_names) fields.append(py::make_tuple("flux_" + b, "f8"));
  for (const std::string& b : band_names) fields.append(py::make_tuple("snr_" + b, "f8"));
  py::object out = np.attr("zeros")(rows.size(), np.attr("dtype")(fields));
  out[py::str("cell")] = column<long long>(rows, [](const MetadetectRow& r) { return r.cell; });
  py::list types;
  for (const MetadetectRow& r : rows) types.append(metacal_type_name(static_cast<MetacalType>(r.shear_type)));
  out[py::str("shear_type")] = np.attr("array")(types, "U7");
  out[py::str("id")] = column<int>(rows, [](const MetadetectRow& r) { return r.id; });
  out[py::str("x")] = column<double>(rows, [](const MetadetectRow& r) { return r.x; });
  out[py::str("y")] = column<double>(rows, [](const MetadetectRow& r) { return r.y; });
  out[py::str("u")] = column<double>(rows, [](const MetadetectRow& r) { return r.u; });
  out[py::str("v")] = column<double>(rows, [](const MetadetectRow& r) { return r.v; });
  out[py::str("e1")] = column<double>(rows, [](const MetadetectRow& r) { return r.e1; });
  out[py::str("e2")] = column<double>(rows, [](const MetadetectRow& r) { return r.e2; });
  out[py::str("e1_err")] = column<double>(rows, [](const MetadetectRow& r) { return r.e1_err; });
  out[py::str("e2_err")] = column<double>(rows, [](const MetadetectRow& r) { return r.e2_err; });
  out[py::str("T")] = column<double>(rows, [](const MetadetectRow& r) { return r.t; });
  out[py::str("T_ratio")] = column<double>(rows, [](const MetadetectRow& r) { return r.t_ratio; });
  out[py::str("psf_T")] = column<double>(rows, [](const MetadetectRow& r) { return r.psf_t; });
  out[py::str("flux")] = column<double>(rows, [](const MetadetectRow& r) { return r.flux; });
  out[py::str("snr")] = column<double>(rows, [](const MetadetectRow& r) { return r.snr; });
  out[py::str("mfrac")] = column<double>(rows, [](const MetadetectRow& r) { return r.mfrac; });
  out[py::str("box_size")] = column<int>(rows, [](const MetadetectRow& r) { return r.box_size; });
  out[py::str("isophotal_area")] = column<int>(rows, [](const MetadetectRow& r) { return r.isophotal_area; });
  out[py::str("sep_flags")] = column<int>(rows, [](const MetadetectRow& r) { return r.sep_flags; });
  out[py::str("flags")] = column<unsigned>(rows, [](const MetadetectRow& r) { return r.flags; });
  out[py::str("psf_orig_e1")] = column<double>(rows, [](const MetadetectRow& r) { return r.psf_orig_e1; });
  out[py::str("psf_orig_e2")] = column<double>(rows, [](const MetadetectRow& r) { return r.psf_orig_e2; });
  out[py::str("psf_orig_T")] = column<double>(rows, [](const MetadetectRow& r) { return r.psf_orig_t; });
  out[py::str("psf_rec_e1")] = column<double>(rows, [](const MetadetectRow& r) { return r.psf_rec_e1; });
  out[py::str("psf_rec_e2")] = column<double>(rows, [](const MetadetectRow& r) { return r.psf_rec_e2; });
  out[py::str("x_noshear")] = column<double>(rows, [](const MetadetectRow& r) { return r.x_noshear; });
  out[py::str("y_noshear")] = column<double>(rows, [](const MetadetectRow& r) { return r.y_noshear; });
  out[py::str("bmask")] = column<int>(rows, [](const MetadetectRow& r) { return r.bmask; });
  out[py::str("ormask")] = column<int>(rows, [](const MetadetectRow& r) { return r.ormask; });
  for (std::size_t b = 0; b < band_names.size(); ++b) {
    out[py::str("flux_" + band_names[b])] = column<double>(rows, [b](const MetadetectRow& r) { return r.band_flux[b]; });
    out[py::str("snr_" + band_names[b])] = column<double>(rows, [b](const MetadetectRow& r) { return r.band_snr[b]; });
  }
  return out;
}

// The detection options both detect() and metadetect() take.
void read_detection_options(const Arguments& a, DetectionOptions* d) {
  if (const std::string v = a.text("detector", detector_kind_name(d->detector)); !parse_detector_kind(v, &d->detector))
    throw py::value_error(a.where("detector") + ": '" + v + "' must be tree or sep");
  d->threshold = a.real("detect_threshold", d->threshold);
  d->min_area = static_cast<int>(a.integer("detect_min_area", d->min_area));
  d->deblend_contrast = a.real("deblend_contrast", d->deblend_contrast);
  d->deblend_thresholds = static_cast<int>(a.integer("deblend_thresholds", d->deblend_thresholds));
  d->filter_fwhm = a.real("filter_fwhm", d->filter_fwhm);
  d->filter_size = static_cast<int>(a.integer("filter_size", d->filter_size));
  d->clean = a.flag("clean", d->clean);
}

// metadetect()'s parameters: the image's, then every option of the table by its field's name.
std::vector<Parameter> metadetect_parameters() {
  std::vector<Parameter> p = {{"image", true},          {"weight", true},         {"psf", true},
                              {"pixel_scale", true},    {"bmask"},                {"threads"},
                              {"noise", false, true},   {"ormask", false, true},  {"mfrac", false, true},  {"detect_bands", false, true},
                              {"shear_bands", false, true}, {"layout", false, true}};
  for (const app::MetadetectOptionKey& k : app::metadetect_option_keys())
    if (k.python()) p.push_back({k.field.c_str(), false, true});
  return p;
}

// The options given as keywords, each read as its kind and set through the table.
MetadetectOptions read_metadetect_options(const Arguments& a) {
  MetadetectOptions o;
  using Kind = app::MetadetectOptionKey::Kind;
  for (const app::MetadetectOptionKey& k : app::metadetect_option_keys()) {
    const char* name = k.field.c_str();
    if (!k.python() || !a.given(name)) continue;
    std::string text;
    switch (k.kind) {
      case Kind::kInteger: text = std::to_string(a.integer(name, 0)); break;
      case Kind::kReal: text = io::format_double(a.real(name, 0)); break;
      case Kind::kSwitch: text = io::format_bool(a.flag(name, false)); break;
      case Kind::kChoice: text = a.text(name); break;
    }
    if (const std::string why = k.set(o, text); !why.empty())
      throw py::value_error(a.where(name) + ": '" + text + "' " + why);
  }
  return o;
}

// A per-band argument: a 2-D array (one band), a 3-D array (band first) or a sequence of 2-D
// arrays, each band's checked as `name`[b]; `bits`: integer mask planes, taken as float64 (exact).
std::vector<DoubleArray> band_arrays(const Arguments& a, const char* name, bool bits = false) {
  const py::object v = a.object(name);
  std::vector<py::object> items;
  if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    for (const py::handle h : v) items.push_back(py::reinterpret_borrow<py::object>(h));
  } else {
    const py::object arr = py::module_::import("numpy").attr("asarray")(v);
    if (arr.attr("ndim").cast<int>() == 3) {
      const long n = arr.attr("shape").cast<py::tuple>()[0].cast<long>();
      for (long b = 0; b < n; ++b) items.push_back(arr[py::int_(b)]);
    } else {
      items.push_back(v);
    }
  }
  std::vector<DoubleArray> out;
  for (std::size_t b = 0; b < items.size(); ++b) {
    std::string what = a.where(name);
    if (items.size() > 1 || py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v))
      what.append(1, '[').append(std::to_string(b)).append(1, ']');
    const py::object item = bits ? py::module_::import("numpy").attr("asarray")(items[b], "float64") : items[b];
    out.push_back(as_float64(item, {2}, what.c_str()));
  }
  return out;
}

// A band-role list (band indices) as the options' bit mask (0: not given, every band).
std::uint32_t band_role(const Arguments& a, const char* name, int bands) {
  if (!a.given(name)) return 0;
  const std::vector<long long> v = integer_values(a.object(name), a.where(name), 0, bands - 1, false);
  if (v.empty()) throw py::value_error(a.where(name) + ": at least one band index");
  std::uint32_t mask = 0;
  for (const long long b : v) mask |= 1u << b;
  return mask;
}

// The rows in the reference package's layout: {shear type: structured array}.
py::dict package_arrays(const std::vector<MetadetectRow>& rows, const io::PackageLayoutOptions& layout) {
  const py::module_ np = py::module_::import("numpy");
  const std::vector<io::PackageColumn> columns = io::package_columns(layout);
  py::list fields;
  for (const io::PackageColumn& c : columns) {
    using Type = io::PackageColumn::Type;
    const char* format = c.type == Type::kFloat64   ? "f8"
                         : c.type == Type::kFloat32 ? "f4"
                         : c.type == Type::kInt32   ? "i4"
                         : c.type == Type::kInt64   ? "i8"
                                                    : nullptr;
    if (!format) {
      fields.append(py::make_tuple(c.name, "U" + std::to_string(c.shape[0])));
    } else if (c.shape.empty()) {
      fields.append(py::make_tuple(c.name, format));
    } else {
      py::tuple shape(c.shape.size());
      for (std::size_t k = 0; k < c.shape.size(); ++k) shape[k] = c.shape[k];
      fields.append(py::make_tuple(c.name, format, shape));
    }
  }
  const py::object dtype = np.attr("dtype")(fields);
  py::dict out;
  const std::vector<std::vector<const MetadetectRow*>> by = io::rows_by_shear_type(rows);
  for (int t = 0; t < kNumMetacalTypes; ++t) {
    const std::vector<const MetadetectRow*>& in = by[static_cast<std::size_t>(t)];
    py::object table = np.attr("zeros")(in.size(), dtype);
    for (const io::PackageColumn& c : columns) {
      if (c.type == io::PackageColumn::Type::kText) {
        table[py::str(c.name)] = py::str(c.text);
        continue;
      }
      const auto k = static_cast<std::size_t>(c.count());
      py::array_t<double> values({static_cast<py::ssize_t>(in.size()), static_cast<py::ssize_t>(k)});
      double* p = values.mutable_data();
      for (std::size_t r = 0; r < in.size(); ++r) c.values(*in[r], std::span<double>(p + r * k, k));
      py::list shape;
      shape.append(in.size());
      for (const int d : c.shape) shape.append(d);
      table[py::str(c.name)] = values.attr("reshape")(py::tuple(shape));
    }
    out[py::str(metacal_type_name(kMetacalTypes[static_cast<std::size_t>(t)]))] = table;
  }
  return out;
}

py::object metadetect(py::args args, py::kwargs kwargs) {
  static const std::vector<Parameter> parameters = metadetect_parameters();
  const Arguments a("metadetect", args, kwargs, parameters);
  const std::vector<DoubleArray> images = band_arrays(a, "image");
  const std::vector<DoubleArray> weights = band_arrays(a, "weight");
  const std::vector<DoubleArray> psfs = band_arrays(a, "psf");
  const std::size_t nb = images.size();
  if (nb > static_cast<std::size_t>(kMaxMetadetectBands))
    throw py::value_error(a.where("image") + ": " + std::to_string(nb) + " bands; at most " +
                          std::to_string(kMaxMetadetectBands));
  std::vector<DoubleArray> bmasks, ormasks, mfracs, noises;
  if (a.given("bmask")) bmasks = band_arrays(a, "bmask", true);
  if (a.given("ormask")) ormasks = band_arrays(a, "ormask", true);
  if (a.given("noise")) noises = band_arrays(a, "noise");
  if (a.given("mfrac")) mfracs = band_arrays(a, "mfrac");
  using Bands = const std::vector<DoubleArray>*;
  for (const auto& [name, list] : {std::pair<const char*, Bands>{"weight", &weights}, {"psf", &psfs}, {"bmask", &bmasks},
                                   {"ormask", &ormasks}, {"mfrac", &mfracs}, {"noise", &noises}})
    if (!list->empty() && list->size() != nb)
      throw py::value_error(a.where(name) + ": " + std::to_string(list->size()) + " bands, the image " +
                            std::to_string(nb));
  MetadetectOptions o = read_metadetect_options(a);
  o.detect_bands = band_role(a, "detect_bands", static_cast<int>(nb));
  o.shear_bands = band_role(a, "shear_bands", static_cast<int>(nb));
  const double scale = a.real("pixel_scale", 0);
  if (!(scale > 0 && std::isfinite(scale))) throw py::value_error(a.where("pixel_scale") + ": must be finite and > 0 (arcsec per pixel)");
  const int threads = static_cast<int>(a.integer_in("threads", 0, 0, 4096));
  const std::string layout = a.text("layout", "table");
  if (layout != "table" && layout != "package")
    throw py::value_error(a.where("layout") + ": '" + layout + "' must be table or package");
  std::vector<io::CellImage> bands(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    const std::string band = nb > 1 ? "[" + std::to_string(b) + "]" : "";
    const DoubleArray& image = images[b];
    auto same_shape = [&](const DoubleArray& x, const char* name) {
      if (x.shape(0) != image.shape(0) || x.shape(1) != image.shape(1))
        throw py::value_error(a.where(name) + band + ": shape differs from the image's");
    };
    io::CellImage& im = bands[b];
    same_shape(weights[b], "weight");
    im.width = static_cast<long>(image.shape(1)), im.height = static_cast<long>(image.shape(0));
    im.pixel_scale = scale;
    im.pixels.assign(image.data(), image.data() + image.size());
    im.weight.assign(weights[b].data(), weights[b].data() + weights[b].size());
    auto p = std::make_shared<PsfImage>();
    p->nx = static_cast<int>(psfs[b].shape(1)), p->ny = static_cast<int>(psfs[b].shape(0));
    p->pixels.assign(psfs[b].data(), psfs[b].data() + psfs[b].size());
    if (const std::string why = io::cell_psf_problem(*p); !why.empty()) throw py::value_error(a.where("psf") + band + ": " + why);
    im.psf = p;
    std::vector<double> mask;
    if (!bmasks.empty()) {
      same_shape(bmasks[b], "bmask");
      mask.assign(bmasks[b].data(), bmasks[b].data() + bmasks[b].size());
      im.bmask = io::mask_bits(mask);
    }
    if (!ormasks.empty()) {
      same_shape(ormasks[b], "ormask");
      im.ormask = io::mask_bits(values(ormasks[b]));
    }
    if (!mfracs.empty()) {
      same_shape(mfracs[b], "mfrac");
      im.mfrac.assign(mfracs[b].data(), mfracs[b].data() + mfracs[b].size());
      if (const std::string why = io::mfrac_problem(im.mfrac, im.width); !why.empty())
        throw py::value_error(a.where("mfrac") + band + ": " + why);
    }
    if (!noises.empty()) {
      same_shape(noises[b], "noise");
      im.noise.assign(noises[b].data(), noises[b].data() + noises[b].size());
    }
    try {
      io::apply_cell_masks(mask, &im);
    } catch (const std::invalid_argument& e) {
      throw py::value_error(a.where("weight") + band + ": " + e.what());
    }
    if (const std::string why = io::cell_noise_problem(im); !why.empty())
      throw py::value_error(a.where("noise") + band + ": " + why);
  }
  std::vector<MetadetectRow> rows;
  {
    py::gil_scoped_release release;
    rows = app::metadetect_image(bands, o, threads);
  }
  if (layout == "table") return rows_array(rows, static_cast<int>(nb));
  io::PackageLayoutOptions pl;
  pl.measurement = metadetect_measurement_name(o.measurement);
  pl.bands = static_cast<int>(nb);
  pl.shear_bands = io::package_band_indices(o.shear_bands, pl.bands);
  pl.det_bands = io::package_band_indices(o.detect_bands, pl.bands);
  return package_arrays(rows, pl);
}

py::dict metadetect_metrics(py::args args, py::kwargs kwargs) {
  const Arguments a("metadetect_metrics", args, kwargs,
                    {{"table", true}, {"minus"}, {"rotated"}, {"rotated_minus"}, {"shear"}, {"cut_snr"},
                     {"cut_t_ratio"}, {"cut_mfrac"}, {"bootstrap"}, {"seed"}, {"estimator"}});
  app::MetadetectMetricsOptions o;
  o.table = a.text("table");
  o.minus = a.text("minus");
  o.rotated = a.text("rotated");
  o.rotated_minus = a.text("rotated_minus");
  if (a.given("shear")) {
    const DoubleArray g = as_float64(a.object("shear"), {1}, "shear");
    if (g.size() != 2) throw py::value_error(a.where("shear") + ": two numbers (g1, g2)");
    o.shear = std::array<double, 2>{g.data()[0], g.data()[1]};
  }
  if (a.given("cut_snr")) o.cut_snr = a.real("cut_snr", 0);
  if (a.given("cut_t_ratio")) o.cut_t_ratio = a.real("cut_t_ratio", 0);
  if (a.given("cut_mfrac")) o.cut_mfrac = a.real("cut_mfrac", 0);
  o.resamples = static_cast<int>(a.integer_in("bootstrap", 200, 2, 100000));
  o.seed = static_cast<std::uint64_t>(a.integer_in("seed", 1, 0, 1LL << 62));
  if (const std::string v = a.text("estimator", "composed"); !parse_metadetect_estimator(v, &o.estimator))
    throw py::value_error(a.where("estimator") + ": '" + v + "' must be composed or package");
  app::MetadetectMetrics r;
  {
    py::gil_scoped_release release;
    r = app::metadetect_metrics(o);
  }
  py::dict d;
  const MetadetectShear& s = r.shear;
  d["cells"] = s.cells, d["kept_noshear"] = s.kept_noshear;
  d["cut_snr"] = r.cuts.min_snr, d["cut_t_ratio"] = r.cuts.min_t_ratio, d["cut_mfrac"] = r.cuts.max_mfrac;
  d["R11"] = s.r11, d["R11_err"] = s.r11_err, d["R22"] = s.r22, d["R22_err"] = s.r22_err;
  d["g1"] = s.g1, d["g1_err"] = s.g1_err, d["g2"] = s.g2, d["g2_err"] = s.g2_err;
  if (r.has_bias) {
    const MetadetectBias& b = r.bias;
    d["shear"] = py::make_tuple(r.true_shear[0], r.true_shear[1]);
    d["pairs"] = b.pairs;
    d["estimator"] = metadetect_estimator_name(o.estimator);
    d["m1"] = b.m1, d["m1_err"] = b.m1_err, d["c2"] = b.c2, d["c2_err"] = b.c2_err;
    d["m2"] = b.m2, d["m2_err"] = b.m2_err, d["c1"] = b.c1, d["c1_err"] = b.c1_err;
  }
  return d;
}

py::object detect(py::args args, py::kwargs kwargs) {
  const Arguments a("detect", args, kwargs,
                    {{"image", true}, {"noise_sigma", true}, {"detector", false, true},
                     {"detect_threshold", false, true}, {"detect_min_area", false, true},
                     {"deblend_contrast", false, true}, {"deblend_thresholds", false, true},
                     {"filter_fwhm", false, true}, {"filter_size", false, true}, {"clean", false, true}});
  const DoubleArray image = as_float64(a.object("image"), {2}, "image");
  MetadetectOptions o;
  read_detection_options(a, &o.detection);
  if (std::string why; !o.IsValid(&why)) throw py::value_error("detect: " + why);
  const double sigma = a.real("noise_sigma", 0);
  const int w = static_cast<int>(image.shape(1)), h = static_cast<int>(image.shape(0));
  std::vector<float> pixels(image.data(), image.data() + image.size());
  std::vector<Detection> found;
  std::string error;
  bool ok = false;
  {
    py::gil_scoped_release release;
    if (o.detection.detector == DetectorKind::kSep) set_detection_pixel_stack(static_cast<long long>(w) * h);
    ObjectDetector detector(o.detection);
    ok = detector.detect(pixels, w, h, sigma, &found, &error);
  }
  if (!ok) throw py::value_error(a.where("image") + ": " + error);
  py::dict out;
  auto col = [&](const char* name, auto get) {
    using T = decltype(get(found[0]));
    py::array_t<T> c(static_cast<py::ssize_t>(found.size()));
    for (std::size_t i = 0; i < found.size(); ++i) c.mutable_data()[i] = get(found[i]);
    out[py::str(name)] = c;
  };
  col("x", [](const Detection& d) { return d.x; });
  col("y", [](const Detection& d) { return d.y; });
  col("flux", [](const Detection& d) { return d.flux; });
  col("isophotal_area", [](const Detection& d) { return d.isophotal_area; });
  col("xmin", [](const Detection& d) { return d.xmin; });
  col("xmax", [](const Detection& d) { return d.xmax; });
  col("ymin", [](const Detection& d) { return d.ymin; });
  col("ymax", [](const Detection& d) { return d.ymax; });
  col("sep_flags", [](const Detection& d) { return d.sep_flags; });
  return out;
}

}  // namespace

void bind_metadetect(py::module_& m) {
  m.def("detect", &detect, R"doc(detect(image, noise_sigma, *, detector="tree", detect_threshold=0.8,
           detect_min_area=4, deblend_contrast=1e-5, deblend_thresholds=32, filter_fwhm=3, filter_size=7,
           clean=True)

Source Extractor's detection of a 2-D image (background subtracted) whose noise has standard
deviation `noise_sigma`, as `stampede metadetect` detects each metacal image: the image filtered
with a Gaussian of filter_fwhm pixels, pixels above detect_threshold x noise_sigma, segments of at
least detect_min_area pixels deblended over deblend_thresholds levels, cleaned. `detector`: "tree"
(ours) or "sep" (SEP's library). Returns a dict of arrays: x, y (0-based pixels; the filtered
barycentre, a deblended child's of its core), flux and isophotal_area (unfiltered pixels),
xmin, xmax, ymin, ymax, sep_flags (1 deblended, 2 on the edge, 8 degenerate moments).
)doc");
  m.def("metadetect_metrics", &metadetect_metrics, R"doc(metadetect_metrics(table, minus=None, rotated=None,
           rotated_minus=None, shear=None, cut_snr=10, cut_t_ratio=1.2, cut_mfrac=0.1, bootstrap=200, seed=1,
           estimator="composed")

`stampede metrics --metadetect` as a dict: R11, R22, g1, g2 (with _err, bootstrap over cells) of
`table`; with `minus` (the same cells under the opposite shear) m1, c2, m2, c1 and their errors.
`rotated`/`rotated_minus`: the same cells' scenes turned by 90 degrees, joined to their cells.
`shear`: the true shear (g1, g2) of `table`, else its first input's G1, G2 keys.
`estimator`: "composed" (the response to the sky's shear, R / (1 - |g|^2)) or "package" (<e> / R).
)doc");
  m.def("metadetect", &metadetect, R"doc(metadetect(image, weight, psf, pixel_scale, bmask=None, threads=0, *,
           noise=None, ormask=None, mfrac=None, detect_bands=None, shear_bands=None, layout="table",
           cell_size=251, cell_buffer=34, step=0.01, reconvolution_psf="auto", psf_dilation=0, fixnoise=True,
           double_images=False, seed=20170101, measurement="wmom", weight_fwhm=0, recentre=False, detector="tree", detect_threshold=0.8,
           detect_min_area=4, deblend_contrast=1e-5, deblend_thresholds=32, filter_fwhm=3, filter_size=7,
           clean=True, stamp_size=32, box_min=33, box_max=255, per_object_metacal=False)

Metadetection (Sheldon et al. 2020) of one image as `stampede metadetect` does it: the image
(2-D, at least one cell) is cut into cells; each cell's five metacal images (noshear, 1p, 1m,
2p, 2m, fixnoise; made in single precision unless `double_images`) are detected anew (see detect()) and every detection is measured: `measurement` "wmom",
weighted moments under a round Gaussian weight of weight_fwhm arcsec (0: 1.2), or "pgauss", the
pre-PSF Gaussian moments under that weight (0: 2.0), or "gauss" / "exp" / "bd", a fit of that model
(one band; weight_fwhm then 0). `weight`: inverse variances (0 masks); `psf`: a
centred PSF image at the image's pixel scale; `pixel_scale`: arcsec per pixel; `bmask`: non-zero
masks (its bits are reported per detection); `ormask`: bits reported per detection, masking nothing;
`mfrac`: each pixel's masked fraction in [0, 1] (e.g. of a coadd's epochs), which each detection's
mfrac averages under its Gaussian (masked pixels counting 1; several bands: their mean);
`noise`: a realisation of the image's noise (a NOISE plane), fixnoise's field (else one
is drawn from the weight).
Several bands: image, weight, psf (and bmask, ormask, noise where given) each a list of 2-D arrays
or a 3-D array, band first, the bands of one size; `detect_bands`, `shear_bands`: the band indices
detection sums and the shapes come from (default every band); fluxes and S/N in every band.
Returns, with layout="table", a structured array with the METADETECT table's columns (shear_type a
string; x, y 0-based pixels of the image; several bands: flux_b0, snr_b0, ...), rows in cell order;
a cell that cannot be measured is one row with id -1 and flags 8. The rows equal `stampede
metadetect`'s for the same image and options. With layout="package", the reference metadetect
package's layout: {"noshear", "1p", "1m", "2p", "2m": structured array} with its column names
({m}_g, {m}_g_cov, {m}_s2n, {m}_T_ratio, sx_row, sx_col, mfrac, bmask, psfrec_g, ...; docs/survey_metadetect.md).
)doc");
}

}  // namespace stampede::python
