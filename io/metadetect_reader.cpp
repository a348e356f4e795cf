// Reading a metadetection catalogue; see metadetect_reader.hpp.
#include "io/metadetect_reader.hpp"

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <memory>

#include "engine/metacal/metacal_type.hpp"
#include "io/fits_file.hpp"
#include "io/metadetect_writer.hpp"
#include "io/table_join.hpp"

namespace stampede::io {

std::optional<std::string> MetadetectTable::key(const std::string& name) const {
  for (const auto& [k, v] : header)
    if (k == name) return v;
  return std::nullopt;
}

MetadetectTable read_metadetect_table(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  if (!f.move_to_if_present("METADETECT"))
    throw FitsError(path + ": no METADETECT table (is it a `stampede metadetect` catalogue?)");
  MetadetectTable t;
  t.path = path;
  t.step = f.key_double("MCSTEP");
  for (const FitsFile::HeaderCard& c : f.header_cards())
    if (c.type != FitsFile::HeaderCard::Type::kCommentary && !is_table_structure_key(c.key)) t.header.emplace_back(c.key, c.value);
  const long long n = f.table_rows();
  // Every row is at least a byte of the file: a NAXIS2 beyond that is a damaged header, not rows.
  if (n < 0 || static_cast<unsigned long long>(n) > std::filesystem::file_size(fits_root_name(path)))
    throw FitsError(f.describe() + ": NAXIS2 = " + std::to_string(n) + " rows do not fit in the file");
  auto doubles = [&](const char* name) { return f.read_column(name); };
  auto integers = [&](const char* name) {
    std::vector<long long> v(static_cast<std::size_t>(n));
    if (n > 0) f.read_column_rows(name, 0, std::span<long long>(v));
    return v;
  };
  t.cell = integers("cell");
  t.flags = integers("flags");
  t.e1 = doubles("e1");
  t.e2 = doubles("e2");
  t.snr = doubles("snr");
  t.t_ratio = doubles("T_ratio");
  t.mfrac = doubles("mfrac");
  t.shear_type.resize(static_cast<std::size_t>(n));
  std::vector<std::string> names(static_cast<std::size_t>(n));
  f.read_string_rows("shear_type", 0, names);
  for (long long i = 0; i < n; ++i) {
    const std::string& s = names[static_cast<std::size_t>(i)];
    int type = -1;
    for (MetacalType m : kMetacalTypes)
      if (s == metacal_type_name(m)) type = static_cast<int>(m);
    if (type < 0) throw FitsError(f.describe() + ": row " + std::to_string(i + 1) + " has shear_type '" + s + "'");
    t.shear_type[static_cast<std::size_t>(i)] = type;
  }
  return t;
}

namespace {

std::vector<std::string> bands_of(FitsFile& f) {
  std::vector<std::string> out;
  const std::string v = f.read_key_string("BANDS").value_or("");
  for (std::size_t begin = 0; !v.empty();) {
    const std::size_t comma = v.find(',', begin);
    out.push_back(v.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
    if (comma == std::string::npos) break;
    begin = comma + 1;
  }
  if (out.size() > static_cast<std::size_t>(kMaxMetadetectBands))
    throw FitsError(f.describe() + ": header key BANDS '" + v + "' names more than " +
                    std::to_string(kMaxMetadetectBands) + " bands");
  return out;
}

}  // namespace

std::vector<std::string> metadetect_table_bands(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  if (!f.move_to_if_present("METADETECT"))
    throw FitsError(path + ": no METADETECT table (is it a `stampede metadetect` catalogue?)");
  return bands_of(f);
}

struct MetadetectRowReader::State {
  State(FitsFile f, long long n) : file(std::move(f)), rows(n) {}
  FitsFile file;
  std::vector<std::string> bands;
  long long rows = 0;
  std::vector<const MetadetectColumn*> columns;  // the field columns the table has
  std::vector<double> doubles;
  std::vector<long long> integers;
  std::vector<std::string> names;
};

MetadetectRowReader::MetadetectRowReader(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  if (!f.move_to_if_present("METADETECT"))
    throw FitsError(path + ": no METADETECT table (is it a `stampede metadetect` catalogue?)");
  const long long n = f.table_rows();
  if (n < 0 || static_cast<unsigned long long>(n) > std::filesystem::file_size(fits_root_name(path)))
    throw FitsError(f.describe() + ": NAXIS2 = " + std::to_string(n) + " rows do not fit in the file");
  s_ = std::unique_ptr<State>(new State(std::move(f), n));
  s_->bands = bands_of(s_->file);
  for (const MetadetectColumn& c : metadetect_field_columns())
    if (!c.optional || s_->file.has_column(c.name)) s_->columns.push_back(&c);
}
MetadetectRowReader::~MetadetectRowReader() = default;

long long MetadetectRowReader::rows() const { return s_->rows; }
const std::vector<std::string>& MetadetectRowReader::bands() const { return s_->bands; }

void MetadetectRowReader::read(long long first, std::size_t n, std::vector<MetadetectRow>* out) {
  State& s = *s_;
  FitsFile& f = s.file;
  out->assign(n, MetadetectRow{});
  std::vector<MetadetectRow>& rows = *out;
  if (n == 0) return;
  s.doubles.resize(n), s.integers.resize(n), s.names.resize(n);
  auto doubles = [&](const std::string& name, auto set) {
    f.read_column_rows(name, first, std::span<double>(s.doubles));
    for (std::size_t i = 0; i < n; ++i) set(rows[i], s.doubles[i]);
  };
  f.read_column_rows("cell", first, std::span<long long>(s.integers));
  for (std::size_t i = 0; i < n; ++i) rows[i].cell = s.integers[i];
  f.read_string_rows("shear_type", first, s.names);
  for (std::size_t i = 0; i < n; ++i) {
    rows[i].shear_type = -1;
    for (MetacalType m : kMetacalTypes)
      if (s.names[i] == metacal_type_name(m)) rows[i].shear_type = static_cast<int>(m);
    if (rows[i].shear_type < 0)
      throw FitsError(f.describe() + ": row " + std::to_string(first + static_cast<long long>(i) + 1) +
                      " has shear_type '" + s.names[i] + "'");
  }
  for (const MetadetectColumn* c : s.columns) {
    if (c->tform[1] == 'J') {  // read as integers: a value that is not one is refused, not rounded
      f.read_column_rows(c->name, first, std::span<long long>(s.integers));
      for (std::size_t i = 0; i < n; ++i) {
        if (s.integers[i] < INT32_MIN || s.integers[i] > UINT32_MAX)  // scaled by TZERO beyond 32 bits
          throw FitsError(f.describe() + ": row " + std::to_string(first + static_cast<long long>(i) + 1) + " has " +
                          c->name + " = " + std::to_string(s.integers[i]) + ", beyond 32 bits");
        c->set(rows[i], static_cast<double>(s.integers[i]));
      }
    } else {
      doubles(c->name, c->set);
    }
  }
  for (std::size_t b = 0; b < s.bands.size(); ++b) {
    doubles("flux_" + s.bands[b], [b](MetadetectRow& r, double v) { r.band_flux[b] = v; });
    doubles("snr_" + s.bands[b], [b](MetadetectRow& r, double v) { r.band_snr[b] = v; });
  }
}

std::vector<MetadetectRow> read_metadetect_rows(const std::string& path) {
  MetadetectRowReader reader(path);
  std::vector<MetadetectRow> rows;
  reader.read(0, static_cast<std::size_t>(reader.rows()), &rows);
  return rows;
}

}  // namespace stampede::io
