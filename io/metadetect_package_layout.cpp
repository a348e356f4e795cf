// The reference package's layout; see metadetect_package_layout.hpp.
#include "io/metadetect_package_layout.hpp"

#include <fitsio.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "engine/metacal/metacal_type.hpp"
#include "io/durable_file.hpp"
#include "io/fits_error.hpp"

namespace stampede::io {
namespace {

constexpr int kMaxPackageBands = 6;  // the package's MAX_NUM_SHEAR_BANDS: its index strings are U6

using Type = PackageColumn::Type;
using Values = std::function<void(const MetadetectRow&, std::span<double>)>;

Values scalar(double (*get)(const MetadetectRow&)) {
  return [get](const MetadetectRow& r, std::span<double> out) { out[0] = get(r); };
}

void check(int status, const std::string& path, const char* what) {
  if (status) throw FitsError(std::string("cannot ") + what + " '" + path + "': " + cfitsio_status_text(status));
}

}  // namespace

int PackageColumn::count() const {
  if (type == Type::kText) return 1;
  return std::accumulate(shape.begin(), shape.end(), 1, std::multiplies<>());
}

std::string package_band_indices(std::uint32_t mask, int bands) {
  std::string s;
  for (int b = 0; b < bands && b < kMaxPackageBands; ++b)
    if (mask == 0 || (mask >> b & 1u)) s += static_cast<char>('0' + b);
  return s;
}

std::vector<PackageColumn> package_columns(const PackageLayoutOptions& o) {
  const std::string& m = o.measurement;
  const int nb = o.bands;
  std::vector<int> band_shape;
  if (nb > 1) band_shape = {nb};
  constexpr std::uint32_t kObjectFlags = kMetadetectMomentsFailed | kMetadetectEdge | kMetadetectMasked;
  std::vector<PackageColumn> c;
  c.push_back({"cell", Type::kInt64, {}, "stampede: the cell's number in the run",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.cell); })});
  c.push_back({"id", Type::kInt32, {}, "stampede: the detection's number in its cell and image; -1 the cell failed",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.id); })});
  c.push_back({m + "_flags", Type::kInt32, {}, "stampede's flags: 1 measurement, 2 edge, 4 masked, 8 cell failed",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.flags); })});
  c.push_back({m + "_psf_flags", Type::kInt32, {}, "8: the cell failed (its PSF, or nothing to detect)",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.flags & kMetadetectCellFailed); })});
  c.push_back({m + "_psf_g", Type::kFloat64, {2}, "the reconvolved PSF's e under the weight",
               [](const MetadetectRow& r, std::span<double> v) { v[0] = r.psf_rec_e1, v[1] = r.psf_rec_e2; }});
  c.push_back({m + "_psf_T", Type::kFloat64, {}, "the reconvolved PSF's T under the weight, arcsec2",
               scalar([](const MetadetectRow& r) { return r.psf_t; })});
  c.push_back({m + "_obj_flags", Type::kInt32, {}, "flags 1, 2, 4 (measurement, edge, masked)",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.flags & kObjectFlags); })});
  c.push_back({m + "_s2n", Type::kFloat64, {}, "flux over its error",
               scalar([](const MetadetectRow& r) { return r.snr; })});
  c.push_back({m + "_g", Type::kFloat64, {2}, "e1, e2 (moments: (Mxx - Myy) / T, 2 Mxy / T; fits: the model's)",
               [](const MetadetectRow& r, std::span<double> v) { v[0] = r.e1, v[1] = r.e2; }});
  c.push_back({m + "_g_cov", Type::kFloat64, {2, 2}, "diagonal: e1_err^2, e2_err^2 (the covariance is not measured)",
               [](const MetadetectRow& r, std::span<double> v) {
                 v[0] = r.e1_err * r.e1_err, v[1] = v[2] = r.e1_err == r.e1_err && r.e2_err == r.e2_err ? 0.0 : NAN;
                 v[3] = r.e2_err * r.e2_err;
               }});
  c.push_back({m + "_T", Type::kFloat64, {}, "T, arcsec2", scalar([](const MetadetectRow& r) { return r.t; })});
  c.push_back({m + "_T_flags", Type::kInt32, {}, "1: the measurement failed",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.flags & kMetadetectMomentsFailed); })});
  c.push_back({m + "_T_err", Type::kFloat64, {}, "not measured (NaN)", scalar([](const MetadetectRow&) -> double { return NAN; })});
  c.push_back({m + "_T_ratio", Type::kFloat64, {}, "T over the reconvolved PSF's T",
               scalar([](const MetadetectRow& r) { return r.t_ratio; })});
  c.push_back({m + "_band_flux_flags", Type::kInt32, band_shape, "1: the measurement failed",
               [nb](const MetadetectRow& r, std::span<double> v) {
                 for (int b = 0; b < nb; ++b) v[b] = static_cast<double>(r.flags & kMetadetectMomentsFailed);
               }});
  c.push_back({m + "_band_flux", Type::kFloat64, band_shape, "each band's flux under the weight",
               [nb](const MetadetectRow& r, std::span<double> v) {
                 for (int b = 0; b < nb; ++b) v[b] = r.band_flux[static_cast<std::size_t>(b)];
                 if (nb == 1 && std::isnan(v[0])) v[0] = r.flux;
               }});
  c.push_back({m + "_band_flux_err", Type::kFloat64, band_shape, "each band's flux over its S/N",
               [nb](const MetadetectRow& r, std::span<double> v) {
                 for (int b = 0; b < nb; ++b) {
                   const auto k = static_cast<std::size_t>(b);
                   v[b] = r.band_flux[k] / r.band_snr[k];
                 }
                 if (nb == 1 && std::isnan(v[0])) v[0] = r.flux / r.snr;
               }});
  c.push_back({"shear_bands", Type::kText, {kMaxPackageBands}, "the shape bands' indices", {}, o.shear_bands});
  c.push_back({"sx_row", Type::kFloat32, {}, "y, 0-based pixels of the input image",
               scalar([](const MetadetectRow& r) { return r.y; })});
  c.push_back({"sx_col", Type::kFloat32, {}, "x, 0-based pixels of the input image",
               scalar([](const MetadetectRow& r) { return r.x; })});
  c.push_back({"sx_row_noshear", Type::kFloat32, {}, "y carried back through the metacal shear",
               scalar([](const MetadetectRow& r) { return r.y_noshear; })});
  c.push_back({"sx_col_noshear", Type::kFloat32, {}, "x carried back through the metacal shear",
               scalar([](const MetadetectRow& r) { return r.x_noshear; })});
  c.push_back({"ormask", Type::kInt32, {}, "ORMASK bits at the unsheared pixel",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.ormask); })});
  c.push_back({"mfrac", Type::kFloat32, {}, "masked share of a Gaussian about the detection",
               scalar([](const MetadetectRow& r) { return r.mfrac; })});
  c.push_back({"bmask", Type::kInt32, {}, "BMASK bits at the unsheared pixel",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.bmask); })});
  c.push_back({"ormask_noshear", Type::kInt32, {}, "ORMASK bits at the unsheared pixel",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.ormask); })});
  c.push_back({"bmask_noshear", Type::kInt32, {}, "BMASK bits at the unsheared pixel",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.bmask); })});
  c.push_back({"det_bands", Type::kText, {kMaxPackageBands}, "the detection bands' indices", {}, o.det_bands});
  c.push_back({"psfrec_flags", Type::kInt32, {}, "8: the cell failed",
               scalar([](const MetadetectRow& r) { return static_cast<double>(r.flags & kMetadetectCellFailed); })});
  c.push_back({"psfrec_g", Type::kFloat64, {2}, "the original PSF's e under the weight (the shape bands')",
               [](const MetadetectRow& r, std::span<double> v) { v[0] = r.psf_orig_e1, v[1] = r.psf_orig_e2; }});
  c.push_back({"psfrec_T", Type::kFloat64, {}, "the original PSF's T under the weight, arcsec2",
               scalar([](const MetadetectRow& r) { return r.psf_orig_t; })});
  return c;
}

std::vector<std::vector<const MetadetectRow*>> rows_by_shear_type(std::span<const MetadetectRow> rows) {
  std::vector<std::vector<const MetadetectRow*>> by(kNumMetacalTypes);
  for (const MetadetectRow& r : rows)
    if (r.shear_type >= 0 && r.shear_type < kNumMetacalTypes) by[static_cast<std::size_t>(r.shear_type)].push_back(&r);
  return by;
}

void write_package_layout(const std::string& path, MetadetectRowReader& reader, const PackageLayoutOptions& options,
                          const std::vector<std::pair<std::string, std::string>>& primary_keys) {
  const std::string partial = path + ".partial";
  std::error_code ignored;
  std::filesystem::remove(partial, ignored);
  fitsfile* f = nullptr;
  int status = 0;
  // A disk file by its name as given: none of CFITSIO's extended file-name syntax.
  fits_create_diskfile(&f, partial.c_str(), &status);
  check(status, partial, "create");
  struct Closer {
    fitsfile* f;
    ~Closer() {
      int s = 0;
      if (f) fits_close_file(f, &s);
    }
  } closer{f};
  fits_create_img(f, BYTE_IMG, 0, nullptr, &status);
  for (const auto& [key, value] : primary_keys)
    fits_write_key(f, TSTRING, key.c_str(), const_cast<char*>(value.c_str()), nullptr, &status);
  check(status, partial, "write the primary header of");
  const std::vector<PackageColumn> columns = package_columns(options);
  std::vector<std::string> names, forms;
  for (const PackageColumn& c : columns) {
    names.push_back(c.name);
    const char code = c.type == Type::kFloat64   ? 'D'
                      : c.type == Type::kFloat32 ? 'E'
                      : c.type == Type::kInt32   ? 'J'
                      : c.type == Type::kInt64   ? 'K'
                                                 : 'A';
    forms.push_back(std::to_string(c.type == Type::kText ? c.shape[0] : c.count()) + code);
  }
  std::vector<char*> ttype, tform;
  for (std::size_t i = 0; i < columns.size(); ++i) ttype.push_back(names[i].data()), tform.push_back(forms[i].data());
  // Each shear type's table in turn, from the rows read in chunks: memory bounded by the chunk.
  constexpr std::size_t kChunk = 65536;
  std::vector<MetadetectRow> chunk;
  std::vector<const MetadetectRow*> in;
  std::vector<double> values;
  std::vector<char*> texts;
  for (int t = 0; t < kNumMetacalTypes; ++t) {
    char* extname = const_cast<char*>(metacal_type_name(kMetacalTypes[static_cast<std::size_t>(t)]));
    fits_create_tbl(f, BINARY_TBL, 0, static_cast<int>(columns.size()), ttype.data(), tform.data(), nullptr, extname,
                    &status);
    for (std::size_t i = 0; i < columns.size(); ++i) {
      const int col = static_cast<int>(i) + 1;
      if (!columns[i].comment.empty()) {
        const std::string key = "TCOMM" + std::to_string(col);
        fits_write_key(f, TSTRING, key.c_str(), const_cast<char*>(columns[i].comment.c_str()), nullptr, &status);
      }
      if (columns[i].shape.size() == 2 && columns[i].type != Type::kText) {
        long dims[2] = {columns[i].shape[1], columns[i].shape[0]};  // FITS's first axis varies fastest
        fits_write_tdim(f, col, 2, dims, &status);
      }
    }
    check(status, partial, "write the package-layout table headers of");
    LONGLONG written = 0;
    for (long long first = 0; first < reader.rows(); first += static_cast<long long>(kChunk)) {
      reader.read(first, static_cast<std::size_t>(std::min<long long>(static_cast<long long>(kChunk), reader.rows() - first)),
                  &chunk);
      in.clear();
      for (const MetadetectRow& r : chunk)
        if (r.shear_type == t) in.push_back(&r);
      if (in.empty()) continue;
      const auto n = static_cast<LONGLONG>(in.size());
      for (std::size_t i = 0; i < columns.size(); ++i) {
        const PackageColumn& c = columns[i];
        const int col = static_cast<int>(i) + 1;
        if (c.type == Type::kText) {
          texts.assign(in.size(), const_cast<char*>(c.text.c_str()));
          fits_write_col(f, TSTRING, col, written + 1, 1, n, texts.data(), &status);
          continue;
        }
        const auto k = static_cast<std::size_t>(c.count());
        values.resize(in.size() * k);
        for (std::size_t r = 0; r < in.size(); ++r) c.values(*in[r], std::span<double>(values).subspan(r * k, k));
        fits_write_col(f, TDOUBLE, col, written + 1, 1, n * static_cast<LONGLONG>(k), values.data(), &status);
      }
      written += n;
      check(status, partial, "write the package-layout rows of");
    }
  }
  closer.f = nullptr;
  fits_close_file(f, &status);
  check(status, partial, "close");
  {
    DurableFile done = DurableFile::open(partial, DurableFile::Mode::kRead);
    done.sync();
  }
  std::filesystem::rename(partial, path);
  sync_directory_of(path);
}

}  // namespace stampede::io
