// The module's own argument parsing. pybind11's overload dispatch answers a wrong type or keyword
// with "incompatible function arguments ... Invoked with: <every argument's repr>", naming no
// argument and printing whole stamp arrays; these functions take (*args, **kwargs) and parse them
// here, so that every error names the function, the argument and what it takes, and shows at most
// a short description of the value given.
#pragma once

#include <pybind11/pybind11.h>

#include <initializer_list>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace stampede::python {

struct Parameter {
  const char* name;
  bool required = false;
  bool keyword_only = false;
};

// A short description of a value for a message: its type and, for scalars and short strings, its
// repr ("str 'x'", "int 5"), for arrays their shape ("numpy.ndarray float64 (9, 9)"); never more
// than ~80 characters.
std::string describe(pybind11::handle value);

class Arguments {
 public:
  // Matches args and kwargs to `parameters` as Python would: TypeError (naming the function) for too
  // many positionals, an unknown or repeated keyword, or a missing required argument.
  Arguments(std::string function, const pybind11::args& args, const pybind11::kwargs& kwargs,
            std::initializer_list<Parameter> parameters)
      : Arguments(std::move(function), args, kwargs, std::vector<Parameter>(parameters)) {}
  // Parameters made at run time (a table's keywords); names must outlive the Arguments.
  Arguments(std::string function, const pybind11::args& args, const pybind11::kwargs& kwargs,
            const std::vector<Parameter>& parameters);

  // The value given for `name`, or None when it was not given.
  pybind11::object object(const char* name) const;
  bool given(const char* name) const { return !object(name).is_none(); }

  // Typed values; a missing or None argument gives `fallback` (for text: a str or os.PathLike;
  // for integer: an int or numpy integer, not bool; for real: an int or float, not bool; for flag:
  // a bool or numpy.bool_). TypeError for another type, ValueError for an integer beyond int64 or
  // text holding a NUL byte.
  std::string text(const char* name, const std::string& fallback = "") const;
  long long integer(const char* name, long long fallback) const;
  // integer() within [lo, hi], else ValueError naming the argument and the range.
  long long integer_in(const char* name, long long fallback, long long lo, long long hi) const;
  double real(const char* name, double fallback) const;
  bool flag(const char* name, bool fallback) const;
  // A list or tuple of str / os.PathLike.
  std::vector<std::string> texts(const char* name) const;
  // A list or tuple of str (column names, keys; a bare str is refused, not read as its letters).
  std::vector<std::string> names(const char* name) const;

  // "function(): name" for a message about the argument; for the parts of one argument (a
  // function named "run_fit(): shard"), "run_fit(): shard: i".
  std::string where(const char* name) const {
    return function_ + (function_.find('(') == std::string::npos ? "(): " : ": ") + name;
  }

 private:
  std::string function_;
  std::vector<std::pair<const char*, pybind11::object>> values_;
};

}  // namespace stampede::python
