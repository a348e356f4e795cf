// The MEDS tile writer; see meds_writer.hpp.
#include "io/meds_writer.hpp"

#include <fitsio.h>

#include <cstdio>
#include <algorithm>
#include <filesystem>

#include "io/fits_error.hpp"

namespace stampede::io {

namespace {

void check(int status, const std::string& path, const char* what) {
  if (status) throw FitsError(std::string("cannot ") + what + " '" + path + "': " + cfitsio_status_text(status));
}

bool integer_type(MedsCutoutType t) {
  return t == MedsCutoutType::kSeg || t == MedsCutoutType::kBmask || t == MedsCutoutType::kOrmask;
}

}  // namespace

struct MedsWriter::State {
  std::string path, partial;
  fitsfile* f = nullptr;
  std::vector<MedsObjectLayout> objects;
  std::vector<std::vector<long long>> start_row;  // per object, per cutout
  std::vector<std::vector<long long>> psf_start_row;
  int psf_hdu = 0;  // 0: no PSF images
  std::vector<int> hdu_of_type = std::vector<int>(kNumMedsCutoutTypes, 0);  // 1-based HDU number; 0 = absent
  std::vector<float> floats;
  std::vector<int> ints;

  // Appends a 1-D array HDU of `length` values named `name`; returns its 1-based HDU number.
  int create_array(bool integer, long long length, const char* name, int* status) {
    long n[1] = {static_cast<long>(std::max<long long>(length, 1))};
    fits_create_img(f, integer ? LONG_IMG : FLOAT_IMG, 1, n, status);
    fits_update_key(f, TSTRING, "EXTNAME", const_cast<char*>(name), nullptr, status);
    int hdu = 0;
    fits_get_hdu_num(f, &hdu);
    return hdu;
  }
  // Writes `values` into array HDU `hdu` from 0-based element `start` (as int32 or float32).
  void write_range(int hdu, long long start, std::span<const double> values, bool integer, const char* what) {
    int status = 0;
    fits_movabs_hdu(f, hdu, nullptr, &status);
    const LONGLONG first = start + 1, n = static_cast<LONGLONG>(values.size());
    if (integer) {
      ints.assign(values.begin(), values.end());
      fits_write_img(f, TINT, first, n, ints.data(), &status);
    } else {
      floats.assign(values.begin(), values.end());
      fits_write_img(f, TFLOAT, first, n, floats.data(), &status);
    }
    check(status, partial, what);
  }
};

MedsWriter::MedsWriter(const std::string& path, std::vector<MedsObjectLayout> objects,
                       const std::vector<MedsImageInfo>& images, const std::vector<MedsCutoutType>& types,
                       const std::vector<std::pair<std::string, std::string>>& primary_keys)
    : s_(std::make_unique<State>()) {
  State& s = *s_;
  s.path = path;
  s.partial = path + ".partial";
  s.objects = std::move(objects);
  std::filesystem::remove(s.partial);
  int status = 0;
  fits_create_file(&s.f, s.partial.c_str(), &status);
  check(status, s.partial, "create the MEDS tile");
  long nmax = 1;
  long long total = 0, psf_total = 0;
  bool with_psf = false;
  for (const MedsObjectLayout& o : s.objects) {
    nmax = std::max<long>(nmax, static_cast<long>(o.cutouts.size()));
    with_psf = with_psf || o.psf_size > 0;
    std::vector<long long> rows, psf_rows;
    for (std::size_t k = 0; k < o.cutouts.size(); ++k) {
      rows.push_back(total);
      total += static_cast<long long>(o.box_size) * o.box_size;
      psf_rows.push_back(psf_total);
      psf_total += static_cast<long long>(o.psf_size) * o.psf_size;
    }
    s.start_row.push_back(std::move(rows));
    s.psf_start_row.push_back(std::move(psf_rows));
  }
  // A primary HDU with no data, then the tables.
  fits_create_img(s.f, BYTE_IMG, 0, nullptr, &status);
  for (const auto& [key, value] : primary_keys)
    fits_write_key(s.f, TSTRING, key.c_str(), const_cast<char*>(value.c_str()), nullptr, &status);
  {
    const std::string n = std::to_string(nmax);
    const std::string k = n + "K", d = n + "D";
    std::vector<std::string> names = {"id", "number", "box_size", "ra", "dec", "ncutout", "file_id", "start_row",
                                      "orig_row", "orig_col", "orig_start_row", "orig_start_col", "cutout_row",
                                      "cutout_col", "dudrow", "dudcol", "dvdrow", "dvdcol"};
    std::vector<std::string> forms = {"1K", "1K", "1K", "1D", "1D", "1K", k, k, d, d, k, k, d, d, d, d, d, d};
    if (with_psf) {
      for (const char* name : {"psf_box_size", "psf_start_row", "psf_cutout_row", "psf_cutout_col"}) names.push_back(name);
      for (const std::string& form : {std::string("1K"), k, d, d}) forms.push_back(form);
    }
    std::vector<char*> tt, tf;
    for (auto& x : names) tt.push_back(x.data());
    for (auto& x : forms) tf.push_back(x.data());
    fits_create_tbl(s.f, BINARY_TBL, 0, static_cast<int>(names.size()), tt.data(), tf.data(), nullptr, "object_data", &status);
    std::vector<long long> iv(static_cast<std::size_t>(nmax));
    std::vector<double> dv(static_cast<std::size_t>(nmax));
    for (std::size_t r = 0; r < s.objects.size(); ++r) {
      const MedsObjectLayout& o = s.objects[r];
      const LONGLONG row = static_cast<LONGLONG>(r) + 1;
      long long scalars[] = {o.id, o.number, o.box_size, 0, 0, static_cast<long long>(o.cutouts.size())};
      for (int c : {1, 2, 3, 6}) fits_write_col(s.f, TLONGLONG, c, row, 1, 1, &scalars[c - 1], &status);
      double ra = o.ra, dec = o.dec;
      fits_write_col(s.f, TDOUBLE, 4, row, 1, 1, &ra, &status);
      fits_write_col(s.f, TDOUBLE, 5, row, 1, 1, &dec, &status);
      auto ints = [&](int col, auto get) {
        std::fill(iv.begin(), iv.end(), 0LL);
        for (std::size_t k = 0; k < o.cutouts.size(); ++k) iv[k] = get(k);
        fits_write_col(s.f, TLONGLONG, col, row, 1, nmax, iv.data(), &status);
      };
      auto doubles = [&](int col, auto get) {
        std::fill(dv.begin(), dv.end(), 0.0);
        for (std::size_t k = 0; k < o.cutouts.size(); ++k) dv[k] = get(o.cutouts[k]);
        fits_write_col(s.f, TDOUBLE, col, row, 1, nmax, dv.data(), &status);
      };
      ints(7, [&](std::size_t k) { return o.cutouts[k].file_id; });
      ints(8, [&](std::size_t k) { return s.start_row[r][k]; });
      doubles(9, [](const MedsCutout& c) { return c.orig_row; });
      doubles(10, [](const MedsCutout& c) { return c.orig_col; });
      ints(11, [&](std::size_t k) { return o.cutouts[k].orig_start_row; });
      ints(12, [&](std::size_t k) { return o.cutouts[k].orig_start_col; });
      doubles(13, [](const MedsCutout& c) { return c.cutout_row; });
      doubles(14, [](const MedsCutout& c) { return c.cutout_col; });
      doubles(15, [](const MedsCutout& c) { return c.dudrow; });
      doubles(16, [](const MedsCutout& c) { return c.dudcol; });
      doubles(17, [](const MedsCutout& c) { return c.dvdrow; });
      doubles(18, [](const MedsCutout& c) { return c.dvdcol; });
      if (with_psf) {
        long long psf_size = o.psf_size;
        fits_write_col(s.f, TLONGLONG, 19, row, 1, 1, &psf_size, &status);
        ints(20, [&](std::size_t k) { return s.psf_start_row[r][k]; });
        doubles(21, [](const MedsCutout& c) { return c.psf_cutout_row; });
        doubles(22, [](const MedsCutout& c) { return c.psf_cutout_col; });
      }
    }
  }
  {
    std::size_t width = 1;
    for (const MedsImageInfo& i : images) width = std::max({width, i.image_path.size(), i.psf_path.size()});
    const std::string a = std::to_string(width) + "A";
    char* tt[] = {const_cast<char*>("image_path"), const_cast<char*>("psf_path"), const_cast<char*>("image_id"),
                  const_cast<char*>("image_flags"), const_cast<char*>("magzp"), const_cast<char*>("scale"),
                  const_cast<char*>("position_offset")};
    char* tf[] = {const_cast<char*>(a.c_str()), const_cast<char*>(a.c_str()), const_cast<char*>("1K"),
                  const_cast<char*>("1K"), const_cast<char*>("1E"), const_cast<char*>("1E"), const_cast<char*>("1D")};
    fits_create_tbl(s.f, BINARY_TBL, 0, 7, tt, tf, nullptr, "image_info", &status);
    for (std::size_t r = 0; r < images.size(); ++r) {
      const MedsImageInfo& i = images[r];
      const LONGLONG row = static_cast<LONGLONG>(r) + 1;
      char* ip = const_cast<char*>(i.image_path.c_str());
      char* pp = const_cast<char*>(i.psf_path.c_str());
      fits_write_col(s.f, TSTRING, 1, row, 1, 1, &ip, &status);
      fits_write_col(s.f, TSTRING, 2, row, 1, 1, &pp, &status);
      long long id = i.image_id, flags = i.image_flags;
      fits_write_col(s.f, TLONGLONG, 3, row, 1, 1, &id, &status);
      fits_write_col(s.f, TLONGLONG, 4, row, 1, 1, &flags, &status);
      double magzp = i.magzp, scale = i.scale, offset = i.position_offset;
      fits_write_col(s.f, TDOUBLE, 5, row, 1, 1, &magzp, &status);
      fits_write_col(s.f, TDOUBLE, 6, row, 1, 1, &scale, &status);
      fits_write_col(s.f, TDOUBLE, 7, row, 1, 1, &offset, &status);
    }
  }
  {
    char* tt[] = {const_cast<char*>("medsconf"), const_cast<char*>("magzp_ref")};
    char* tf[] = {const_cast<char*>("16A"), const_cast<char*>("1D")};
    fits_create_tbl(s.f, BINARY_TBL, 0, 2, tt, tf, nullptr, "metadata", &status);
    char* conf = const_cast<char*>("stampede-sim");
    fits_write_col(s.f, TSTRING, 1, 1, 1, 1, &conf, &status);
    double zp = images.empty() ? 30 : images.front().magzp;
    fits_write_col(s.f, TDOUBLE, 2, 1, 1, 1, &zp, &status);
  }
  check(status, s.partial, "write the tables of");
  std::vector<MedsCutoutType> all = {MedsCutoutType::kImage};
  for (MedsCutoutType t : types)
    if (t != MedsCutoutType::kImage) all.push_back(t);
  for (MedsCutoutType t : all)
    s.hdu_of_type[static_cast<std::size_t>(t)] = s.create_array(integer_type(t), total, meds_hdu_name(t), &status);
  if (with_psf) s.psf_hdu = s.create_array(false, psf_total, "psf", &status);
  check(status, s.partial, "create the cutout arrays of");
}

void MedsWriter::write_psf_cutout(long long row, int icut, std::span<const double> samples) {
  State& s = *s_;
  const MedsObjectLayout& o = s.objects.at(static_cast<std::size_t>(row));
  if (s.psf_hdu == 0 || o.psf_size <= 0) throw std::invalid_argument("MedsWriter: this tile's layout has no PSF images");
  const std::size_t n = static_cast<std::size_t>(o.psf_size) * o.psf_size;
  if (samples.size() != n) throw std::invalid_argument("MedsWriter::write_psf_cutout: not psf_size^2 values");
  s.write_range(s.psf_hdu, s.psf_start_row.at(static_cast<std::size_t>(row)).at(static_cast<std::size_t>(icut)), samples,
                false, "write a PSF cutout to");
}

MedsWriter::~MedsWriter() {
  if (s_->f) {
    int status = 0;
    fits_close_file(s_->f, &status);
    std::filesystem::remove(s_->partial);  // not finished: no tile
  }
}

void MedsWriter::write_cutout(long long row, int icut, MedsCutoutType type, std::span<const double> pixels) {
  State& s = *s_;
  const int hdu = s.hdu_of_type[static_cast<std::size_t>(type)];
  if (hdu == 0) throw std::invalid_argument(std::string("MedsWriter: no HDU '") + meds_hdu_name(type) + "' in this tile");
  const MedsObjectLayout& o = s.objects.at(static_cast<std::size_t>(row));
  const std::size_t n = static_cast<std::size_t>(o.box_size) * o.box_size;
  if (pixels.size() != n) throw std::invalid_argument("MedsWriter::write_cutout: not box_size^2 values");
  s.write_range(hdu, s.start_row.at(static_cast<std::size_t>(row)).at(static_cast<std::size_t>(icut)), pixels,
                integer_type(type), "write a cutout to");
}

void MedsWriter::finish() {
  State& s = *s_;
  int status = 0;
  fits_close_file(s.f, &status);
  s.f = nullptr;
  check(status, s.partial, "close");
  std::filesystem::rename(s.partial, s.path);
}

void write_psfex_constant(const std::string& path, int nx, int ny, std::span<const double> samples, double fwhm) {
  if (samples.size() != static_cast<std::size_t>(nx) * ny) throw std::invalid_argument("write_psfex_constant: not nx * ny samples");
  std::filesystem::remove(path);
  fitsfile* f = nullptr;
  int status = 0;
  fits_create_file(&f, path.c_str(), &status);
  check(status, path, "create the PSFEx model");
  char* ttype[] = {const_cast<char*>("PSF_MASK")};
  const std::string form = std::to_string(nx * ny) + "E";
  char* tform[] = {const_cast<char*>(form.c_str())};
  fits_create_tbl(f, BINARY_TBL, 1, 1, ttype, tform, nullptr, "PSF_DATA", &status);
  auto key_long = [&](const char* k, long v) { fits_update_key(f, TLONG, k, &v, nullptr, &status); };
  auto key_double = [&](const char* k, double v) { fits_update_key(f, TDOUBLE, k, &v, nullptr, &status); };
  auto key_string = [&](const char* k, const char* v) { fits_update_key(f, TSTRING, k, const_cast<char*>(v), nullptr, &status); };
  key_long("POLNAXIS", 2), key_long("POLNGRP", 1), key_long("POLGRP1", 1), key_long("POLGRP2", 1);
  key_long("POLDEG1", 0), key_long("PSFNAXIS", 3);
  key_string("POLNAME1", "X_IMAGE"), key_string("POLNAME2", "Y_IMAGE");
  key_double("POLZERO1", 0), key_double("POLZERO2", 0), key_double("POLSCAL1", 1), key_double("POLSCAL2", 1);
  key_double("PSF_SAMP", 1.0), key_double("PSF_FWHM", fwhm);
  key_long("PSFAXIS1", nx), key_long("PSFAXIS2", ny), key_long("PSFAXIS3", 1);
  std::vector<float> cube(samples.begin(), samples.end());
  fits_write_col(f, TFLOAT, 1, 1, 1, static_cast<LONGLONG>(cube.size()), cube.data(), &status);
  fits_close_file(f, &status);
  check(status, path, "write the PSFEx model");
}

}  // namespace stampede::io
