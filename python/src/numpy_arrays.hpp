// numpy at the module's boundary: input arrays checked and viewed as C-contiguous float64 (zero
// copy when they already are; other float dtypes and strides converted once), and result rows
// turned into a structured array with exactly the FITS table's columns.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <span>
#include <string>
#include <vector>

#include "engine/pipeline/object_record.hpp"
#include "io/result_columns.hpp"

namespace stampede::python {

using DoubleArray = pybind11::array_t<double, pybind11::array::c_style>;

// `obj` (an array or anything numpy.asarray takes, e.g. a GalSim Image's .array) as a C-contiguous
// float64 array of `ndim` dimensions (any of `ndims` when several are allowed). Raises TypeError
// for a dtype that is not floating point (int, bool, complex, object, strings) and ValueError for
// the wrong number of dimensions or an empty array; `what` names the argument in the message.
DoubleArray as_float64(pybind11::handle obj, std::initializer_list<int> ndims, const char* what);

// `obj` (a 1-D array or sequence) as integers, each in [lo, hi]: integer dtypes, floats only where
// every value is a whole number (so 0.9 is refused, not truncated to 0, and NaN is refused), and
// booleans (as 0 and 1) only when `booleans`. Never converted modulo the type's range (256 is not
// 0, -1 not 255). Raises TypeError for another dtype and ValueError naming `what`, the index and
// the value otherwise.
std::vector<long long> integer_values(pybind11::handle obj, const std::string& what, long long lo, long long hi,
                                      bool booleans);

inline std::span<const double> values(const DoubleArray& a) {
  return {a.data(), static_cast<std::size_t>(a.size())};
}

// The numpy dtype of a result table with `positions` (field names as TTYPEn; int64, int32, uint32
// and float64 as TFORM K, J, V and D).
// A multi-band table's `bands` add their columns (io::ResultSchema).
pybind11::dtype result_dtype(io::PositionColumns positions, bool metacal = false,
                             const std::vector<std::string>& bands = {});
// Rows as a structured array of result_dtype(positions, metacal, bands).
pybind11::array result_array(const std::vector<ObjectRecord>& rows, io::PositionColumns positions,
                             bool metacal = false, const std::vector<std::string>& bands = {});
// One row as a dict {column: Python int or float}.
pybind11::dict result_dict(const ObjectRecord& row, io::PositionColumns positions, bool metacal = false);

}  // namespace stampede::python
