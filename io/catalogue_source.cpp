// Catalogue stamp source; see catalogue_source.hpp.
#include "io/catalogue_source.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <utility>

#include "io/fits_error.hpp"
#include "io/text_lines.hpp"

namespace stampede::io {
namespace {

bool is_fits(const std::string& path) {
  std::ifstream f(path.substr(0, path.find('[')), std::ios::binary);
  char head[6] = {};
  f.read(head, 6);
  if (std::string(head, 6) == "SIMPLE") return true;
  const std::string base = path.substr(0, path.find('['));
  auto ends = [&](const char* s) { return base.size() >= std::strlen(s) && base.compare(base.size() - std::strlen(s), std::string::npos, s) == 0; };
  return ends(".fits") || ends(".fits.gz") || ends(".fit") || ends(".fz") || path.find('[') != std::string::npos;
}

// An integral double as an id: below 2^53 in magnitude for text (every integer literal there is
// exact, so no id is silently rounded), within the 64-bit range for a FITS float column (its
// binary value is the id).
bool integral_id(double v, double limit, std::int64_t* id) {
  if (!(std::abs(v) < limit) || v != std::trunc(v)) return false;
  *id = static_cast<std::int64_t>(v);
  return true;
}

constexpr double kTwoTo53 = 9007199254740992.0, kTwoTo63 = 9223372036854775808.0;

bool parse_id(std::string_view t, std::int64_t* id) {
  if (t.size() > 1 && t[0] == '+' && t[1] != '-') t.remove_prefix(1);
  std::int64_t v = 0;
  auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec == std::errc() && end == t.data() + t.size()) {
    *id = v;
    return true;
  }
  double d = 0;
  auto [dend, dec] = std::from_chars(t.data(), t.data() + t.size(), d);
  return dec == std::errc() && dend == t.data() + t.size() && integral_id(d, kTwoTo53, id);
}

// A number as istream >> double reads it (a leading '+' too), and also nan / inf; a value beyond
// the double range is +-inf or 0, as strtod gives it.
bool parse_number(std::string_view t, double* v) {
  if (t.size() > 1 && t[0] == '+' && t[1] != '-') t.remove_prefix(1);
  auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), *v);
  if (end != t.data() + t.size()) return false;
  if (ec == std::errc::result_out_of_range) *v = std::strtod(std::string(t).c_str(), nullptr);
  return ec == std::errc() || ec == std::errc::result_out_of_range;
}

// The first token of at most 40 characters, for messages.
std::string shown(std::string_view t) { return t.size() <= 40 ? std::string(t) : std::string(t.substr(0, 40)) + "..."; }

}  // namespace

CatalogueStampSource::CatalogueStampSource(const std::string& image_path, const std::string& weight_path,
                                           const std::string& catalogue_path, int stamp_size,
                                           const CatalogueColumns& columns, std::span<const std::int64_t> save_images)
    : image_(FitsFile::open_read(image_path)), catalogue_path_(catalogue_path), columns_(columns), stamp_(stamp_size) {
  image_.image_shape();  // fails early, naming the file, when there is no 2-D image
  if (!weight_path.empty()) {
    weight_ = std::make_unique<FitsFile>(FitsFile::open_read(weight_path));
    const auto a = image_.image_shape(), b = weight_->image_shape();
    if (a.nx != b.nx || a.ny != b.ny)
      throw FitsError(weight_->describe() + ": weight image is " + std::to_string(b.nx) + " x " + std::to_string(b.ny) +
                      ", the input image " + std::to_string(a.nx) + " x " + std::to_string(a.ny));
  }
  // A directory opens as an empty stream: it would read as a catalogue of no objects.
  std::error_code ec;
  if (std::filesystem::is_directory(catalogue_path.substr(0, catalogue_path.find('[')), ec))
    throw std::runtime_error("catalogue '" + catalogue_path + "' is a directory, not a catalogue file");
  fits_catalogue_ = is_fits(catalogue_path);
  if (fits_catalogue_) {
    table_ = std::make_unique<FitsFile>(FitsFile::open_read(catalogue_path));
    if (table_->hdu_index() == 0) table_->move_to(1);  // a bare path: the first extension
    std::vector<std::string> needed = {columns_.id, columns_.x, columns_.y};
    if (columns_.with_psf)
      for (const auto& c : {columns_.psf_beta, columns_.psf_fwhm, columns_.psf_e1, columns_.psf_e2}) needed.push_back(c);
    for (const auto& c : needed)
      if (!table_->has_column(c)) throw FitsError(table_->describe() + ": no column '" + c + "'");
    total_ = table_->table_rows();
    if (total_ > 0) {
      long long probe = 0;
      try {
        table_->read_column_rows(columns_.id, 0, std::span<long long>(&probe, 1));
        integer_ids_ = true;
      } catch (const FitsError&) {
        // not an integer column: doubles, each checked to be integral (table_ids)
      }
    }
  }
  check_ids(save_images);
  cutout_.resize(static_cast<std::size_t>(stamp_) * stamp_);
}

// The first streaming pass: every line (or id) valid, no id twice, every saved id present.
void CatalogueStampSource::check_ids(std::span<const std::int64_t> save_images) {
  std::vector<std::pair<std::int64_t, long long>> ids;  // (id, line or 1-based row)
  if (fits_catalogue_) {
    ids.reserve(static_cast<std::size_t>(total_));
    std::vector<std::int64_t> chunk(4096);
    for (long long first = 0; first < total_; first += static_cast<long long>(chunk.size())) {
      const std::span<std::int64_t> part(chunk.data(), static_cast<std::size_t>(std::min<long long>(4096, total_ - first)));
      table_ids(first, part);
      for (std::size_t i = 0; i < part.size(); ++i) ids.emplace_back(part[i], first + static_cast<long long>(i) + 1);
    }
  } else {
    text_.open(catalogue_path_);
    if (!text_) throw std::runtime_error("cannot open catalogue '" + catalogue_path_ + "'");
    Entry e;
    while (next_entry(&e)) {
      ids.emplace_back(e.id, text_line_);
      ++total_;
    }
    text_.clear();
    text_.seekg(0);
    text_line_ = 0;
  }
  std::sort(ids.begin(), ids.end());
  const std::string where = fits_catalogue_ ? table_->describe() + ": id " : catalogue_path_ + ": id ";
  const char* unit = fits_catalogue_ ? " in rows " : " on lines ";
  for (std::size_t i = 1; i < ids.size(); ++i)
    if (ids[i].first == ids[i - 1].first)
      throw std::runtime_error(where + std::to_string(ids[i].first) + unit + std::to_string(ids[i - 1].second) + " and " +
                               std::to_string(ids[i].second) + ": object ids must be unique");
  for (std::int64_t id : save_images) {
    const auto it = std::lower_bound(ids.begin(), ids.end(), std::pair<std::int64_t, long long>(id, 0));
    if (it == ids.end() || it->first != id)
      throw std::runtime_error("option 'save_images': object id " + std::to_string(id) + " is not in catalogue '" +
                               catalogue_path_ + "'");
  }
}

void CatalogueStampSource::table_ids(long long first_row, std::span<std::int64_t> out) {
  if (integer_ids_) {
    std::vector<long long> v(out.size());
    table_->read_column_rows(columns_.id, first_row, v);
    std::copy(v.begin(), v.end(), out.begin());
    return;
  }
  std::vector<double> v(out.size());
  table_->read_column_rows(columns_.id, first_row, v);
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!integral_id(v[i], kTwoTo63, &out[i])) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.17g", v[i]);
      throw FitsError(table_->describe() + ": row " + std::to_string(first_row + static_cast<long long>(i) + 1) + ": id " +
                      buf + " in column '" + columns_.id + "' is not a 64-bit integer");
    }
}

CatalogueStampSource::~CatalogueStampSource() = default;

bool CatalogueStampSource::next_entry(Entry* e) {
  if (fits_catalogue_) {
    if (next_ >= total_) return false;
    auto read = [&](const std::string& c) {
      double v = NAN;
      table_->read_column_rows(c, next_, std::span<double>(&v, 1));
      return v;
    };
    table_ids(next_, std::span<std::int64_t>(&e->id, 1));
    e->x = read(columns_.x);
    e->y = read(columns_.y);
    if (columns_.with_psf) {
      e->beta = read(columns_.psf_beta);
      e->fwhm = read(columns_.psf_fwhm);
      e->e1 = read(columns_.psf_e1);
      e->e2 = read(columns_.psf_e2);
    }
    return true;
  }
  std::string line;
  for (TextLine read; (read = read_text_line(text_, &line)) != TextLine::kEnd;) {
    ++text_line_;
    if (read == TextLine::kTooLong)
      throw std::runtime_error(catalogue_path_ + ":" + std::to_string(text_line_) + ": a line longer than " +
                               std::to_string(kMaxTextLine) + " bytes: not a text catalogue");
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    auto where = [&] { return catalogue_path_ + ":" + std::to_string(text_line_) + ": "; };
    std::vector<std::string_view> tokens;
    for (std::size_t pos = line.find_first_not_of(" \t\r\v\f"); pos != std::string::npos;) {
      const std::size_t end = std::min(line.find_first_of(" \t\r\v\f", pos), line.size());
      tokens.emplace_back(line.data() + pos, end - pos);
      pos = line.find_first_not_of(" \t\r\v\f", end);
    }
    if (tokens.empty()) continue;
    std::vector<double> v(tokens.size(), NAN);
    for (std::size_t i = 1; i < tokens.size(); ++i)
      if (!parse_number(tokens[i], &v[i])) throw std::runtime_error(where() + "'" + shown(tokens[i]) + "' is not a number");
    const std::size_t need = columns_.with_psf ? 7 : 3;
    if (v.size() < need)
      throw std::runtime_error(where() + "expected " + std::to_string(need) + " columns (id x y" +
                               (columns_.with_psf ? " psf_beta psf_fwhm psf_e1 psf_e2" : "") + "), found " +
                               std::to_string(v.size()));
    std::int64_t id = 0;
    if (!parse_id(tokens[0], &id)) throw std::runtime_error(where() + "id '" + shown(tokens[0]) + "' is not a 64-bit integer");
    *e = {id, v[1], v[2], NAN, NAN, NAN, NAN};
    if (columns_.with_psf) e->beta = v[3], e->fwhm = v[4], e->e1 = v[5], e->e2 = v[6];
    return true;
  }
  return false;
}

void CatalogueStampSource::skip_to(long long index) {
  if (!fits_catalogue_) {
    Entry e;
    while (next_ < index && next_entry(&e)) ++next_;
  }
  next_ = index;
}

void CatalogueStampSource::cut(const Entry& e, int k, StampBatch& batch) {
  const auto shape = image_.image_shape();
  const std::size_t npix = static_cast<std::size_t>(stamp_) * stamp_;
  std::span<double> pix, w;
  ArenaObservation& o = batch.observations.add_stamp(stamp_, &pix, &w);
  // The mask of the image edge lives in the weights: a weight map's, else a mask on noise_sigma's.
  o.weight_kind = weight_ ? WeightKind::kInverseVariance : WeightKind::kMask;
  if (columns_.with_psf) o.psf = PsfModel::Moffat({e.beta, e.fwhm, e.e1, e.e2, 0.0});
  std::fill_n(pix.begin(), npix, 0.0);
  std::fill_n(w.begin(), npix, 0.0);
  ObjectRecord& r = batch.records[k];
  r = ObjectRecord{};
  r.id = e.id;
  r.x_image = e.x;
  r.y_image = e.y;
  // Only a stamp that can reach the image is cut; checked in doubles, so no position (however
  // large, or not finite) reaches the integer arithmetic below, which it would overflow.
  const double fx = e.x - 1.0, fy = e.y - 1.0, reach = stamp_ + 1.0;
  if (!(fx > -reach && fx < shape.nx + reach && fy > -reach && fy < shape.ny + reach)) {
    r.flags |= kFlagEdge;
    return;  // all weights 0: reported as no_data
  }
  // Nearest pixel, 0-based; the stamp's first pixel so that pixel sits at the stamp centre.
  const long cx = std::lround(e.x - 1.0), cy = std::lround(e.y - 1.0);
  const long x0 = cx - (stamp_ - 1) / 2, y0 = cy - (stamp_ - 1) / 2;
  r.stamp_x0 = static_cast<double>(x0);
  r.stamp_y0 = static_cast<double>(y0);
  const long xa = std::max(0L, x0), ya = std::max(0L, y0);
  const long xb = std::min<long>(shape.nx, x0 + stamp_), yb = std::min<long>(shape.ny, y0 + stamp_);
  if (xa != x0 || ya != y0 || xb != x0 + stamp_ || yb != y0 + stamp_) r.flags |= kFlagEdge;
  if (xa >= xb || ya >= yb) return;
  const long nx = xb - xa, ny = yb - ya;
  std::span<double> region(cutout_.data(), static_cast<std::size_t>(nx * ny));
  image_.read_image_region(xa, ya, nx, ny, region);
  for (long j = 0; j < ny; ++j)
    for (long i = 0; i < nx; ++i) {
      const std::size_t d = static_cast<std::size_t>(ya - y0 + j) * stamp_ + (xa - x0 + i);
      pix[d] = region[j * nx + i];
      w[d] = 1.0;  // replaced by the weight map; else a mask, on noise_sigma's weight
    }
  if (weight_) {
    weight_->read_image_region(xa, ya, nx, ny, region);
    for (long j = 0; j < ny; ++j)
      for (long i = 0; i < nx; ++i) w[static_cast<std::size_t>(ya - y0 + j) * stamp_ + (xa - x0 + i)] = region[j * nx + i];
  }
}

bool CatalogueStampSource::fill(StampBatch& batch) {
  batch.begin(next_);
  Entry e;
  while (batch.count < batch.capacity() && next_ < total_ && next_entry(&e)) {
    const int k = batch.count++;
    cut(e, k, batch);
    ++next_;
  }
  return batch.count > 0;
}

}  // namespace stampede::io
