// The module's argument parsing; see arguments.hpp.
#include "arguments.hpp"

#include <climits>
#include <cstring>

namespace py = pybind11;

namespace stampede::python {

namespace {

std::string type_name(py::handle value) {
  const py::handle type = py::type::handle_of(value);
  const std::string module = py::str(type.attr("__module__")).cast<std::string>();
  const std::string name = py::str(type.attr("__qualname__")).cast<std::string>();
  return module == "builtins" ? name : module + "." + name;
}

bool is_bool(py::handle value) {
  if (py::isinstance<py::bool_>(value)) return true;
  const std::string t = type_name(value);
  return t == "numpy.bool_" || t == "numpy.bool";
}

std::string text_of(const std::string& where, py::handle value) {
  py::object v = py::reinterpret_borrow<py::object>(value);
  if (!py::isinstance<py::str>(v) && py::hasattr(v, "__fspath__")) v = py::module_::import("os").attr("fspath")(v);
  if (!py::isinstance<py::str>(v))
    throw py::type_error(where + " must be a str or a path (os.PathLike), not " + describe(value));
  const std::string s = v.cast<std::string>();
  if (s.find('\0') != std::string::npos) throw py::value_error(where + " holds a NUL byte: " + describe(value));
  return s;
}

}  // namespace

std::string describe(py::handle value) {
  const std::string type = type_name(value);
  if (py::hasattr(value, "shape") && py::hasattr(value, "dtype")) {
    std::string d = type + " " + py::str(value.attr("dtype")).cast<std::string>() + " " +
                    py::str(py::tuple(value.attr("shape"))).cast<std::string>();
    return d.size() > 80 ? d.substr(0, 77) + "..." : d;
  }
  std::string r;
  try {
    r = py::repr(value).cast<std::string>();
  } catch (const py::error_already_set&) {
    r = "<unprintable>";
  }
  if (r.size() > 60) r = r.substr(0, 57) + "...";
  return type + " " + r;
}

Arguments::Arguments(std::string function, const py::args& args, const py::kwargs& kwargs,
                     const std::vector<Parameter>& parameters)
    : function_(std::move(function)) {
  std::size_t positional = 0;
  for (const Parameter& p : parameters) {
    values_.emplace_back(p.name, py::none());
    if (!p.keyword_only) ++positional;
  }
  if (args.size() > positional)
    throw py::type_error(function_ + "() takes at most " + std::to_string(positional) + " positional argument" +
                         (positional == 1 ? "" : "s") + " (" + std::to_string(args.size()) + " given)");
  std::vector<bool> seen(values_.size(), false);
  for (std::size_t k = 0; k < args.size(); ++k) {
    values_[k].second = py::reinterpret_borrow<py::object>(args[k]);
    seen[k] = true;
  }
  for (auto item : kwargs) {
    const std::string key = py::str(item.first).cast<std::string>();
    std::size_t k = 0;
    while (k < values_.size() && key != values_[k].first) ++k;
    if (k == values_.size()) {
      std::string names;
      for (const auto& [name, v] : values_) names += (names.empty() ? "" : ", ") + std::string(name);
      throw py::type_error(function_ + "() got an unexpected keyword argument '" + key + "' (it takes " + names + ")");
    }
    if (seen[k]) throw py::type_error(function_ + "() got multiple values for argument '" + key + "'");
    values_[k].second = py::reinterpret_borrow<py::object>(item.second);
    seen[k] = true;
  }
  std::size_t k = 0;
  for (const Parameter& p : parameters) {
    if (p.required && !seen[k])
      throw py::type_error(function_ + "() missing required argument '" + std::string(p.name) + "'");
    ++k;
  }
}

py::object Arguments::object(const char* name) const {
  for (const auto& [n, v] : values_)
    if (std::strcmp(n, name) == 0) return v;
  throw std::logic_error(function_ + "(): no parameter " + name);  // a binding's own mistake
}

std::string Arguments::text(const char* name, const std::string& fallback) const {
  const py::object v = object(name);
  return v.is_none() ? fallback : text_of(where(name), v);
}

long long Arguments::integer(const char* name, long long fallback) const {
  const py::object v = object(name);
  if (v.is_none()) return fallback;
  if (is_bool(v) || !py::hasattr(v, "__index__"))
    throw py::type_error(where(name) + " must be an int, not " + describe(v));
  const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(v.ptr()));
  if (!index) throw py::error_already_set();
  int overflow = 0;
  const long long out = PyLong_AsLongLongAndOverflow(index.ptr(), &overflow);
  if (overflow != 0) throw py::value_error(where(name) + " = " + describe(v) + " is beyond the 64-bit integer range");
  if (out == -1 && PyErr_Occurred()) throw py::error_already_set();
  return out;
}

long long Arguments::integer_in(const char* name, long long fallback, long long lo, long long hi) const {
  const long long v = integer(name, fallback);
  if (v < lo || v > hi)
    throw py::value_error(where(name) + " = " + std::to_string(v) + ": must be in [" + std::to_string(lo) + ", " +
                          std::to_string(hi) + "]");
  return v;
}

double Arguments::real(const char* name, double fallback) const {
  const py::object v = object(name);
  if (v.is_none()) return fallback;
  if (is_bool(v) || py::isinstance<py::str>(v) || py::isinstance<py::bytes>(v) || !py::hasattr(v, "__float__"))
    throw py::type_error(where(name) + " must be a number, not " + describe(v));
  const double out = PyFloat_AsDouble(v.ptr());
  if (out == -1.0 && PyErr_Occurred()) throw py::error_already_set();
  return out;
}

bool Arguments::flag(const char* name, bool fallback) const {
  const py::object v = object(name);
  if (v.is_none()) return fallback;
  if (!is_bool(v)) throw py::type_error(where(name) + " must be True or False, not " + describe(v));
  return v.cast<bool>();
}

std::vector<std::string> Arguments::texts(const char* name) const {
  const py::object v = object(name);
  if (!py::isinstance<py::list>(v) && !py::isinstance<py::tuple>(v))
    throw py::type_error(where(name) + " must be a list of paths, not " + describe(v));
  std::vector<std::string> out;
  std::size_t k = 0;
  for (py::handle item : v) out.push_back(text_of(where(name) + "[" + std::to_string(k++) + "]", item));
  return out;
}

std::vector<std::string> Arguments::names(const char* name) const {
  const py::object v = object(name);
  if (!py::isinstance<py::list>(v) && !py::isinstance<py::tuple>(v))
    throw py::type_error(where(name) + " must be a list of str, not " + describe(v));
  std::vector<std::string> out;
  std::size_t k = 0;
  for (py::handle item : v) {
    const std::string at = where(name) + "[" + std::to_string(k++) + "]";
    if (!py::isinstance<py::str>(item)) throw py::type_error(at + " must be a str, not " + describe(item));
    out.push_back(item.cast<std::string>());
    if (out.back().find('\0') != std::string::npos) throw py::value_error(at + " holds a NUL byte: " + describe(item));
  }
  return out;
}

}  // namespace stampede::python
