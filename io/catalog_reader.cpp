// Reading result tables by the column schema; see catalog_reader.hpp.
#include "io/catalog_reader.hpp"

#include <optional>
#include <cstdint>
#include <stdexcept>
#include <utility>

namespace stampede::io {

CatalogReader CatalogReader::open(const std::string& path,
                                  const std::vector<ResultField>& required) {
  FitsFile f = FitsFile::open_read(path);
  f.move_to("RESULTS");
  CatalogReader reader(std::move(f));
  for (ResultField field : required) reader.require(field);
  return reader;
}

void CatalogReader::require(ResultField field) {
  if (!has(field)) throw FitsError(f_.describe() + ": no column '" + column_name(field) + "'");
}

long long CatalogReader::rows() { return f_.table_rows(); }

bool CatalogReader::has(ResultField field) { return f_.has_column(column_name(field)); }

PositionColumns CatalogReader::positions() {
  if (has(ResultField::kNumber)) return PositionColumns::kSurvey;
  return has(ResultField::kXImage) ? PositionColumns::kCatalogue : PositionColumns::kGrid;
}

bool CatalogReader::metacal() { return has(ResultField::kR11); }

std::vector<double> CatalogReader::column(ResultField field) {
  require(field);
  return f_.read_column(column_name(field));
}

void CatalogReader::column_rows(ResultField field, long long first_row, std::span<double> out) {
  require(field);
  f_.read_column_rows(column_name(field), first_row, out);
}

std::vector<double> CatalogReader::column(const std::string& name) { return f_.read_column(name); }

void CatalogReader::column_rows(const std::string& name, long long first_row,
                                std::span<double> out) {
  f_.read_column_rows(name, first_row, out);
}

std::vector<std::string> CatalogReader::bands() {
  std::vector<std::string> out;
  const std::optional<std::string> value = f_.read_key_string(kBandsKey);
  if (!value || value->empty()) return out;
  std::size_t begin = 0;
  while (true) {
    const std::size_t comma = value->find(',', begin);
    out.push_back(value->substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
    if (comma == std::string::npos) break;
    begin = comma + 1;
  }
  try {
    const ResultSchema check(positions(), metacal(), out);
  } catch (const std::invalid_argument& e) {
    throw FitsError(describe() + ": key " + kBandsKey + " = '" + *value + "': " + e.what());
  }
  return out;
}

std::vector<ObjectRecord> CatalogReader::records(long long first_row, long long count) {
  if (count < 0) throw std::invalid_argument("CatalogReader::records: negative count");
  const ResultSchema schema(positions(), metacal(), bands());
  const std::span<const ResultColumn> columns = schema.columns();
  for (const ResultColumn& c : columns)
    if (!f_.has_column(c.name)) throw FitsError(describe() + ": no column '" + c.name + "'");
  std::vector<ObjectRecord> out(static_cast<std::size_t>(count));
  std::vector<double> reals(out.size());
  std::vector<long long> integers(out.size());
  for (const ResultColumn& c : columns) {
    if (c.type == ColumnType::kFloat64) {
      f_.read_column_rows(c.name, first_row, reals);
      for (std::size_t i = 0; i < out.size(); ++i) c.set_real(out[i], reals[i]);
    } else {
      f_.read_column_rows(c.name, first_row, integers);
      for (std::size_t i = 0; i < out.size(); ++i) {
        c.set_integer(out[i], static_cast<std::int64_t>(integers[i]));
      }
    }
  }
  return out;
}

}  // namespace stampede::io
