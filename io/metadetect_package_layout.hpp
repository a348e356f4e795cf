// The reference metadetect package's output layout, so that analysis code written against the
// package reads our rows unchanged: one table per shear type (noshear, 1p, 1m, 2p, 2m; in a FITS
// file each an HDU of that EXTNAME, in Python a dict of structured arrays), with the package's
// column names, types and shapes (its fitting.py and metadetect.py; docs/survey_metadetect.md
// lists them and what each holds here). `{m}` is the measurement's name (wmom, pgauss, gauss, exp,
// bd). Two columns beside them say where a row came from: `cell` and `id` (as our table's).
//
// What the package has and we do not measure is NaN (`{m}_T_err`), and g_cov is diagonal (the
// e1-e2 covariance is not measured): both said in the column's TCOMM.
#pragma once
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "engine/metadetect/metadetect_row.hpp"
#include "io/metadetect_reader.hpp"

namespace stampede::io {

struct PackageLayoutOptions {
  std::string measurement = "wmom";  // the column prefix
  int bands = 1;                     // one: the band columns are scalars, as the package's
  // The package's band-index strings ("012": bands 0, 1, 2 of the input's order), at most 6 bands.
  std::string shear_bands = "0", det_bands = "0";
};

// A band-role bit mask (bit b: band b; 0: every one of `bands`) as the package's index string.
std::string package_band_indices(std::uint32_t mask, int bands);

struct PackageColumn {
  enum class Type { kFloat64, kFloat32, kInt32, kInt64, kText };
  std::string name;
  Type type = Type::kFloat64;
  std::vector<int> shape;  // per row: {} a scalar, {2}, {2, 2}, {bands}; kText: {characters}
  std::string comment;
  // The row's values (product of shape of them, row-major) for numeric columns.
  std::function<void(const MetadetectRow&, std::span<double>)> values;
  std::string text = {};  // kText: the same string in every row
  int count() const;  // values per row (1 for kText)
};

std::vector<PackageColumn> package_columns(const PackageLayoutOptions& options);

// The rows of each shear type, in row order, by MetacalType (noshear, 1p, 1m, 2p, 2m).
std::vector<std::vector<const MetadetectRow*>> rows_by_shear_type(std::span<const MetadetectRow> rows);

// A metadetection table's rows rewritten in the package's layout to PATH (PATH.partial, then
// renamed), read in chunks (memory bounded whatever the table's size): an empty primary HDU holding
// `primary_keys` (the run's record), then the five tables. Throws FitsError or FileError naming
// the file.
void write_package_layout(const std::string& path, MetadetectRowReader& reader, const PackageLayoutOptions& options,
                          const std::vector<std::pair<std::string, std::string>>& primary_keys);

}  // namespace stampede::io
