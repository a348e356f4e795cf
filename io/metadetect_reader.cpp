// Reading a metadetection catalogue; see metadetect_reader.hpp.
#include "io/metadetect_reader.hpp"

#include <algorithm>
#include <filesystem>
#include <type_traits>

#include "engine/metacal/metacal_type.hpp"
#include "io/fits_file.hpp"
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

std::vector<MetadetectRow> read_metadetect_rows(const std::string& path) {
  const MetadetectTable t = read_metadetect_table(path);
  FitsFile f = FitsFile::open_read(path);
  f.move_to("METADETECT");
  const std::size_t n = t.cell.size();
  std::vector<MetadetectRow> rows(n);
  auto doubles = [&](const char* name, double MetadetectRow::*field) {
    const std::vector<double> v = f.read_column(name);
    for (std::size_t i = 0; i < n; ++i) rows[i].*field = v[i];
  };
  auto integers = [&](const char* name, auto MetadetectRow::*field) {
    std::vector<long long> v(n);
    if (n > 0) f.read_column_rows(name, 0, std::span<long long>(v));
    for (std::size_t i = 0; i < n; ++i) rows[i].*field = static_cast<std::remove_reference_t<decltype(rows[i].*field)>>(v[i]);
  };
  for (std::size_t i = 0; i < n; ++i) rows[i].cell = t.cell[i], rows[i].shear_type = t.shear_type[i];
  integers("id", &MetadetectRow::id);
  doubles("x", &MetadetectRow::x);
  doubles("y", &MetadetectRow::y);
  doubles("u", &MetadetectRow::u);
  doubles("v", &MetadetectRow::v);
  doubles("e1", &MetadetectRow::e1);
  doubles("e2", &MetadetectRow::e2);
  doubles("e1_err", &MetadetectRow::e1_err);
  doubles("e2_err", &MetadetectRow::e2_err);
  doubles("T", &MetadetectRow::t);
  doubles("T_ratio", &MetadetectRow::t_ratio);
  doubles("psf_T", &MetadetectRow::psf_t);
  doubles("flux", &MetadetectRow::flux);
  doubles("snr", &MetadetectRow::snr);
  doubles("mfrac", &MetadetectRow::mfrac);
  integers("box_size", &MetadetectRow::box_size);
  integers("isophotal_area", &MetadetectRow::isophotal_area);
  integers("sep_flags", &MetadetectRow::sep_flags);
  integers("flags", &MetadetectRow::flags);
  if (f.has_column("psf_orig_e1")) {  // tables written before these columns lack them
    doubles("psf_orig_e1", &MetadetectRow::psf_orig_e1);
    doubles("psf_orig_e2", &MetadetectRow::psf_orig_e2);
    doubles("psf_orig_T", &MetadetectRow::psf_orig_t);
    doubles("psf_rec_e1", &MetadetectRow::psf_rec_e1);
    doubles("psf_rec_e2", &MetadetectRow::psf_rec_e2);
  }
  const std::vector<std::string> bands = bands_of(f);
  for (std::size_t b = 0; b < bands.size(); ++b) {
    const std::vector<double> flux = f.read_column("flux_" + bands[b]), snr = f.read_column("snr_" + bands[b]);
    for (std::size_t i = 0; i < n; ++i) rows[i].band_flux[b] = flux[i], rows[i].band_snr[b] = snr[i];
  }
  return rows;
}

}  // namespace stampede::io
