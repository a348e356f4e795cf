// The metadetection catalogue; see metadetect_writer.hpp.
#include "io/metadetect_writer.hpp"

#include <fitsio.h>

#include <cerrno>
#include <iterator>
#include <string_view>
#include <type_traits>

#include "engine/metacal/metacal_type.hpp"
#include "io/durable_table.hpp"

namespace stampede::io {
namespace {

// A row field as a column's value (its integers exact in a double).
template <auto Field>
double get(const MetadetectRow& r) {
  return static_cast<double>(r.*Field);
}
template <auto Field>
void set(MetadetectRow& r, double v) {
  using T = std::remove_reference_t<decltype(r.*Field)>;
  if constexpr (std::is_integral_v<T>)
    r.*Field = static_cast<T>(static_cast<long long>(v));  // a 32-bit column's bits (flags' high bit too)
  else
    r.*Field = v;
}
template <auto Field>
constexpr MetadetectColumn real(const char* name, const char* unit, const char* comment, bool optional = false) {
  return {name, "1D", unit, comment, get<Field>, set<Field>, optional};
}
template <auto Field>
constexpr MetadetectColumn integer(const char* name, const char* unit, const char* comment, bool optional = false) {
  return {name, "1J", unit, comment, get<Field>, set<Field>, optional};
}

using R = MetadetectRow;
constexpr bool kLater = true;  // columns that tables written before them lack
constexpr MetadetectColumn kFieldColumns[] = {
    integer<&R::id>("id", "", "detection number in its cell and image; -1: the cell failed"),
    real<&R::x>("x", "pixel", "centroid (exp, bd: the fit's), 0-based column of the input image"),
    real<&R::y>("y", "pixel", "centroid (exp, bd: the fit's), 0-based row of the input image"),
    real<&R::u>("u", "arcsec", "x times the pixel scale"),
    real<&R::v>("v", "arcsec", "y times the pixel scale"),
    real<&R::e1>("e1", "", "(Mxx - Myy) / T under the weight; exp, bd: (a - b) / (a + b)"),
    real<&R::e2>("e2", "", "2 Mxy / T"),
    real<&R::e1_err>("e1_err", "", "for white noise of the image's variance"),
    real<&R::e2_err>("e2_err", "", "for white noise of the image's variance"),
    real<&R::t>("T", "arcsec2", "Mxx + Myy (weighted; pgauss: pre-PSF; exp, bd: the model's)"),
    real<&R::t_ratio>("T_ratio", "", "T over the reconvolved PSF's T"),
    real<&R::psf_t>("psf_T", "arcsec2", "the reconvolved PSF's T under the weight"),
    real<&R::flux>("flux", "", "sum of weight x pixel values (exp, bd: the model's flux)"),
    real<&R::snr>("snr", "", "flux over its error"),
    real<&R::mfrac>("mfrac", "", "masked share of a Gaussian (FWHM MFRACFW) about it"),
    integer<&R::box_size>("box_size", "pixel", "the stamp's side"),
    integer<&R::isophotal_area>("isophotal_area", "pixel", "pixels above the detection threshold"),
    integer<&R::sep_flags>("sep_flags", "", "Source Extractor: 1 deblended, 2 on the edge, 8 singular"),
    integer<&R::flags>("flags", "", "1 measurement failed, 2 edge, 4 masked at the detection, 8 cell failed"),
    real<&R::psf_orig_e1>("psf_orig_e1", "", "the cell's PSF's e1 under the weight (its shape bands')", kLater),
    real<&R::psf_orig_e2>("psf_orig_e2", "", "the cell's PSF's e2 under the weight", kLater),
    real<&R::psf_orig_t>("psf_orig_T", "arcsec2", "the cell's PSF's T under the weight", kLater),
    real<&R::psf_rec_e1>("psf_rec_e1", "", "the reconvolved PSF's e1 under the weight", kLater),
    real<&R::psf_rec_e2>("psf_rec_e2", "", "the reconvolved PSF's e2 under the weight", kLater),
    real<&R::x_noshear>("x_noshear", "pixel", "x carried back through the image's metacal shear to the unsheared image",
                        kLater),
    real<&R::y_noshear>("y_noshear", "pixel", "y carried back through the image's metacal shear to the unsheared image",
                        kLater),
    integer<&R::bmask>("bmask", "", "the input's BMASK bits at the unsheared pixel (bands OR'ed)", kLater),
    integer<&R::ormask>("ormask", "", "the input's ORMASK bits at the unsheared pixel (bands OR'ed)", kLater),
};
constexpr int kFirstField = 3;  // FITS column number of the first field column (after cell, shear_type)

DurableTableOptions table_options(const MetadetectWriterOptions& o) {
  DurableTableOptions t;
  static_cast<TableWriterOptions&>(t) = o;
  t.extname = "METADETECT";
  t.columns.push_back({"cell", "1K", "", "cell number in the run (input order)"});
  t.columns.push_back({"shear_type", "7A", "", "metacal image: noshear 1p 1m 2p 2m"});
  for (const MetadetectColumn& c : kFieldColumns) t.columns.push_back({c.name, c.tform, c.unit, c.comment});
  for (const std::string& b : o.bands) t.columns.push_back({"flux_" + b, "1D", "", "band " + b + ": its stamp's flux under the weight"});
  for (const std::string& b : o.bands) t.columns.push_back({"snr_" + b, "1D", "", "band " + b + ": its stamp's flux over its error"});
  t.layout = "metadetect table";
  t.reserved_keys = 2;  // NCELLSW, NROWSW
  t.units = "cells";
  return t;
}

}  // namespace

std::span<const MetadetectColumn> metadetect_field_columns() { return kFieldColumns; }

struct MetadetectWriter::State {
  MetadetectWriterOptions options;
  DurableTable* table = nullptr;  // the writer's
  std::vector<double> f64;
  std::vector<LONGLONG> i64;
  std::vector<int> i32;
  std::vector<char*> strings;

  explicit State(const MetadetectWriterOptions& o) : options(o) {}

  void write_rows(std::span<const MetadetectRow> r) {
    fitsfile* fits = table->fits();
    const auto n = static_cast<LONGLONG>(r.size());
    const LONGLONG first = table->rows() + 1;
    f64.resize(r.size()), i64.resize(r.size()), i32.resize(r.size()), strings.resize(r.size());
    int status = 0;
    errno = 0;
    auto doubles = [&](int col, auto get) {
      for (std::size_t i = 0; i < r.size(); ++i) f64[i] = get(r[i]);
      fits_write_col(fits, TDOUBLE, col, first, 1, n, f64.data(), &status);
    };
    auto ints = [&](int col, auto get) {
      for (std::size_t i = 0; i < r.size(); ++i) i32[i] = static_cast<int>(static_cast<long long>(get(r[i])));
      fits_write_col(fits, TINT, col, first, 1, n, i32.data(), &status);
    };
    for (std::size_t i = 0; i < r.size(); ++i) i64[i] = r[i].cell;
    fits_write_col(fits, TLONGLONG, 1, first, 1, n, i64.data(), &status);
    for (std::size_t i = 0; i < r.size(); ++i)
      strings[i] = const_cast<char*>(metacal_type_name(static_cast<MetacalType>(r[i].shear_type)));
    fits_write_col(fits, TSTRING, 2, first, 1, n, strings.data(), &status);
    int col = kFirstField;
    for (const MetadetectColumn& c : kFieldColumns) {
      if (c.tform[1] == 'J')
        ints(col++, c.get);
      else
        doubles(col++, c.get);
    }
    const int nb = static_cast<int>(options.bands.size());
    for (int b = 0; b < nb; ++b) {
      doubles(col + b, [b](const MetadetectRow& x) { return x.band_flux[static_cast<std::size_t>(b)]; });
      doubles(col + nb + b, [b](const MetadetectRow& x) { return x.band_snr[static_cast<std::size_t>(b)]; });
    }
    table->check(status, "write rows to", errno);
  }
};

MetadetectWriter::MetadetectWriter(const MetadetectWriterOptions& options, bool resume)
    : s_(std::make_unique<State>(options)) {
  open(table_options(options), resume);
  s_->table = &table();
}
MetadetectWriter::~MetadetectWriter() = default;

std::unique_ptr<MetadetectWriter> MetadetectWriter::create(const MetadetectWriterOptions& options) {
  return std::unique_ptr<MetadetectWriter>(new MetadetectWriter(options, false));
}

std::unique_ptr<MetadetectWriter> MetadetectWriter::resume(const MetadetectWriterOptions& options) {
  return std::unique_ptr<MetadetectWriter>(new MetadetectWriter(options, true));
}

void MetadetectWriter::append(std::span<const MetadetectRow> rows, long long cells) {
  State& s = *s_;
  s.table->append(static_cast<long long>(rows.size()), cells, [&] {
    if (!rows.empty()) s.write_rows(rows);
  });
}

void MetadetectWriter::finish() {
  s_->table->finish({{"NCELLSW", units(), "cells whose rows this table holds"},
                     {"NROWSW", rows(), "rows its run wrote (a merge checks none is lost)"}});
}

}  // namespace stampede::io
