// stampede.Options; see options.hpp.
#include "options.hpp"

#include <string>

#include "arguments.hpp"
#include "errors.hpp"

namespace py = pybind11;

namespace stampede::python {

namespace {

// A Python value as the ini file would spell it: bools as true/false, floats at full precision
// (repr is the shortest text that round-trips), None refused; everything else by str().
std::string option_text(const std::string& key, py::handle value) {
  if (value.is_none()) throw io::ConfigError("option '" + key + "' = None: give a value (or leave the key out)");
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::float_>(value)) return py::repr(value).cast<std::string>();
  // Numbers (Python's or numpy scalars) and strings; not containers or arrays, whose str() would be
  // parsed as the value and echoed whole in the error.
  const bool number = py::hasattr(value, "__index__") || py::hasattr(value, "__float__");
  const bool scalar = !py::hasattr(value, "shape") || py::len(value.attr("shape")) == 0;
  if (!(py::isinstance<py::str>(value) || (number && scalar)))
    throw py::type_error("option '" + key + "' must be a number, bool or str, not " + describe(value));
  if (py::hasattr(value, "dtype") && value.attr("dtype").attr("kind").cast<std::string>() == "f")
    return py::repr(py::float_(py::reinterpret_borrow<py::object>(value))).cast<std::string>();
  return py::str(value).cast<std::string>();
}

void set_from(app::RunConfig& cfg, py::handle mapping) {
  for (auto item : py::reinterpret_borrow<py::dict>(mapping)) {
    if (!py::isinstance<py::str>(item.first))
      throw py::type_error("option names are strings, not " + describe(item.first));
    const std::string key = item.first.cast<std::string>();
    app::set_option(cfg, key, option_text(key, item.second));
  }
}

}  // namespace

app::RunConfig config_from(py::handle obj) {
  if (obj.is_none()) return app::RunConfig{};
  if (py::isinstance<app::RunConfig>(obj)) return obj.cast<app::RunConfig>();
  if (py::isinstance<py::dict>(obj)) {
    app::RunConfig cfg;
    set_from(cfg, obj);
    app::validate(cfg);
    return cfg;
  }
  throw py::type_error("options must be a stampede.Options or a dict of option: value, not " +
                       py::str(obj.get_type().attr("__name__")).cast<std::string>());
}

void bind_options(py::module_& m) {
  py::class_<app::RunConfig>(m, "Options", R"doc(
A run configuration: every key of `stampede fit --help-config`, with the same names, values and
validation. Options(dict) or Options(key=value, ...); values may be Python numbers, bools or
strings. A bad key or value raises stampede.ConfigError (a ValueError) naming the key, value and rule.

    opts = stampede.Options(renderer="exact", psf_fwhm=2.85, psf_e2=0.05)
    opts["psf_fwhm"]      # '2.85': the canonical text, as in the output header
)doc")
      .def(py::init([](py::args args, py::kwargs kwargs) {
             // Options(mapping=None, **options): `options=` names the mapping too (no option has that name).
             py::kwargs options = kwargs;
             py::object mapping = py::none();
             if (args.size() > 1)
               throw py::type_error("Options() takes one dict of option: value, then option keywords (" +
                                    std::to_string(args.size()) + " positional arguments given)");
             if (args.size() == 1) mapping = args[0];
             if (options.contains("options")) {
               if (args.size() == 1) throw py::type_error("Options() got the dict twice (positional and options=)");
               mapping = options["options"];
               PyDict_DelItemString(options.ptr(), "options");
             }
             app::RunConfig cfg;
             if (!mapping.is_none()) {
               if (!py::isinstance<py::dict>(mapping))
                 throw py::type_error("Options() takes a dict of option: value (or keywords), not " + describe(mapping));
               set_from(cfg, mapping);
             }
             set_from(cfg, options);
             app::validate(cfg);
             return cfg;
           }),
           "Options(mapping=None, **options)")
      .def_static(
          "from_ini",
          [](py::args args, py::kwargs kwargs) {
            // from_ini(path, **overrides): the path is positional, every keyword an option.
            if (args.size() != 1)
              throw py::type_error("Options.from_ini() takes the ini file's path, then option keywords (" +
                                   std::to_string(args.size()) + " positional arguments given)");
            const py::kwargs overrides = kwargs;
            const py::kwargs none;
            const std::string path = Arguments("Options.from_ini", args, none, {{"path", true}}).text("path");
            app::RunConfig cfg;
            app::load_ini(cfg, path);
            set_from(cfg, overrides);
            app::validate(cfg);
            return cfg;
          },
          "from_ini(path, **overrides)\n\nReads an ini file (as `stampede fit --config`), then any keyword overrides.")
      .def("__getitem__",
           [](const app::RunConfig& c, py::handle key) {
             if (!py::isinstance<py::str>(key))
               throw py::type_error("Options[key]: option names are strings, not " + describe(key));
             return app::get_option(c, key.cast<std::string>());
           })
      .def("__contains__",
           [](const app::RunConfig&, py::handle key) {
             if (!py::isinstance<py::str>(key)) return false;
             const std::string name = key.cast<std::string>();
             for (const io::OptionInfo& o : app::run_config_options())
               if (o.name == name) return true;
             return false;
           })
      .def(
          "to_dict",
          [](const app::RunConfig& c) {
            py::dict out;
            for (const auto& [k, v] : app::effective_options(c)) out[py::str(k)] = v;
            return out;
          },
          "Every key with its value's canonical text, in documentation order.")
      .def(
          "explicitly_set", [](const app::RunConfig& c) {
            py::list out;
            for (const auto& [k, where] : c.explicitly_set) out.append(k);
            return out;
          },
          "The keys given explicitly (the rest are defaults).")
      .def(
          "replace",
          [](const app::RunConfig& c, py::kwargs changes) {
            app::RunConfig out = c;
            set_from(out, changes);
            app::validate(out);
            return out;
          },
          "A copy with the given keys changed, validated.")
      .def("__repr__", [](const app::RunConfig& c) {
        std::string s = "stampede.Options(";
        bool first = true;
        for (const auto& [k, where] : c.explicitly_set) {
          s += (first ? "" : ", ") + k + "=" + py::repr(py::str(app::get_option(c, k))).cast<std::string>();
          first = false;
        }
        return s + ")";
      });

  m.def(
      "option_help",
      [] {
        py::dict out;
        for (const io::OptionInfo& o : app::run_config_options())
          out[py::str(o.name)] = py::make_tuple(o.default_value, o.help);
        return out;
      },
      "{key: (default, help)} for every option.");
}

}  // namespace stampede::python
