// FITS input as numpy, for users without astropy or fitsio and for the diagnostics report:
// read_image and read_results (a `stampede fit` table whole, as fit_stamps' rows), and the
// general readers over io::FitsFile: fits_hdus (what a file holds), fits_header (an HDU's cards)
// and read_table (columns of a row range, so a table of any size can be streamed in chunks).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cctype>
#include <climits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "io/catalog_reader.hpp"
#include "io/fits_file.hpp"
#include "arguments.hpp"
#include "numpy_arrays.hpp"

namespace py = pybind11;

namespace stampede::python {

namespace {

bool equal_ignoring_case(const std::string& a, const std::string& b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// A TDIMn value "(a,b,...)" as its axes when it has two or more whose product is the column's
// repeat; otherwise (absent, one axis, malformed, inconsistent) none: the column reads as
// (rows, repeat).
std::vector<long> tdim_axes(const std::string& text, long long repeat) {
  std::vector<long> axes;
  const std::size_t open = text.find('('), close = text.find(')');
  if (open == std::string::npos || close == std::string::npos || close < open) return {};
  long long product = 1;
  std::size_t at = open + 1;
  while (at < close) {
    std::size_t used = 0;
    long v = 0;
    try {
      v = std::stol(text.substr(at, close - at), &used);
    } catch (const std::exception&) {
      return {};
    }
    if (v < 1 || v > repeat) return {};
    axes.push_back(v);
    product *= v;
    if (product > repeat) return {};
    at += used;
    while (at < close && (text[at] == ' ' || text[at] == ',')) ++at;
  }
  if (axes.size() < 2 || product != repeat) return {};
  return axes;
}

// An HDU as the caller names it: an index (0 = primary) or an EXTNAME.
struct HduChoice {
  std::optional<int> index;
  std::string extname;
};

HduChoice hdu_argument(const Arguments& a, const char* name) {
  const py::object v = a.object(name);
  if (py::isinstance<py::str>(v)) return {std::nullopt, a.text(name)};
  if (!py::hasattr(v, "__index__"))
    throw py::type_error(a.where(name) + " must be an HDU index (int, 0 = primary) or an EXTNAME (str), not " +
                         describe(v));
  return {static_cast<int>(a.integer_in(name, 0, 0, INT_MAX - 1)), ""};
}

void move_to(io::FitsFile& f, const HduChoice& hdu) {
  if (hdu.index) {
    f.move_to(*hdu.index);
  } else {
    f.move_to(hdu.extname);
  }
}

io::FitsFile open_at(const std::string& path, const std::optional<HduChoice>& hdu) {
  py::gil_scoped_release release;
  io::FitsFile f = io::FitsFile::open_read(path);
  if (hdu) move_to(f, *hdu);
  return f;
}

// Header text is ASCII by the standard; a corrupt file's other bytes become U+FFFD rather than a
// UnicodeDecodeError that would name no file.
py::str text(const std::string& s) {
  PyObject* o = PyUnicode_DecodeUTF8(s.data(), static_cast<Py_ssize_t>(s.size()), "replace");
  if (o == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

// A card's value as the Python type it is written as; a number Python does not parse as CFITSIO
// did stays its text.
py::object card_value(const io::FitsFile::HeaderCard& card) {
  using Type = io::FitsFile::HeaderCard::Type;
  PyObject* number = nullptr;
  switch (card.type) {
    case Type::kUndefined:
      return py::none();
    case Type::kLogical:
      return py::bool_(card.value == "T");
    case Type::kInteger:
      number = PyLong_FromString(card.value.c_str(), nullptr, 10);
      break;
    case Type::kReal:
      number = PyFloat_FromString(text(card.value).ptr());
      break;
    case Type::kCommentary:
    case Type::kString:
      return text(card.value);
  }
  if (number == nullptr) {
    PyErr_Clear();
    return text(card.value);
  }
  return py::reinterpret_steal<py::object>(number);
}

const char* kind_name(io::FitsFile::HduKind kind) {
  switch (kind) {
    case io::FitsFile::HduKind::kImage: return "image";
    case io::FitsFile::HduKind::kEmpty: return "empty";
    case io::FitsFile::HduKind::kTable: return "table";
  }
  return "?";
}

}  // namespace

void bind_io(py::module_& m) {
  m.def(
      "read_image",
      [](py::args args, py::kwargs kwargs) {
        const Arguments a("read_image", args, kwargs, {{"path", true}, {"hdu"}});
        const std::string path = a.text("path");
        const std::optional<HduChoice> hdu = a.given("hdu") ? std::optional(hdu_argument(a, "hdu")) : std::nullopt;
        std::vector<double> pixels;
        long nx = 0, ny = 0;
        io::FitsFile f = open_at(path, hdu);
        {
          py::gil_scoped_release release;
          const auto shape = f.image_shape();
          nx = shape.nx, ny = shape.ny;
          pixels = f.read_image();
          f.close();
        }
        py::array_t<double> out(std::vector<py::ssize_t>{ny, nx});
        std::copy(pixels.begin(), pixels.end(), out.mutable_data());
        return out;
      },
      "read_image(path, hdu=None)\n\nA 2-D image of a FITS file as a float64 array [y, x] (BSCALE/BZERO applied, "
      "BLANK pixels NaN). hdu: an index (0 = primary) or an EXTNAME; without it, the HDU CFITSIO syntax names "
      "('f.fits[2]') or the first image holding pixels. 'f.fits.gz' is read too.");
  m.def(
      "read_results",
      [](py::args args, py::kwargs kwargs) {
        const std::string path = Arguments("read_results", args, kwargs, {{"path", true}}).text("path");
        std::vector<ObjectRecord> rows;
        io::PositionColumns positions;
        bool metacal = false;
        std::vector<std::string> bands;
        {
          py::gil_scoped_release release;
          io::CatalogReader r = io::CatalogReader::open(path);
          positions = r.positions();
          metacal = r.metacal();
          bands = r.bands();
          rows = r.records(0, r.rows());
        }
        return result_array(rows, positions, metacal, bands);
      },
      "read_results(path)\n\nThe RESULTS table of a `stampede fit` output as a structured array of its schema columns (the dtype "
      "fit_stamps returns for grid input; a multi-band table's per-band columns included).");
  m.def(
      "fits_hdus",
      [](py::args args, py::kwargs kwargs) {
        const std::string path = Arguments("fits_hdus", args, kwargs, {{"path", true}}).text("path");
        struct Hdu {
          std::string name;
          io::FitsFile::HduKind kind;
          long long rows = 0;
          std::vector<std::string> columns;
        };
        std::vector<Hdu> hdus;
        {
          py::gil_scoped_release release;
          io::FitsFile f = io::FitsFile::open_read(path);
          const int n = f.hdu_count();
          for (int i = 0; i < n; ++i) {
            f.move_to(i);
            Hdu h{f.read_key_string("EXTNAME").value_or(""), f.hdu_kind(), 0, {}};
            if (h.kind == io::FitsFile::HduKind::kTable) {
              h.rows = f.table_rows();
              h.columns = f.column_names();
            }
            hdus.push_back(std::move(h));
          }
          f.close();
        }
        py::list out;
        for (std::size_t i = 0; i < hdus.size(); ++i) {
          py::dict d;
          d["index"] = i;
          d["name"] = text(hdus[i].name);
          d["kind"] = kind_name(hdus[i].kind);
          const bool table = hdus[i].kind == io::FitsFile::HduKind::kTable;
          d["rows"] = table ? py::object(py::int_(hdus[i].rows)) : py::object(py::none());
          py::list columns;
          for (const std::string& c : hdus[i].columns) columns.append(text(c));
          d["columns"] = columns;
          out.append(d);
        }
        return out;
      },
      "fits_hdus(path)\n\nThe HDUs of a FITS file in order, each a dict: index (0 = primary), name (EXTNAME, '' "
      "without one), kind ('image', 'empty' for one without pixels, or 'table'), rows (tables; else None) and "
      "columns (a table's column names in order; else []).");
  m.def(
      "fits_header",
      [](py::args args, py::kwargs kwargs) {
        const Arguments a("fits_header", args, kwargs, {{"path", true}, {"hdu"}});
        const std::string path = a.text("path");
        const HduChoice hdu = a.given("hdu") ? hdu_argument(a, "hdu") : HduChoice{0, ""};
        std::vector<io::FitsFile::HeaderCard> cards;
        io::FitsFile f = open_at(path, hdu);
        {
          py::gil_scoped_release release;
          cards = f.header_cards();
          f.close();
        }
        py::list out;
        for (const auto& c : cards) out.append(py::make_tuple(text(c.key), card_value(c), text(c.comment)));
        return out;
      },
      "fits_header(path, hdu=0)\n\nThe cards of an HDU (an index, 0 = primary, or an EXTNAME) in order, END excluded, "
      "as (key, value, comment) tuples. value is a str, bool, int or float as written, None for a key without one; a "
      "long string's CONTINUE cards are joined into it; HIERARCH keys appear by their long name. COMMENT, HISTORY "
      "and blank-keyword cards have their text as value.");
  m.def(
      "read_table",
      [](py::args args, py::kwargs kwargs) {
        const Arguments a("read_table", args, kwargs,
                          {{"path", true}, {"hdu", true}, {"columns", true}, {"first_row"}, {"count"}});
        const std::string path = a.text("path");
        const HduChoice hdu = hdu_argument(a, "hdu");
        const std::vector<std::string> names = a.names("columns");
        const long long first = a.integer_in("first_row", 0, 0, LLONG_MAX);
        // count < 0: to the end of the table.
        const long long count = a.given("count") ? a.integer_in("count", 0, 0, LLONG_MAX) : -1;
        io::FitsFile f = open_at(path, hdu);
        long long rows = 0;
        std::vector<char> integer(names.size()), string(names.size());
        // Values per row (vector columns: > 1) and their TDIM shape where it has two axes or more.
        std::vector<long long> repeat(names.size(), 1);
        std::vector<std::vector<long>> tdim(names.size());
        std::string where;
        {
          py::gil_scoped_release release;
          rows = f.table_rows();
          const std::vector<std::string> all = f.column_names();
          // Every column checked before any is read: an absent one is an error naming it at once.
          for (std::size_t i = 0; i < names.size(); ++i) {
            string[i] = f.is_string_column(names[i]);
            if (string[i]) continue;
            integer[i] = f.is_integer_column(names[i]);
            repeat[i] = f.column_repeat(names[i]);
            for (std::size_t c = 0; c < all.size() && repeat[i] > 1; ++c) {
              if (!equal_ignoring_case(all[c], names[i])) continue;
              tdim[i] = tdim_axes(f.read_key_string("TDIM" + std::to_string(c + 1)).value_or(""), repeat[i]);
              break;
            }
          }
          where = f.describe();
        }
        if (first > rows || (count >= 0 && count > rows - first))
          throw py::value_error("read_table(): rows " + std::to_string(first) + ".." +
                                (count >= 0 ? std::to_string(first + count - 1) : std::string("end")) +
                                " are beyond the " + std::to_string(rows) + " rows of " + where);
        const long long n = count >= 0 ? count : rows - first;
        // Allocated here, with the GIL, and filled without it: no copy of a chunk's columns.
        std::vector<py::array> arrays;
        for (std::size_t i = 0; i < names.size(); ++i) {
          std::vector<py::ssize_t> shape = {static_cast<py::ssize_t>(n)};
          if (repeat[i] > 1 && tdim[i].empty()) shape.push_back(static_cast<py::ssize_t>(repeat[i]));
          for (auto d = tdim[i].rbegin(); d != tdim[i].rend(); ++d) shape.push_back(*d);  // FITS's first axis fastest
          if (string[i]) {
            arrays.emplace_back();  // made below, from the strings read
          } else if (integer[i]) {
            arrays.push_back(py::array_t<long long>(shape));
          } else {
            arrays.push_back(py::array_t<double>(shape));
          }
        }
        std::vector<io::FitsFile::ColumnOutput> outputs;
        const auto size = static_cast<std::size_t>(n);
        for (std::size_t i = 0; i < names.size(); ++i) {
          if (string[i] || repeat[i] > 1) continue;
          void* data = arrays[i].mutable_data();
          if (integer[i]) {
            outputs.push_back({names[i], std::span<long long>(static_cast<long long*>(data), size)});
          } else {
            outputs.push_back({names[i], std::span<double>(static_cast<double*>(data), size)});
          }
        }
        std::vector<std::vector<std::string>> strings(names.size());
        {
          py::gil_scoped_release release;
          if (!outputs.empty()) f.read_columns_rows(first, outputs);  // all columns in one pass over the rows
          for (std::size_t i = 0; i < names.size(); ++i) {
            if (string[i] || repeat[i] <= 1 || n == 0) continue;
            const std::size_t values = size * static_cast<std::size_t>(repeat[i]);
            void* data = arrays[i].mutable_data();
            if (integer[i]) {
              f.read_vector_rows(names[i], first, std::span<long long>(static_cast<long long*>(data), values));
            } else {
              f.read_vector_rows(names[i], first, std::span<double>(static_cast<double*>(data), values));
            }
          }
          for (std::size_t i = 0; i < names.size(); ++i)
            if (string[i]) {
              strings[i].resize(size);
              f.read_string_rows(names[i], first, strings[i]);
            }
          f.close();
        }
        for (std::size_t i = 0; i < names.size(); ++i)
          if (string[i]) {
            py::list values(size);
            for (std::size_t k = 0; k < size; ++k) values[k] = text(strings[i][k]);
            arrays[i] = py::module_::import("numpy").attr("array")(values, py::arg("dtype") = "U");
          }
        py::dict out;
        for (std::size_t i = 0; i < names.size(); ++i) out[py::str(names[i])] = arrays[i];
        return out;
      },
      "read_table(path, hdu, columns, first_row=0, count=None)\n\nRows [first_row, first_row + count) (to the end "
      "without count) of the named numeric or character columns of a table HDU (an index or an EXTNAME), as a dict "
      "{name: array}: int64 for integer columns (after TZERO: uint32 and int64 ids exact), float64 for real "
      "ones, str (numpy 'U', trailing blanks removed) for character columns ('7A'); a vector column ('2D') is "
      "(rows, values), or (rows, *axes) by its TDIM ('(2,2)' gives (rows, 2, 2)). Names match "
      "case-insensitively. An absent HDU or column, "
      "or one of another kind (logicals, bits, complex), is a stampede.FitsError naming the file, "
      "HDU and column; rows beyond the table a ValueError. Read a large table in chunks of rows: only those rows "
      "are read.");
}

}  // namespace stampede::python
