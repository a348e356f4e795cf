// MEDS tiles read object by object; see meds_file.hpp.
#include "io/meds_file.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "engine/common/number_text.hpp"

namespace stampede::io {
namespace {

constexpr const char* kHduNames[kNumMedsCutoutTypes] = {"image_cutouts", "weight_cutouts", "seg_cutouts",
                                                        "bmask_cutouts", "noise_cutouts", "ormask_cutouts",
                                                        "mfrac_cutouts"};
// Per-cutout columns, [NMAX] each: integers first, then doubles (the order of the scratch rows).
constexpr const char* kCutoutInts[] = {"file_id", "start_row", "orig_start_row", "orig_start_col"};
constexpr const char* kCutoutDoubles[] = {"orig_row", "orig_col", "cutout_row", "cutout_col",
                                          "dudrow",   "dudcol",   "dvdrow",     "dvdcol"};
constexpr int kNumInts = 4, kNumDoubles = 8;
// Larger boxes are not cutouts of galaxies but corrupt rows; this also keeps box^2 far from overflow.
constexpr long long kMaxBoxSize = 16384;

// "'start_row'[2]"; built by appending (GCC 12 warns falsely on "'" + std::string(...)).
std::string with_index(const char* column, int icut) {
  std::string s(1, '\'');
  s.append(column).append("'[").append(std::to_string(icut)).push_back(']');
  return s;
}

}  // namespace

const char* meds_hdu_name(MedsCutoutType type) { return kHduNames[static_cast<int>(type)]; }

MedsFile MedsFile::open(const std::string& path) {
  MedsFile m(FitsFile::open_read(path), path);
  FitsFile& f = m.file_;
  for (const char* required : {"object_data", "image_info", "image_cutouts"})
    if (!f.move_to_if_present(required))
      throw FitsError(path + ": not a MEDS file: no HDU '" + required +
                      "' (a MEDS tile has object_data, image_info and image_cutouts)");
  // The flat cutout arrays.
  for (int t = 0; t < kNumMedsCutoutTypes; ++t) {
    m.length_[t] = -1;
    if (f.move_to_if_present(kHduNames[t])) {
      m.length_[t] = f.image_length();
      m.hdu_[t] = f.hdu_index();
    }
  }
  // image_info: small (one row per source image), read whole.
  f.move_to("image_info");
  const long long n_images = f.table_rows();
  if (n_images < 1) throw FitsError(f.describe() + ": no rows (a MEDS tile lists at least one source image)");
  if (n_images > 10000000) throw FitsError(f.describe() + ": " + std::to_string(n_images) + " rows is not a tile's image list");
  const bool has_psf_path = f.has_column("psf_path"), has_scale = f.has_column("scale"),
             has_offset = f.has_column("position_offset"), has_id = f.has_column("image_id"),
             has_flags = f.has_column("image_flags");
  const std::vector<double> magzp = f.read_column("magzp");
  std::vector<double> scale, offset;
  if (has_scale) scale = f.read_column("scale");
  if (has_offset) offset = f.read_column("position_offset");
  std::vector<long long> ids(static_cast<std::size_t>(n_images)), flags(static_cast<std::size_t>(n_images));
  if (has_id) f.read_column_rows("image_id", 0, ids);
  if (has_flags) f.read_column_rows("image_flags", 0, flags);
  m.images_.resize(static_cast<std::size_t>(n_images));
  for (long long i = 0; i < n_images; ++i) {
    MedsImageInfo& info = m.images_[static_cast<std::size_t>(i)];
    info.image_path = f.read_string("image_path", i);
    if (has_psf_path) info.psf_path = f.read_string("psf_path", i);
    info.magzp = magzp[static_cast<std::size_t>(i)];
    if (has_scale) info.scale = scale[static_cast<std::size_t>(i)];
    if (has_offset) info.position_offset = offset[static_cast<std::size_t>(i)];
    info.image_id = ids[static_cast<std::size_t>(i)];
    info.image_flags = flags[static_cast<std::size_t>(i)];
  }
  // object_data: the columns and their common NMAX; rows are read on demand.
  f.move_to("object_data");
  m.object_hdu_ = f.hdu_index();
  m.n_objects_ = f.table_rows();
  for (const char* scalar : {"id", "number", "box_size", "ra", "dec", "ncutout"})
    if (f.column_repeat(scalar) != 1)
      throw FitsError(f.describe() + ": column '" + scalar + "' has " + std::to_string(f.column_repeat(scalar)) +
                      " values per row; MEDS has one");
  {  // an id names one object: a tile that repeats one cannot be matched, merged or resumed by id
    std::vector<long long> ids(static_cast<std::size_t>(m.n_objects_));
    f.read_column_rows("id", 0, ids);
    std::vector<std::pair<long long, long long>> sorted;
    sorted.reserve(ids.size());
    for (std::size_t i = 0; i < ids.size(); ++i) sorted.emplace_back(ids[i], static_cast<long long>(i));
    std::sort(sorted.begin(), sorted.end());
    for (std::size_t i = 1; i < sorted.size(); ++i)
      if (sorted[i].first == sorted[i - 1].first)
        throw FitsError(f.describe() + ": column 'id' holds " + std::to_string(sorted[i].first) + " in rows " +
                        std::to_string(sorted[i - 1].second) + " and " + std::to_string(sorted[i].second) +
                        " (0-based); each object needs its own id");
  }
  long long nmax = -1;
  for (const char* const* names : {kCutoutInts, kCutoutDoubles}) {
    const int n = names == kCutoutInts ? kNumInts : kNumDoubles;
    for (int c = 0; c < n; ++c) {
      const long long repeat = f.column_repeat(names[c]);
      if (nmax < 0) nmax = repeat;
      if (repeat != nmax)
        throw FitsError(f.describe() + ": column '" + names[c] + "' has " + std::to_string(repeat) +
                        " values per row but 'file_id' has " + std::to_string(nmax) + " (all per-cutout columns hold NMAX)");
    }
  }
  if (nmax > 100000) throw FitsError(f.describe() + ": NMAX = " + std::to_string(nmax) + " cutouts per object is not a tile's");
  m.nmax_ = static_cast<int>(nmax);
  m.find_psf_cutouts();
  m.ints_.resize(static_cast<std::size_t>(kNumInts * nmax));
  m.doubles_.resize(static_cast<std::size_t>(kNumDoubles * nmax));
  return m;
}

void MedsFile::find_psf_cutouts() {
  FitsFile& f = file_;
  if (!f.move_to_if_present("psf")) {
    psf_problem_ = path_ + ": no HDU 'psf' (the tile has no PSF cutouts)";
    f.move_to(object_hdu_);
    return;
  }
  psf_hdu_ = f.hdu_index();
  psf_length_ = f.image_length();
  f.move_to(object_hdu_);
  const bool square = f.has_column("psf_box_size");
  psf_columns_ = {"psf_start_row", "psf_cutout_row", "psf_cutout_col", square ? "psf_box_size" : "psf_row_size",
                  square ? "psf_box_size" : "psf_col_size"};
  for (std::size_t c = 0; c < psf_columns_.size(); ++c) {
    if (!f.has_column(psf_columns_[c])) {
      psf_problem_ = f.describe() + ": HDU 'psf' is present but there is no column '" + psf_columns_[c] + "'" +
                     (c >= 3 ? " (nor 'psf_box_size')" : "");
      return;
    }
    psf_repeat_[c] = f.column_repeat(psf_columns_[c]);
    if (psf_repeat_[c] != 1 && psf_repeat_[c] != nmax_) {
      psf_problem_ = f.describe() + ": column '" + psf_columns_[c] + "' has " + std::to_string(psf_repeat_[c]) +
                     " values per row: one per object or NMAX = " + std::to_string(nmax_);
      return;
    }
  }
  psf_problem_.clear();
  psf_scratch_.resize(static_cast<std::size_t>(nmax_));
}

void MedsFile::read_psf_columns(MedsObject& o) {
  const std::size_t n = o.cutouts.size();
  std::array<std::vector<double>, 5> values;
  for (std::size_t c = 0; c < psf_columns_.size(); ++c) {
    std::span<double> out(psf_scratch_.data(), static_cast<std::size_t>(psf_repeat_[c]));
    file_.read_vector_rows(psf_columns_[c], o.row, out);
    values[c].assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) values[c][i] = psf_repeat_[c] == 1 ? out[0] : out[i];
  }
  constexpr long long kMaxPsfSide = 1024;
  for (std::size_t i = 0; i < n; ++i) {
    MedsCutout& c = o.cutouts[i];
    const std::string where = describe_object(o) + ", cutout " + std::to_string(i) + ": ";
    const double start = values[0][i], rows = values[3][i], cols = values[4][i];
    c.psf_cutout_row = values[1][i], c.psf_cutout_col = values[2][i];
    if (!(rows >= 1 && rows <= kMaxPsfSide && cols >= 1 && cols <= kMaxPsfSide) || rows != std::floor(rows) ||
        cols != std::floor(cols)) {
      c.psf_problem = where + "columns '" + psf_columns_[3] + "', '" + psf_columns_[4] + "' = " + std::to_string(rows) +
                      ", " + std::to_string(cols) + " are not a PSF image's size (1.." + std::to_string(kMaxPsfSide) + ")";
      continue;
    }
    c.psf_rows = static_cast<long long>(rows), c.psf_cols = static_cast<long long>(cols);
    if (!(start >= 0) || start != std::floor(start) || start > static_cast<double>(psf_length_ - c.psf_rows * c.psf_cols)) {
      c.psf_problem = where + "column " + with_index("psf_start_row", static_cast<int>(i)) + " = " + std::to_string(start) +
                      " with " + std::to_string(c.psf_rows * c.psf_cols) + " samples runs past the " +
                      std::to_string(psf_length_) + " of HDU 'psf'";
      continue;
    }
    c.psf_start_row = static_cast<long long>(start);
    if (!std::isfinite(c.psf_cutout_row) || !std::isfinite(c.psf_cutout_col))
      c.psf_problem = where + "columns 'psf_cutout_row', 'psf_cutout_col' are not finite";
  }
}

void MedsFile::read_psf_cutout(const MedsObject& object, int icut, std::span<double> out) {
  if (!psf_problem_.empty()) throw FitsError(psf_problem_);
  if (!object.problem.empty() || icut < 0 || icut >= static_cast<int>(object.cutouts.size()) ||
      !object.cutouts[static_cast<std::size_t>(icut)].psf_problem.empty())
    throw FitsError(path_ + ": object " + std::to_string(object.row) + " has no usable PSF cutout " + std::to_string(icut));
  const MedsCutout& c = object.cutouts[static_cast<std::size_t>(icut)];
  if (out.size() != static_cast<std::size_t>(c.psf_rows * c.psf_cols))
    throw FitsError(path_ + ": read_psf_cutout: output holds " + std::to_string(out.size()) + " values, not the PSF's");
  file_.move_to(psf_hdu_);
  file_.read_image_range(c.psf_start_row, out);
}

std::string MedsFile::describe_object(const MedsObject& o) {
  return file_.describe() + ": object " + std::to_string(o.row) + " (id " + std::to_string(o.id) + ")";
}

void MedsFile::read_ids(long long first, std::span<long long> out) {
  file_.move_to(object_hdu_);
  file_.read_column_rows("id", first, out);
}

void MedsFile::read_positions(long long first, std::span<double> ra, std::span<double> dec) {
  file_.move_to(object_hdu_);
  file_.read_column_rows("ra", first, ra);
  file_.read_column_rows("dec", first, dec);
}

MedsObject MedsFile::object(long long row) {
  file_.move_to(object_hdu_);
  if (row < 0 || row >= n_objects_)
    throw FitsError(file_.describe() + ": no object " + std::to_string(row) + " (the table has " +
                    std::to_string(n_objects_) + " rows)");
  MedsObject o;
  o.row = row;
  long long v = 0;
  std::span<long long> one(&v, 1);
  file_.read_column_rows("id", row, one), o.id = v;
  file_.read_column_rows("number", row, one), o.number = v;
  file_.read_column_rows("box_size", row, one), o.box_size = v;
  file_.read_column_rows("ncutout", row, one);
  const long long ncutout = v;
  double d = 0;
  file_.read_column_rows("ra", row, std::span<double>(&d, 1)), o.ra = d;
  file_.read_column_rows("dec", row, std::span<double>(&d, 1)), o.dec = d;
  if (o.box_size < 1 || o.box_size > kMaxBoxSize) {
    o.problem = describe_object(o) + ": column 'box_size' = " + std::to_string(o.box_size) + " is not a cutout size (1.." +
                std::to_string(kMaxBoxSize) + ")";
    return o;
  }
  if (ncutout < 0 || ncutout > nmax_) {
    o.problem = describe_object(o) + ": column 'ncutout' = " + std::to_string(ncutout) + " is outside 0.." +
                std::to_string(nmax_) + " (NMAX)";
    return o;
  }
  const std::size_t n = static_cast<std::size_t>(nmax_);
  for (int c = 0; c < kNumInts; ++c)
    file_.read_vector_rows(kCutoutInts[c], row, std::span<long long>(ints_).subspan(c * n, n));
  for (int c = 0; c < kNumDoubles; ++c)
    file_.read_vector_rows(kCutoutDoubles[c], row, std::span<double>(doubles_).subspan(c * n, n));
  const long long pixels = o.box_size * o.box_size;
  o.cutouts.resize(static_cast<std::size_t>(ncutout));
  for (int i = 0; i < ncutout; ++i) {
    MedsCutout& c = o.cutouts[static_cast<std::size_t>(i)];
    auto integer = [&](int col) { return ints_[col * n + static_cast<std::size_t>(i)]; };
    auto real = [&](int col) { return doubles_[col * n + static_cast<std::size_t>(i)]; };
    c.file_id = integer(0);
    c.start_row = integer(1);
    c.orig_start_row = integer(2);
    c.orig_start_col = integer(3);
    c.orig_row = real(0), c.orig_col = real(1), c.cutout_row = real(2), c.cutout_col = real(3);
    c.dudrow = real(4), c.dudcol = real(5), c.dvdrow = real(6), c.dvdcol = real(7);
    const std::string where = describe_object(o) + ", cutout " + std::to_string(i) + ": ";
    if (c.file_id < 0 || c.file_id >= static_cast<long long>(images_.size())) {
      c.problem = where + "column " + with_index("file_id", i) + " = " + std::to_string(c.file_id) +
                  " is not a row of image_info (0.." + std::to_string(images_.size() - 1) + ")";
      continue;
    }
    for (int t = 0; t < kNumMedsCutoutTypes && c.problem.empty(); ++t) {
      if (length_[t] < 0) continue;
      if (c.start_row < 0 || c.start_row > length_[t] - pixels)
        c.problem = where + "column " + with_index("start_row", i) + " = " + std::to_string(c.start_row) +
                    " with box_size^2 = " + std::to_string(pixels) + " runs past the " + std::to_string(length_[t]) +
                    " pixels of HDU '" + kHduNames[t] + "'";
    }
    if (!c.problem.empty()) continue;
    const double det = c.dudrow * c.dvdcol - c.dudcol * c.dvdrow;
    if (!std::isfinite(det) || det == 0)
      c.problem = where + "columns 'dudrow dudcol dvdrow dvdcol'[" + std::to_string(i) + "] = (" +
                  number_text(c.dudrow) + ", " + number_text(c.dudcol) + ", " + number_text(c.dvdrow) + ", " +
                  number_text(c.dvdcol) + ") have no inverse (determinant " + number_text(det) + ")";
    else if (!std::isfinite(c.cutout_row) || !std::isfinite(c.cutout_col))
      c.problem = where + "columns " + with_index("cutout_row", i) + ", " + with_index("cutout_col", i) + " are not finite";
    else if (const double box = static_cast<double>(o.box_size);
             c.cutout_row < -1 || c.cutout_row > box || c.cutout_col < -1 || c.cutout_col > box)
      c.problem = where + "columns " + with_index("cutout_row", i) + ", " + with_index("cutout_col", i) + " = (" +
                  number_text(c.cutout_row) + ", " + number_text(c.cutout_col) + ") put the object outside its " +
                  std::to_string(o.box_size) + " x " + std::to_string(o.box_size) + " cutout";
  }
  if (psf_problem_.empty()) read_psf_columns(o);
  return o;
}

void MedsFile::read_cutout(const MedsObject& object, int icut, MedsCutoutType type, std::span<double> out) {
  const int t = static_cast<int>(type);
  if (length_[t] < 0) throw FitsError(path_ + ": no HDU '" + kHduNames[t] + "'");
  if (!object.problem.empty() || icut < 0 || icut >= static_cast<int>(object.cutouts.size()) ||
      !object.cutouts[static_cast<std::size_t>(icut)].problem.empty())
    throw FitsError(path_ + ": object " + std::to_string(object.row) + " has no usable cutout " + std::to_string(icut));
  if (out.size() != static_cast<std::size_t>(object.box_size * object.box_size))
    throw FitsError(path_ + ": read_cutout: output holds " + std::to_string(out.size()) + " values, not box_size^2");
  file_.move_to(hdu_[t]);
  file_.read_image_range(object.cutouts[static_cast<std::size_t>(icut)].start_row, out);
}

}  // namespace stampede::io
