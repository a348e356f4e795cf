// stampede.simulate_great08, set_shear and shear_metrics: the simulator and the metrics of
// `stampede sim` and `stampede metrics`, returning numpy arrays and dicts.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <climits>
#include <cstring>
#include <string>
#include <vector>

#include "engine/analysis/metacal_shear.hpp"
#include "engine/analysis/shear_metrics.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/sim/great08_sim.hpp"
#include "arguments.hpp"
#include "numpy_arrays.hpp"

namespace py = pybind11;

namespace stampede::python {

namespace {

struct IntField {
  const char* name;
  long long SimObjectTruth::*member;
};
struct RealField {
  const char* name;
  double SimObjectTruth::*member;
};
// The truth table's columns, named as in the GalSim sets' truth files.
constexpr IntField kIntFields[] = {
    {"index", &SimObjectTruth::index}, {"ix", &SimObjectTruth::ix}, {"iy", &SimObjectTruth::iy},
    {"pair", &SimObjectTruth::pair}};
constexpr RealField kRealFields[] = {
    {"x_centre", &SimObjectTruth::x_centre}, {"y_centre", &SimObjectTruth::y_centre},
    {"x_image", &SimObjectTruth::x_image},   {"y_image", &SimObjectTruth::y_image},
    {"e1_int", &SimObjectTruth::e1_int},     {"e2_int", &SimObjectTruth::e2_int},
    {"g1", &SimObjectTruth::g1},             {"g2", &SimObjectTruth::g2},
    {"e1_obs", &SimObjectTruth::e1_obs},     {"e2_obs", &SimObjectTruth::e2_obs},
    {"hlr", &SimObjectTruth::hlr},           {"bulge_frac", &SimObjectTruth::bulge_frac},
    {"flux", &SimObjectTruth::flux},         {"bulge_flux", &SimObjectTruth::bulge_flux},
    {"disc_flux", &SimObjectTruth::disc_flux}, {"stamp_flux", &SimObjectTruth::stamp_flux},
    {"snr", &SimObjectTruth::snr},           {"hlr_bulge", &SimObjectTruth::hlr_bulge},
    {"e1_int_bulge", &SimObjectTruth::e1_int_bulge}, {"e2_int_bulge", &SimObjectTruth::e2_int_bulge},
    {"bulge_dx", &SimObjectTruth::bulge_dx}, {"bulge_dy", &SimObjectTruth::bulge_dy}};

py::array truth_array(const std::vector<SimObjectTruth>& truth) {
  py::list fields;
  for (const IntField& f : kIntFields) fields.append(py::make_tuple(f.name, "<i8"));
  for (const RealField& f : kRealFields) fields.append(py::make_tuple(f.name, "<f8"));
  const py::dtype dt = py::dtype::from_args(fields);
  py::array out(dt, std::vector<py::ssize_t>{static_cast<py::ssize_t>(truth.size())});
  char* base = static_cast<char*>(out.mutable_data());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    char* at = base + static_cast<py::ssize_t>(i) * dt.itemsize();  // packed: fields in order
    for (const IntField& f : kIntFields) {
      const std::int64_t v = truth[i].*f.member;
      std::memcpy(at, &v, sizeof v);
      at += sizeof v;
    }
    for (const RealField& f : kRealFields) {
      const double v = truth[i].*f.member;
      std::memcpy(at, &v, sizeof v);
      at += sizeof v;
    }
  }
  return out;
}

py::array_t<double> image_array(const std::vector<double>& v, std::vector<py::ssize_t> shape) {
  py::array_t<double> out(shape);
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

py::dict simulate(int set, int grid, int stamp_size, double snr, double noise_sigma, bool noise_free,
                  bool noise_pairs, double size_ratio, const std::string& galaxy_type, double e_sigma, double e_max,
                  double shear_max, double centre_offset, double psf_fwhm, double psf_beta, double psf_e1,
                  double psf_e2, std::uint64_t seed) {
  if (set < 0) throw py::value_error("set = " + std::to_string(set) + ": must be >= 0");
  Great08SimOptions o;
  o.sets = set + 1;
  o.grid = grid;
  o.stamp_size = stamp_size;
  o.snr = snr;
  o.noise_sigma = noise_sigma;
  o.noise_free = noise_free;
  o.noise_pairs = noise_pairs;
  o.size_ratio = size_ratio;
  if (!parse_sim_galaxy_type(galaxy_type, &o.galaxy_type))
    throw py::value_error("galaxy_type = '" + galaxy_type + "': must be bd, b+d, bulge or disc");
  o.e_sigma = e_sigma;
  o.e_max = e_max;
  o.shear_max = shear_max;
  o.centre_offset = centre_offset;
  kernels::MoffatProfile m = Great08SimOptions::default_psf().moffat;
  m.fwhm = psf_fwhm;
  m.beta = psf_beta;
  m.e1 = psf_e1;
  m.e2 = psf_e2;
  o.psf = PsfModel::Moffat(m);
  o.seed = seed;
  std::string why;
  if (!o.IsValid(&why)) throw py::value_error(why);
  SimSet s;
  std::vector<double> psf;
  {
    py::gil_scoped_release release;
    const Great08Simulator sim(o);
    s = sim.simulate_set(set);
    psf = sim.psf_image();
  }
  const py::ssize_t n = static_cast<py::ssize_t>(grid) * grid, ss = stamp_size;
  std::vector<double> stamps(static_cast<std::size_t>(n * ss * ss));
  for (py::ssize_t k = 0; k < n; ++k) {
    const py::ssize_t ix = k % grid, iy = k / grid;
    for (py::ssize_t y = 0; y < ss; ++y)
      std::copy_n(s.image.data() + (iy * ss + y) * s.width + ix * ss, ss, stamps.data() + (k * ss + y) * ss);
  }
  py::dict out;
  out["image"] = image_array(s.image, {s.width, s.width});
  out["stamps"] = image_array(stamps, {n, ss, ss});
  out["truth"] = truth_array(s.truth);
  out["g1"] = s.shear1;
  out["g2"] = s.shear2;
  out["noise_seed"] = s.noise_seed;
  out["psf_image"] = image_array(psf, {ss, ss});
  return out;
}

// Ring-pair labels are any integers of this size (|label| < 2^62: exact as a float64 too).
constexpr long long kMaxPairLabel = 1LL << 62;

py::dict set_shear_dict(const SetShear& s) {
  py::dict d;
  d["g1_true"] = s.g1_true;
  d["g2_true"] = s.g2_true;
  d["g1"] = s.g1;
  d["g2"] = s.g2;
  d["err1"] = s.err1;
  d["err2"] = s.err2;
  d["used"] = s.used;
  d["excluded"] = s.excluded;
  d["units"] = s.units;
  return d;
}

}  // namespace

void bind_sim(py::module_& m) {
  m.def(
      "simulate_great08",
      [](py::args args, py::kwargs kwargs) {
        const Arguments a("simulate_great08", args, kwargs,
                          {{"set"}, {"grid", false, true}, {"stamp_size", false, true}, {"snr", false, true},
                           {"noise_sigma", false, true}, {"noise_free", false, true}, {"noise_pairs", false, true},
                           {"size_ratio", false, true}, {"galaxy_type", false, true}, {"e_sigma", false, true},
                           {"e_max", false, true}, {"shear_max", false, true}, {"centre_offset", false, true},
                           {"psf_fwhm", false, true}, {"psf_beta", false, true}, {"psf_e1", false, true},
                           {"psf_e2", false, true}, {"seed", false, true}});
        return simulate(static_cast<int>(a.integer_in("set", 0, 0, INT_MAX - 1)),
                        static_cast<int>(a.integer_in("grid", 20, 1, 100000)),
                        static_cast<int>(a.integer_in("stamp_size", 39, 1, 100000)), a.real("snr", 40.0),
                        a.real("noise_sigma", 1.0), a.flag("noise_free", false), a.flag("noise_pairs", false),
                        a.real("size_ratio", 1.4), a.text("galaxy_type", "bd"), a.real("e_sigma", 0.25),
                        a.real("e_max", 0.9), a.real("shear_max", 0.05), a.real("centre_offset", 0.5),
                        a.real("psf_fwhm", 2.85), a.real("psf_beta", 3.0), a.real("psf_e1", 0.0),
                        a.real("psf_e2", 0.05), static_cast<std::uint64_t>(a.integer_in("seed", 7, 0, LLONG_MAX)));
      },
      R"doc(simulate_great08(set=0, *, grid=20, stamp_size=39, snr=40.0, noise_sigma=1.0, noise_free=False,
        noise_pairs=False, size_ratio=1.4, galaxy_type="bd", e_sigma=0.25, e_max=0.9, shear_max=0.05,
        centre_offset=0.5, psf_fwhm=2.85, psf_beta=3.0, psf_e1=0.0, psf_e2=0.05, seed=7)

Draws set `set` of a GREAT08-like simulation, as `stampede sim great08` (same seed, same pixels):
a grid x grid grid of stamps sharing one shear, ring pairs 2m, 2m+1, every galaxy at S/N `snr`.
Returns {'image': 2-D array, 'stamps': (grid^2, S, S) in grid order, 'truth': structured array
(the truth table's columns), 'g1', 'g2', 'noise_seed', 'psf_image': the PSF x pixel, S x S}.
)doc");

  m.def(
      "set_shear",
      [](py::args args, py::kwargs kwargs) {
        const Arguments in("set_shear", args, kwargs,
                           {{"e1", true}, {"e2", true}, {"usable", true}, {"pair", true}, {"g1_true", true},
                            {"g2_true", true}, {"bootstrap"}, {"seed"}});
        const py::object e1 = in.object("e1"), e2 = in.object("e2"), usable = in.object("usable"),
                         pair = in.object("pair");
        const double g1_true = in.real("g1_true", 0), g2_true = in.real("g2_true", 0);
        const int bootstrap = static_cast<int>(in.integer_in("bootstrap", 200, 1, 1000000));
        const auto seed = static_cast<std::uint64_t>(in.integer_in("seed", 1, 0, LLONG_MAX));
        const DoubleArray a = as_float64(e1, {1}, "e1"), b = as_float64(e2, {1}, "e2");
        const std::vector<long long> u = integer_values(usable, "set_shear(): usable", 0, 1, true);
        const std::vector<long long> p = integer_values(pair, "set_shear(): pair", -kMaxPairLabel, kMaxPairLabel, false);
        if (b.size() != a.size() || static_cast<py::ssize_t>(u.size()) != a.size() ||
            static_cast<py::ssize_t>(p.size()) != a.size())
          throw py::value_error("e1, e2, usable and pair must have one value per object");
        const std::vector<int> usable_int(u.begin(), u.end());
        const SetShear s = estimate_set_shear(values(a), values(b), usable_int, p, g1_true, g2_true, bootstrap, seed);
        return set_shear_dict(s);
      },
      "set_shear(e1, e2, usable, pair, g1_true, g2_true, bootstrap=200, seed=1)\n\nOne set's shear estimate (ring pairs averaged first; bootstrap errors), as `stampede metrics` per set.\n"
      "usable: 0/1 or booleans per object; pair: integer ring-pair labels (-1: none); a value that is not a whole\n"
      "number (0.9, NaN) or out of range is refused, never truncated. err1, err2 are NaN when they cannot be\n"
      "computed: fewer than two usable ring pairs ('units' in the dict) or bootstrap < 2.");

  m.def(
      "metacal_set_shear",
      [](py::args args, py::kwargs kwargs) {
        const Arguments in("metacal_set_shear", args, kwargs,
                           {{"e1", true}, {"e2", true}, {"r11", true}, {"r12", true}, {"r21", true}, {"r22", true},
                            {"selected", true}, {"pair", true}, {"g1_true", true}, {"g2_true", true}, {"step"},
                            {"bootstrap"}, {"seed"}});
        const double g1_true = in.real("g1_true", 0), g2_true = in.real("g2_true", 0), step = in.real("step", 0.01);
        const int bootstrap = static_cast<int>(in.integer_in("bootstrap", 200, 1, 1000000));
        const auto seed = static_cast<std::uint64_t>(in.integer_in("seed", 1, 0, LLONG_MAX));
        if (!(step > 0)) throw py::value_error("metacal_set_shear(): step must be positive");
        const DoubleArray e1 = as_float64(in.object("e1"), {1}, "e1"), e2 = as_float64(in.object("e2"), {1}, "e2");
        const DoubleArray r11 = as_float64(in.object("r11"), {1}, "r11"), r12 = as_float64(in.object("r12"), {1}, "r12");
        const DoubleArray r21 = as_float64(in.object("r21"), {1}, "r21"), r22 = as_float64(in.object("r22"), {1}, "r22");
        // A bit field, so booleans are refused: True would be bit 0 alone (selected on the noshear
        // image only), leaving the sheared selections empty.
        const std::vector<long long> selected = integer_values(in.object("selected"), "metacal_set_shear(): selected",
                                                               0, 0x1f, false);
        const std::vector<long long> p =
            integer_values(in.object("pair"), "metacal_set_shear(): pair", -kMaxPairLabel, kMaxPairLabel, false);
        const auto n = e1.size();
        for (const DoubleArray* a : {&e2, &r11, &r12, &r21, &r22})
          if (a->size() != n) throw py::value_error("e1, e2, r11, r12, r21, r22, selected and pair must have one value per object");
        if (static_cast<py::ssize_t>(selected.size()) != n || static_cast<py::ssize_t>(p.size()) != n)
          throw py::value_error("e1, e2, r11, r12, r21, r22, selected and pair must have one value per object");
        const std::vector<std::uint8_t> sel(selected.begin(), selected.end());
        const MetacalRows rows{values(e1), values(e2), {values(r11), values(r12), values(r21), values(r22)}, sel, p,
                               step};
        const MetacalSetShear m = estimate_metacal_set_shear(rows, g1_true, g2_true, bootstrap, seed);
        py::dict d = set_shear_dict(m.shear);
        d["R"] = py::make_tuple(m.r[0], m.r[1], m.r[2], m.r[3]);
        d["R_S"] = py::make_tuple(m.r_sel[0], m.r_sel[1], m.r_sel[2], m.r_sel[3]);
        py::dict selected_units;
        for (int k = 0; k < 5; ++k) selected_units[kMetacalSelectionNames[k]] = m.selected_units[k];
        d["selected_units"] = selected_units;
        d["g1_raw"] = m.g1_raw;
        d["g2_raw"] = m.g2_raw;
        return d;
      },
      "metacal_set_shear(e1, e2, r11, r12, r21, r22, selected, pair, g1_true, g2_true, step=0.01, bootstrap=200, seed=1)\n\n"
      "One set's metacalibrated shear, as `stampede metrics --metacal` per set: g = (<R> + R_S)^-1 <e>, ring pairs\n"
      "averaged first, bootstrap errors. selected: per object, bit 0 passes the selection on the noshear\n"
      "quantities, bits 1-4 on the 1p 1m 2p 2m images' (0x1f for every usable object without cuts; 0 excludes):\n"
      "integers 0..31 (booleans, fractions, NaN and values out of range are refused). Returns set_shear()'s dict with\n"
      "'R' and 'R_S' (R11 R12 R21 R22), 'g1_raw', 'g2_raw' and 'selected_units' (ring pairs passing each selection,\n"
      "by name: noshear 1p 1m 2p 2m; one at 0 leaves g, R and R_S NaN).");
  // The flags that exclude a row from every shear estimate (`stampede metrics`' rule).
  m.attr("shear_excluding_flags") = static_cast<unsigned long long>(kShearExcludingFlags);

  m.def(
      "shear_metrics",
      [](py::args args, py::kwargs kwargs) {
        const Arguments a("shear_metrics", args, kwargs, {{"sets", true}, {"psf_e1"}, {"psf_e2"}});
        const double psf_e1 = a.real("psf_e1", 0.0), psf_e2 = a.real("psf_e2", 0.0);
        const py::object sets = a.object("sets");
        if (!py::isinstance<py::list>(sets) && !py::isinstance<py::tuple>(sets))
          throw py::type_error("shear_metrics(): sets must be a list of set_shear() dicts, not " + describe(sets));
        std::vector<SetShear> in;
        for (py::handle item : sets) {
          const std::string where = "shear_metrics(): sets[" + std::to_string(in.size()) + "]";
          if (!py::isinstance<py::dict>(item))
            throw py::type_error(where + " must be a set_shear() dict, not " + describe(item));
          const py::dict d = py::reinterpret_borrow<py::dict>(item);
          py::args none;
          py::kwargs fields;
          for (const char* key : {"g1_true", "g2_true", "g1", "g2", "err1", "err2", "used", "excluded"})
            if (d.contains(key)) fields[key] = d[key];
          for (const char* key : {"g1_true", "g2_true", "g1", "g2", "err1", "err2"})
            if (!d.contains(key)) throw py::value_error(where + " has no '" + std::string(key) + "'");
          const Arguments f(where, none, fields,
                            {{"g1_true"}, {"g2_true"}, {"g1"}, {"g2"}, {"err1"}, {"err2"}, {"used"}, {"excluded"}});
          SetShear s;
          s.g1_true = f.real("g1_true", 0);
          s.g2_true = f.real("g2_true", 0);
          s.g1 = f.real("g1", 0);
          s.g2 = f.real("g2", 0);
          s.err1 = f.real("err1", 0);
          s.err2 = f.real("err2", 0);
          s.used = f.integer("used", 0);
          s.excluded = f.integer("excluded", 0);
          in.push_back(s);
        }
        if (in.size() < 2) throw py::value_error("shear_metrics needs at least two sets (a line through the shears)");
        const ShearMetrics r = combine_sets(std::move(in), psf_e1, psf_e2);
        py::dict out;
        for (int c = 0; c < 2; ++c) {
          const std::string k = std::to_string(c + 1);
          out[py::str("m" + k)] = r.component[c].m;
          out[py::str("m" + k + "_err")] = r.component[c].m_err;
          out[py::str("c" + k)] = r.component[c].c;
          out[py::str("c" + k + "_err")] = r.component[c].c_err;
        }
        out["c_plus"] = r.c_plus;
        out["c_cross"] = r.c_cross;
        out["q"] = r.q;
        return out;
      },
      "shear_metrics(sets, psf_e1=0.0, psf_e2=0.0)\n\nm and c per component, c in the PSF frame and the GREAT08 Q from set_shear() dicts, as `stampede metrics`.");
}

}  // namespace stampede::python
