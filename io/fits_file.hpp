// FitsFile: an owning RAII wrapper around a CFITSIO `fitsfile*`, covering what stampede reads and
// writes: header keywords, 2-D images (read whole or by row range) and numeric binary-table columns.
//
// Every failure throws FitsError whose message starts with describe(), i.e. names the file and the
// current HDU, e.g. "render_cases.fits[HDU 2 'CASE01']: missing header keyword 'GAIN'". CFITSIO's own
// error stack is cleared after each failure, and nothing is printed to stderr.
//
// HDU indices are 0-based everywhere (0 = primary), unlike CFITSIO's 1-based ones.
// A FitsFile is not safe to use from two threads at once; distinct FitsFile objects are.
#pragma once

#include <concepts>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "io/fits_error.hpp"

namespace stampede::io {

class FitsFile {
 public:
  // Opens for reading. `path` may use CFITSIO extended syntax: "f.fits[1]", "f.fits[CASES]",
  // "f.fits.gz", "f.fits.fz". Throws FitsError "cannot open FITS file 'PATH': <cfitsio text>".
  static FitsFile open_read(const std::string& path);
  // Creates a new, empty file for writing; with `overwrite` an existing file is replaced.
  // A name ending in ".gz" is written gzip-compressed when the file is closed.
  static FitsFile create(const std::string& path, bool overwrite);

  FitsFile(FitsFile&& other) noexcept;
  FitsFile& operator=(FitsFile&& other) noexcept;
  FitsFile(const FitsFile&) = delete;
  FitsFile& operator=(const FitsFile&) = delete;
  // Closes the file, swallowing errors; call close() first where a failed flush must be seen.
  ~FitsFile();

  // Closes now and reports a failure to flush (e.g. compressing a ".gz" output). Idempotent.
  // Any other call on a closed (or moved-from) FitsFile throws FitsError.
  void close();

  // The path exactly as given to open_read/create.
  const std::string& path() const;

  // --- HDU navigation -------------------------------------------------------------------------
  int hdu_count();
  void move_to(int hdu_index);               // 0-based
  void move_to(const std::string& extname);  // EXTNAME (or HDUNAME), case-insensitive
  // Moves to the HDU named `extname` and returns true, or stays and returns false when none is.
  bool move_to_if_present(const std::string& extname);
  int hdu_index();                           // 0-based current HDU
  // What the current HDU holds (no automatic move to the first image, unlike the image
  // functions): kEmpty is an image HDU without pixels (NAXIS = 0 or an axis of length 0), such as
  // a header-only primary; kTable a binary or ASCII table.
  enum class HduKind { kImage, kEmpty, kTable };
  HduKind hdu_kind();
  // "FILE[HDU n 'EXTNAME']" ("FILE[HDU n]" when there is no EXTNAME); FILE is the path without
  // CFITSIO's bracketed extended syntax. Never throws.
  std::string describe();

  // --- Header keywords of the current HDU ------------------------------------------------------
  // The optional forms return nullopt if the keyword is absent or has no value; all forms throw
  // FitsError "...: keyword 'KEY' is not a number" (or "... is not an integer") on a wrong type.
  std::optional<double> read_key_double(const std::string& key);
  std::optional<long long> read_key_long(const std::string& key);  // accepts integral floats, 3.0
  std::optional<std::string> read_key_string(const std::string& key);  // non-strings as written
  // The required forms throw "PATH[HDU n 'NAME']: missing header keyword 'KEY'" when absent.
  double key_double(const std::string& key);
  long long key_long(const std::string& key);
  std::string key_string(const std::string& key);
  // One card of the current header, for a reader that wants all of them (a report of a run's
  // options) rather than the keywords it knows.
  struct HeaderCard {
    // kCommentary: COMMENT, HISTORY, a blank keyword or any card without a value indicator.
    // kUndefined: "KEY =" with no value. Complex values are kString, as written.
    enum class Type { kCommentary, kUndefined, kString, kLogical, kInteger, kReal };
    std::string key;      // as in the file; a HIERARCH card's by its long name
    Type type = Type::kCommentary;
    // kString: unquoted, CONTINUE cards joined (LONGSTRN), trailing blanks dropped; kLogical "T"
    // or "F"; kInteger and kReal as written (a real's D exponent as E, so strtod reads it);
    // kCommentary: the text from column 9, trailing blanks dropped.
    std::string value;
    std::string comment;  // after the '/', trimmed ("" for commentary cards)
  };
  // Every card of the current HDU in order, END excluded, a long string's CONTINUE cards folded
  // into the card they continue. A repeated keyword is listed each time.
  std::vector<HeaderCard> header_cards();
  // Adds the keyword or replaces its value and comment. Doubles are written with 17 significant
  // digits so they read back bitwise; long strings use the CONTINUE convention.
  void write_key(const std::string& key, double value, const std::string& comment);
  void write_key(const std::string& key, long long value, const std::string& comment);
  void write_key(const std::string& key, const std::string& value, const std::string& comment);
  // Any other integer type (int, long, unsigned, ...): without this, write_key("N", 3, "") would
  // be ambiguous between the double and long long overloads. bool stays ambiguous on purpose.
  template <std::integral T>
    requires(!std::same_as<T, bool> && !std::same_as<T, long long>)
  void write_key(const std::string& key, T value, const std::string& comment) {
    if (!std::in_range<long long>(value)) {
      fail("value of header keyword '" + key + "' does not fit in a 64-bit integer");
    }
    write_key(key, static_cast<long long>(value), comment);
  }

  // --- 2-D image HDUs ---------------------------------------------------------------------------
  // nx = NAXIS1 (columns, the fast axis), ny = NAXIS2 (rows).
  // Image functions on a file from open_read that is still on an empty primary HDU (NAXIS = 0)
  // and on which move_to was never called first move to the first image HDU holding data, as
  // for tile-compressed ".fz" files; hdu_index() then reports that HDU.
  struct ImageShape {
    long nx = 0;
    long ny = 0;
  };
  // Throws FitsError if the current HDU is not a 2-D image.
  ImageShape image_shape();
  // Reads rows [y_begin, y_begin + n_rows) (0-based) into `out`, which must hold exactly
  // n_rows * nx values; row-major, x fastest. Any BITPIX is converted to double, BSCALE/BZERO
  // applied, BLANK pixels become NaN. Only those rows are read from disk (a ".gz" file, though,
  // is decompressed into memory as a whole when opened: CFITSIO cannot seek in gzip streams).
  void read_image_rows(long y_begin, long n_rows, std::span<double> out);
  std::vector<double> read_image();  // the whole image, row-major
  // 1-D image HDUs (MEDS keeps every cutout of a type in one flat array): the number of pixels
  // (throws unless NAXIS = 1), and pixels [first, first + out.size()), converted as above; only
  // the tiles or blocks holding them are read.
  long long image_length();
  void read_image_range(long long first, std::span<double> out);
  // Appends an image HDU (BITPIX -64) of nx * ny pixels (row-major) and makes it current; the
  // first one in a new file becomes the primary. A non-empty `extname` is written as EXTNAME.
  // BITPIX -64, -32 or 32 on disk (kInt32: values rounded to the nearest integer, as a bit mask's).
  enum class PixelType { kFloat64, kFloat32, kInt32 };
  void write_image(long nx, long ny, std::span<const double> pixels, const std::string& extname = "",
                   PixelType type = PixelType::kFloat64);
  // Appends a header-only image HDU (NAXIS = 0): a primary that carries keywords only.
  void write_empty_image();

  // --- Table HDUs (binary or ASCII) --------------------------------------------------------------
  long long table_rows();
  // Column names match case-insensitively and literally (no CFITSIO wildcards).
  bool has_column(const std::string& name);
  // Every column's TTYPEn in column order ("" for a column without one).
  std::vector<std::string> column_names();
  // Whether a numeric column's values (after TSCAL/TZERO) are integers, i.e. whether to read it
  // into long long rather than double; scalar and vector columns alike. Throws as read_column
  // does for an absent or non-numeric column (strings, logicals, bits, complex).
  bool is_integer_column(const std::string& name);
  // A whole scalar numeric column converted to double (TNULL values become NaN). Throws
  // "PATH[HDU n 'TRUTH']: no column 'NAME'" if absent, or if the column is not scalar numeric.
  std::vector<double> read_column(const std::string& name);
  // Rows [first_row, first_row + out.size()) (0-based) of a scalar numeric column, so a catalogue
  // can be streamed in chunks.
  void read_column_rows(const std::string& name, long long first_row, std::span<double> out);
  // The same for an integer column (after TSCAL/TZERO), read exactly as 64-bit integers (ids
  // beyond 2^53 included; TNULL is not applied). Throws "... column 'NAME' is not an integer
  // column" for a floating-point column.
  void read_column_rows(const std::string& name, long long first_row, std::span<long long> out);
  // Several scalar numeric columns over the same rows [first_row, first_row + n), n the size of
  // every output, each into a double or a long long span (converted as the single-column forms
  // above). Faster than one call per column on a wide table: the rows are read in blocks that fit
  // CFITSIO's buffers, every column of a block before the next, so each row comes from the file
  // once rather than once per column (docs/report/README.md).
  struct ColumnOutput {
    std::string name;
    std::variant<std::span<double>, std::span<long long>> out;
  };
  void read_columns_rows(long long first_row, std::span<const ColumnOutput> columns);
  // Vector numeric columns ('5K', '1681E'): values per row, and rows [first_row, first_row +
  // out.size() / repeat) into `out`, row after row (out.size() must be a multiple of repeat).
  // Scalar columns have repeat 1. Integer columns read as doubles are exact up to 2^53.
  long long column_repeat(const std::string& name);
  void read_vector_rows(const std::string& name, long long first_row, std::span<double> out);
  void read_vector_rows(const std::string& name, long long first_row, std::span<long long> out);
  // Whether a column is a character column ('17A'); throws for an absent one.
  bool is_string_column(const std::string& name);
  // Row `row` of a character column, trailing blanks removed. Throws for other types.
  std::string read_string(const std::string& name, long long row);
  // Rows [first_row, first_row + out.size()) of a character column in one read, as read_string.
  void read_string_rows(const std::string& name, long long first_row, std::span<std::string> out);
  // The nx x ny pixels whose lower-left pixel is (x_begin, y_begin), 0-based, row-major.
  void read_image_region(long x_begin, long y_begin, long nx, long ny, std::span<double> out);
  // Appends a binary table of scalar columns (all of one length) and makes it current. Integer
  // columns are stored as 64-bit integers ('K'), the others as doubles ('D').
  struct OutputColumn {
    std::string name;
    bool integer = false;
    std::vector<double> values;
  };
  void write_table(const std::string& extname, const std::vector<OutputColumn>& columns);
  // Appends copies of every HDU of this file (headers and data) to `out` (e.g. a catalogue to be
  // extended with new columns).
  void copy_all_hdus_to(FitsFile& out);
  // Appends a double ('D') column to the current table, with TCOMMn = comment when not empty.
  void add_column(const std::string& name, const std::string& comment);
  // Writes rows [first_row, first_row + values.size()) (0-based) of a numeric column.
  void write_column_rows(const std::string& name, long long first_row, std::span<const double> values);

 private:
  FitsFile(void* fptr, std::string path, bool auto_image);

  // `void*` rather than `fitsfile*`: CFITSIO's fitsfile is an anonymous-struct typedef that cannot
  // be forward-declared, and including fitsio.h here would leak its macros into every includer.
  void* handle();
  // Column number of a scalar numeric column (throws otherwise); *nulval_if_integer is left
  // non-null for integer columns, whose TNULL values must read as NaN.
  int numeric_column(const std::string& name, void** nulval_if_integer, long long* repeat = nullptr);
  // A column's CFITSIO type code, its number in *col and values per row in *repeat; throws when
  // there is no such column.
  int column_type(const std::string& name, int* col, long long* repeat);
  // A character column's number, its characters per row in *chars; throws for other types.
  int string_column(const std::string& name, long long* chars);
  // Rows of a numeric column as doubles (TNULL -> NaN for integer columns) or exact integers;
  // vector: any repeat (out holds whole rows), else a scalar column only.
  void read_rows(const std::string& name, long long first_row, std::span<double> out, bool vector);
  void read_rows(const std::string& name, long long first_row, std::span<long long> out, bool vector);
  // Checks that `values` values from row first_row of a column of `repeat` per row are in the table.
  void require_rows(const std::string& name, long long first_row, std::size_t values, long long repeat);
  void close_noexcept() noexcept;
  [[noreturn]] void fail(const std::string& what);
  [[noreturn]] void fail_status(int status, const std::string& what);
  std::optional<std::string> raw_key(const std::string& key);
  void resolve_auto_image();
  void* image_nulval(double* nan);
  void require_writable(const std::string& what);
  void require_header(const std::string& what);
  void require_table();
  // For a file opened read-only: throws when the current HDU's data, as CFITSIO parsed its header,
  // would end past the end of the file.
  void require_data_in_file();
  std::optional<int> find_column(const std::string& name);

  void* fptr_ = nullptr;
  std::string path_;
  std::string root_;          // path_ without extended syntax, for messages
  bool auto_image_ = false;   // the lazy move to the first image HDU is still pending
};

// The file on disk that a CFITSIO path names: "a.fits[1]" -> "a.fits", "!a.fits" -> "a.fits"
// (the path itself when CFITSIO cannot parse it).
std::string fits_root_name(const std::string& path);

}  // namespace stampede::io
