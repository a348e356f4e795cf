// The metadetection catalogue; see metadetect_writer.hpp.
#include "io/metadetect_writer.hpp"

#include <fitsio.h>

#include <cerrno>
#include <iterator>
#include <string_view>

#include "engine/metacal/metacal_type.hpp"
#include "io/durable_table.hpp"

namespace stampede::io {
namespace {

struct Column {
  const char* name;
  const char* tform;
  const char* unit;
  const char* comment;
};

constexpr Column kColumns[] = {
    {"cell", "1K", "", "cell number in the run (input order)"},
    {"shear_type", "7A", "", "metacal image: noshear 1p 1m 2p 2m"},
    {"id", "1J", "", "detection number in its cell and image; -1: the cell failed"},
    {"x", "1D", "pixel", "centroid (exp, bd: the fit's), 0-based column of the input image"},
    {"y", "1D", "pixel", "centroid (exp, bd: the fit's), 0-based row of the input image"},
    {"u", "1D", "arcsec", "x times the pixel scale"},
    {"v", "1D", "arcsec", "y times the pixel scale"},
    {"e1", "1D", "", "(Mxx - Myy) / T under the weight; exp, bd: (a - b) / (a + b)"},
    {"e2", "1D", "", "2 Mxy / T"},
    {"e1_err", "1D", "", "for white noise of the image's variance"},
    {"e2_err", "1D", "", "for white noise of the image's variance"},
    {"T", "1D", "arcsec2", "Mxx + Myy (weighted; pgauss: pre-PSF; exp, bd: the model's)"},
    {"T_ratio", "1D", "", "T over the reconvolved PSF's T"},
    {"psf_T", "1D", "arcsec2", "the reconvolved PSF's T under the weight"},
    {"flux", "1D", "", "sum of weight x pixel values (exp, bd: the model's flux)"},
    {"snr", "1D", "", "flux over its error"},
    {"mfrac", "1D", "", "masked share of a Gaussian (FWHM MFRACFW) about it"},
    {"box_size", "1J", "pixel", "the stamp's side"},
    {"isophotal_area", "1J", "pixel", "pixels above the detection threshold"},
    {"sep_flags", "1J", "", "Source Extractor: 1 deblended, 2 on the edge, 8 singular"},
    {"flags", "1J", "", "1 measurement failed, 2 edge, 4 masked at the detection, 8 cell failed"},
    {"psf_orig_e1", "1D", "", "the cell's PSF's e1 under the weight (its shape bands')"},
    {"psf_orig_e2", "1D", "", "the cell's PSF's e2 under the weight"},
    {"psf_orig_T", "1D", "arcsec2", "the cell's PSF's T under the weight"},
    {"psf_rec_e1", "1D", "", "the reconvolved PSF's e1 under the weight"},
    {"psf_rec_e2", "1D", "", "the reconvolved PSF's e2 under the weight"},
    {"x_noshear", "1D", "pixel", "x carried back through the image's metacal shear to the unsheared image"},
    {"y_noshear", "1D", "pixel", "y carried back through the image's metacal shear to the unsheared image"},
    {"bmask", "1J", "", "the input's BMASK bits at the unsheared pixel (bands OR'ed)"},
    {"ormask", "1J", "", "the input's ORMASK bits at the unsheared pixel (bands OR'ed)"},
};
constexpr int kNumColumns = static_cast<int>(std::size(kColumns));

DurableTableOptions table_options(const MetadetectWriterOptions& o) {
  DurableTableOptions t;
  static_cast<TableWriterOptions&>(t) = o;
  t.extname = "METADETECT";
  for (const Column& c : kColumns) t.columns.push_back({c.name, c.tform, c.unit, c.comment});
  for (const std::string& b : o.bands) t.columns.push_back({"flux_" + b, "1D", "", "band " + b + ": its stamp's flux under the weight"});
  for (const std::string& b : o.bands) t.columns.push_back({"snr_" + b, "1D", "", "band " + b + ": its stamp's flux over its error"});
  t.layout = "metadetect table";
  t.reserved_keys = 2;  // NCELLSW, NROWSW
  t.units = "cells";
  return t;
}

}  // namespace

std::vector<std::string> metadetect_columns(const std::vector<std::string>& bands) {
  std::vector<std::string> out;
  for (const Column& c : kColumns) out.emplace_back(c.name);
  for (const std::string& b : bands) out.push_back("flux_" + b);
  for (const std::string& b : bands) out.push_back("snr_" + b);
  return out;
}

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
      for (std::size_t i = 0; i < r.size(); ++i) i32[i] = static_cast<int>(get(r[i]));
      fits_write_col(fits, TINT, col, first, 1, n, i32.data(), &status);
    };
    for (std::size_t i = 0; i < r.size(); ++i) i64[i] = r[i].cell;
    fits_write_col(fits, TLONGLONG, 1, first, 1, n, i64.data(), &status);
    for (std::size_t i = 0; i < r.size(); ++i)
      strings[i] = const_cast<char*>(metacal_type_name(static_cast<MetacalType>(r[i].shear_type)));
    fits_write_col(fits, TSTRING, 2, first, 1, n, strings.data(), &status);
    ints(3, [](const MetadetectRow& x) { return x.id; });
    doubles(4, [](const MetadetectRow& x) { return x.x; });
    doubles(5, [](const MetadetectRow& x) { return x.y; });
    doubles(6, [](const MetadetectRow& x) { return x.u; });
    doubles(7, [](const MetadetectRow& x) { return x.v; });
    doubles(8, [](const MetadetectRow& x) { return x.e1; });
    doubles(9, [](const MetadetectRow& x) { return x.e2; });
    doubles(10, [](const MetadetectRow& x) { return x.e1_err; });
    doubles(11, [](const MetadetectRow& x) { return x.e2_err; });
    doubles(12, [](const MetadetectRow& x) { return x.t; });
    doubles(13, [](const MetadetectRow& x) { return x.t_ratio; });
    doubles(14, [](const MetadetectRow& x) { return x.psf_t; });
    doubles(15, [](const MetadetectRow& x) { return x.flux; });
    doubles(16, [](const MetadetectRow& x) { return x.snr; });
    doubles(17, [](const MetadetectRow& x) { return x.mfrac; });
    ints(18, [](const MetadetectRow& x) { return x.box_size; });
    ints(19, [](const MetadetectRow& x) { return x.isophotal_area; });
    ints(20, [](const MetadetectRow& x) { return x.sep_flags; });
    ints(21, [](const MetadetectRow& x) { return x.flags; });
    doubles(22, [](const MetadetectRow& x) { return x.psf_orig_e1; });
    doubles(23, [](const MetadetectRow& x) { return x.psf_orig_e2; });
    doubles(24, [](const MetadetectRow& x) { return x.psf_orig_t; });
    doubles(25, [](const MetadetectRow& x) { return x.psf_rec_e1; });
    doubles(26, [](const MetadetectRow& x) { return x.psf_rec_e2; });
    doubles(27, [](const MetadetectRow& x) { return x.x_noshear; });
    doubles(28, [](const MetadetectRow& x) { return x.y_noshear; });
    ints(29, [](const MetadetectRow& x) { return x.bmask; });
    ints(30, [](const MetadetectRow& x) { return x.ormask; });
    const int nb = static_cast<int>(options.bands.size());
    for (int b = 0; b < nb; ++b) {
      doubles(kNumColumns + 1 + b, [b](const MetadetectRow& x) { return x.band_flux[static_cast<std::size_t>(b)]; });
      doubles(kNumColumns + 1 + nb + b, [b](const MetadetectRow& x) { return x.band_snr[static_cast<std::size_t>(b)]; });
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
