// numpy conversions; see numpy_arrays.hpp.
#include "numpy_arrays.hpp"

#include <cmath>
#include <cstring>

namespace py = pybind11;

namespace stampede::python {

DoubleArray as_float64(py::handle obj, std::initializer_list<int> ndims, const char* what) {
  py::array a = py::array::ensure(obj);
  if (!a) a = py::module_::import("numpy").attr("asarray")(obj);  // raises for what numpy cannot take
  const char kind = a.dtype().kind();
  if (kind != 'f') {
    throw py::type_error(std::string(what) + " must hold floating-point values, not dtype " +
                         py::str(a.dtype()).cast<std::string>());
  }
  bool ndim_ok = false;
  std::string allowed;
  for (int n : ndims) {
    ndim_ok = ndim_ok || a.ndim() == n;
    allowed += (allowed.empty() ? "" : " or ") + std::to_string(n) + "-D";
  }
  if (!ndim_ok) {
    throw py::value_error(std::string(what) + " must be a " + allowed + " array, not " + std::to_string(a.ndim()) +
                          "-D (shape " + py::str(py::tuple(a.attr("shape"))).cast<std::string>() + ")");
  }
  if (a.size() == 0) throw py::value_error(std::string(what) + " is empty");
  // A no-op for C-contiguous float64; one converting copy otherwise. Some dtypes (longdouble) are
  // not converted by ensure(): numpy's own astype does it, and a failed conversion is an exception.
  if (!a.dtype().is(py::dtype::of<double>())) a = a.attr("astype")("float64");
  DoubleArray out = DoubleArray::ensure(a);
  if (!out) {
    PyErr_Clear();
    throw py::type_error(std::string(what) + ": dtype " + py::str(a.dtype()).cast<std::string>() +
                         " could not be converted to float64");
  }
  return out;
}

std::vector<long long> integer_values(py::handle obj, const std::string& what, long long lo, long long hi,
                                      bool booleans) {
  py::array a = py::array::ensure(obj);
  if (!a) a = py::module_::import("numpy").attr("asarray")(obj);
  const char kind = a.dtype().kind();
  const std::string dtype = py::str(a.dtype()).cast<std::string>();
  if (a.ndim() != 1)
    throw py::value_error(what + " must be a 1-D array, not " + std::to_string(a.ndim()) + "-D");
  if (kind == 'b' && !booleans)
    throw py::type_error(what + " must hold integers " + std::to_string(lo) + ".." + std::to_string(hi) +
                         ", not booleans");
  if (kind != 'b' && kind != 'i' && kind != 'u' && kind != 'f')
    throw py::type_error(what + " must hold integers, not dtype " + dtype);
  // Floats are checked as float64 (whole numbers, the bounds' side) and never cast before that (a
  // cast of NaN is undefined); integers and booleans are read as int64, which holds them exactly
  // (a uint64 beyond it is caught by its float64 value).
  const bool floating = kind == 'f';
  const auto real = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  py::array_t<long long, py::array::c_style | py::array::forcecast> exact;
  if (!floating) exact = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!real || (!floating && !exact)) {
    PyErr_Clear();
    throw py::type_error(what + ": dtype " + dtype + " could not be read as integers");
  }
  std::vector<long long> out(static_cast<std::size_t>(a.size()));
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    const double v = real.data()[i];
    auto at = [&] { return what + "[" + std::to_string(i) + "] = " + py::str(a.attr("item")(i)).cast<std::string>(); };
    if (floating && !(std::isfinite(v) && v == std::trunc(v)))
      throw py::value_error(at() + ": not a whole number");
    // The bounds on the double first: a value beyond int64 is refused before any conversion.
    if (v < static_cast<double>(lo) || v > static_cast<double>(hi) ||
        (!floating && (exact.data()[i] < lo || exact.data()[i] > hi)))
      throw py::value_error(at() + ": must be " + (booleans && lo == 0 && hi == 1 ? "0 or 1 (or a boolean)"
                                                                                 : std::to_string(lo) + ".." + std::to_string(hi)));
    out[static_cast<std::size_t>(i)] = floating ? static_cast<long long>(v) : exact.data()[i];
  }
  return out;
}

py::dtype result_dtype(io::PositionColumns positions, bool metacal, const std::vector<std::string>& bands) {
  py::list fields;
  const io::ResultSchema schema(positions, metacal, bands);
  for (const io::ResultColumn& c : schema.columns()) {
    const char* format = "<f8";
    switch (c.type) {
      case io::ColumnType::kInt64: format = "<i8"; break;
      case io::ColumnType::kInt32: format = "<i4"; break;
      case io::ColumnType::kUInt32: format = "<u4"; break;
      case io::ColumnType::kFloat64: format = "<f8"; break;
    }
    fields.append(py::make_tuple(c.name, format));
  }
  return py::dtype::from_args(fields);
}

py::array result_array(const std::vector<ObjectRecord>& rows, io::PositionColumns positions, bool metacal,
                       const std::vector<std::string>& bands) {
  const py::dtype dt = result_dtype(positions, metacal, bands);
  py::array out(dt, std::vector<py::ssize_t>{static_cast<py::ssize_t>(rows.size())});
  const py::dict fields = dt.attr("fields");
  const io::ResultSchema schema(positions, metacal, bands);
  const auto cols = schema.columns();
  std::vector<py::ssize_t> offsets;
  for (const io::ResultColumn& c : cols) offsets.push_back(fields[c.name].cast<py::tuple>()[1].cast<py::ssize_t>());
  char* base = static_cast<char*>(out.mutable_data());
  const py::ssize_t stride = dt.itemsize();
  for (std::size_t i = 0; i < rows.size(); ++i) {
    char* row = base + static_cast<py::ssize_t>(i) * stride;
    for (std::size_t j = 0; j < cols.size(); ++j) {
      const io::ResultColumn& c = cols[j];
      char* at = row + offsets[j];
      switch (c.type) {
        case io::ColumnType::kInt64: {
          const std::int64_t v = c.integer(rows[i]);
          std::memcpy(at, &v, sizeof v);
          break;
        }
        case io::ColumnType::kInt32: {
          const auto v = static_cast<std::int32_t>(c.integer(rows[i]));
          std::memcpy(at, &v, sizeof v);
          break;
        }
        case io::ColumnType::kUInt32: {
          const auto v = static_cast<std::uint32_t>(c.integer(rows[i]));
          std::memcpy(at, &v, sizeof v);
          break;
        }
        case io::ColumnType::kFloat64: {
          const double v = c.real(rows[i]);
          std::memcpy(at, &v, sizeof v);
          break;
        }
      }
    }
  }
  return out;
}

py::dict result_dict(const ObjectRecord& row, io::PositionColumns positions, bool metacal) {
  py::dict out;
  for (const io::ResultColumn& c : io::result_columns(positions, metacal)) {
    if (c.type == io::ColumnType::kFloat64) {
      out[c.name] = c.real(row);
    } else {
      out[c.name] = c.integer(row);
    }
  }
  return out;
}

}  // namespace stampede::python
