// CatalogReader: reads the RESULTS table of a `stampede fit` catalogue (as CatalogWriter wrote it,
// or as `stampede calibrate apply` extended it) by the column schema of result_columns.hpp: whole
// columns, chunks of rows, or rows as ObjectRecords (for a merge of catalogues).
//
// Consumers name schema columns by ResultField, so a renamed column is one edit in
// result_columns.cpp. Columns outside the schema (e1_cal, nbc_m, ... from calibrate apply) are read
// by name. A missing column is a FitsError naming the file, the HDU and the column, e.g.
// "fit.fits[HDU 1 'RESULTS']: no column 'snr'".
//
// Not safe to use from two threads at once (it holds one FitsFile).
#pragma once

#include <span>
#include <string>
#include <utility>
#include <vector>

#include "engine/pipeline/object_record.hpp"
#include "io/fits_file.hpp"
#include "io/result_columns.hpp"

namespace stampede::io {

class CatalogReader {
 public:
  // Opens the RESULTS table of `path` and checks that it has every column in `required`, so a
  // wrong file fails before any work; throws FitsError naming the first missing one.
  static CatalogReader open(const std::string& path,
                            const std::vector<ResultField>& required = {});

  long long rows();
  bool has(ResultField field);
  // The position layout: catalogue when the table has x_image, grid otherwise.
  // Whether the table has the metacal columns (a metacal run's).
  bool metacal();
  PositionColumns positions();
  // A multi-band table's bands (header key BANDS), in column order; empty for one band.
  std::vector<std::string> bands();

  // A schema column as doubles (integer columns exact up to 2^53; TNULL values read as NaN).
  std::vector<double> column(ResultField field);
  // Rows [first_row, first_row + out.size()) of it, 0-based, so a table can be read in chunks.
  void column_rows(ResultField field, long long first_row, std::span<double> out);
  // Any column of the table by name (case-insensitive), schema or not.
  std::vector<double> column(const std::string& name);
  void column_rows(const std::string& name, long long first_row, std::span<double> out);

  // Rows [first_row, first_row + count) as records, from every column of positions() (integer
  // columns read exactly). Record fields the table does not hold keep their defaults
  // (fit.errors, fit.n_pixels, stamp_x0, ...). Throws naming a missing column.
  std::vector<ObjectRecord> records(long long first_row, long long count);

  // The file, on the RESULTS HDU: header keys, copying the HDUs.
  FitsFile& file() { return f_; }
  // "PATH[HDU n 'RESULTS']", for messages.
  std::string describe() { return f_.describe(); }

 private:
  explicit CatalogReader(FitsFile f) : f_(std::move(f)) {}
  void require(ResultField field);
  FitsFile f_;
};

}  // namespace stampede::io
