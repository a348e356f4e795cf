// Catalogue stamp source; see catalogue_source.hpp.
#include "io/catalogue_source.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "io/fits_error.hpp"

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

}  // namespace

CatalogueStampSource::CatalogueStampSource(const std::string& image_path, const std::string& weight_path,
                                           const std::string& catalogue_path, int stamp_size,
                                           const CatalogueColumns& columns)
    : image_(FitsFile::open_read(image_path)), catalogue_path_(catalogue_path), columns_(columns), stamp_(stamp_size) {
  image_.image_shape();  // fails early, naming the file, when there is no 2-D image
  if (!weight_path.empty()) {
    weight_ = std::make_unique<FitsFile>(FitsFile::open_read(weight_path));
    const auto a = image_.image_shape(), b = weight_->image_shape();
    if (a.nx != b.nx || a.ny != b.ny)
      throw FitsError(weight_->describe() + ": weight image is " + std::to_string(b.nx) + " x " + std::to_string(b.ny) +
                      ", the input image " + std::to_string(a.nx) + " x " + std::to_string(a.ny));
  }
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
  } else {
    // A first streaming pass validates every line and counts the objects.
    text_.open(catalogue_path);
    if (!text_) throw std::runtime_error("cannot open catalogue '" + catalogue_path + "'");
    Entry e;
    while (next_entry(&e)) ++total_;
    text_.clear();
    text_.seekg(0);
    text_line_ = 0;
  }
  cutout_.resize(static_cast<std::size_t>(stamp_) * stamp_);
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
    e->id = read(columns_.id);
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
  while (std::getline(text_, line)) {
    ++text_line_;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::istringstream in(line);
    std::vector<double> v;
    double x;
    while (in >> x) v.push_back(x);
    if (!in.eof()) throw std::runtime_error(catalogue_path_ + ":" + std::to_string(text_line_) + ": not a number");
    if (v.empty()) continue;
    const std::size_t need = columns_.with_psf ? 7 : 3;
    if (v.size() < need)
      throw std::runtime_error(catalogue_path_ + ":" + std::to_string(text_line_) + ": expected " + std::to_string(need) +
                               " columns (id x y" + (columns_.with_psf ? " psf_beta psf_fwhm psf_e1 psf_e2" : "") + "), found " +
                               std::to_string(v.size()));
    *e = {v[0], v[1], v[2], NAN, NAN, NAN, NAN};
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
  double* pix = batch.stamp(k);
  double* w = batch.weight(k);
  std::fill_n(pix, npix, 0.0);
  std::fill_n(w, npix, 0.0);
  ObjectRecord& r = batch.records[k];
  r = ObjectRecord{};
  r.id = static_cast<std::int64_t>(e.id);
  r.x_image = e.x;
  r.y_image = e.y;
  if (!std::isfinite(e.x) || !std::isfinite(e.y)) {
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
      w[d] = 1.0;  // replaced by the weight map, or by 1/sigma^2 below
    }
  if (weight_) {
    weight_->read_image_region(xa, ya, nx, ny, region);
    for (long j = 0; j < ny; ++j)
      for (long i = 0; i < nx; ++i) w[static_cast<std::size_t>(ya - y0 + j) * stamp_ + (xa - x0 + i)] = region[j * nx + i];
  }
}

bool CatalogueStampSource::fill(StampBatch& batch) {
  batch.count = 0;
  batch.first_object = next_;
  batch.has_weights = true;  // always: the mask of the image edge lives in the weights
  Entry e;
  while (batch.count < batch.capacity() && next_ < total_ && next_entry(&e)) {
    const int k = batch.count++;
    cut(e, k, batch);
    if (columns_.with_psf) batch.psf[k] = PsfModel::Moffat({e.beta, e.fwhm, e.e1, e.e2, 0.0});
    ++next_;
  }
  return batch.count > 0;
}

}  // namespace stampede::io
