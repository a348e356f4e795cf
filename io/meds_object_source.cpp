// MEDS objects into the batch's observation arena; see meds_object_source.hpp.
#include "io/meds_object_source.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "engine/common/number_text.hpp"
#include "io/psfex_file.hpp"
#include "io/config_error.hpp"

namespace stampede::io {

namespace {
constexpr double kMaxZeroPointOffset = 25;  // magnitudes: a factor 1e10 in flux

// The angle between two (ra, dec) in degrees, in arcsec (haversine: accurate at small angles, where
// the cosine formula loses the offset to rounding).
double separation_arcsec(double ra1, double dec1, double ra2, double dec2) {
  constexpr double kRad = 3.14159265358979323846 / 180;
  const double s_dec = std::sin(0.5 * (dec2 - dec1) * kRad), s_ra = std::sin(0.5 * (ra2 - ra1) * kRad);
  const double h = s_dec * s_dec + std::cos(dec1 * kRad) * std::cos(dec2 * kRad) * s_ra * s_ra;
  return 2 * std::asin(std::sqrt(h > 1 ? 1.0 : h)) / kRad * 3600;  // a NaN stays NaN (std::min would give 1)
}
}  // namespace

void apply_uberseg(std::span<const double> seg, int box_size, std::int64_t number, std::span<double> weight) {
  struct Labelled {
    int x, y;
    bool own;
  };
  std::vector<Labelled> labelled;
  for (int y = 0; y < box_size; ++y)
    for (int x = 0; x < box_size; ++x) {
      const double v = seg[static_cast<std::size_t>(y) * box_size + x];
      if (v != 0) labelled.push_back({x, y, v == static_cast<double>(number)});
    }
  if (labelled.empty()) return;
  for (int y = 0; y < box_size; ++y)
    for (int x = 0; x < box_size; ++x) {
      long best_own = -1, best_other = -1;
      for (const Labelled& l : labelled) {
        const long d = static_cast<long>(l.x - x) * (l.x - x) + static_cast<long>(l.y - y) * (l.y - y);
        long& best = l.own ? best_own : best_other;
        if (best < 0 || d < best) best = d;
      }
      if (best_other >= 0 && (best_own < 0 || best_other < best_own)) weight[static_cast<std::size_t>(y) * box_size + x] = 0;
    }
}

void check_band_tiles(std::span<MedsFile* const> tiles) {
  if (tiles.empty()) return;
  MedsFile& first = *tiles[0];
  constexpr long long kChunk = 65536;  // ids compared a chunk at a time: memory bounded, any tile size
  std::vector<long long> a, b;
  std::vector<double> ra_a, dec_a, ra_b, dec_b;
  for (std::size_t t = 1; t < tiles.size(); ++t) {
    MedsFile& other = *tiles[t];
    if (other.size() != first.size())
      throw ConfigError("--meds '" + other.path() + "' has " + std::to_string(other.size()) + " objects, --meds '" +
                        first.path() + "' " + std::to_string(first.size()) +
                        ": a multi-band run's tiles must list the same objects in the same order");
    for (long long begin = 0; begin < first.size(); begin += kChunk) {
      const long long n = std::min(kChunk, first.size() - begin);
      a.resize(static_cast<std::size_t>(n)), b.resize(static_cast<std::size_t>(n));
      first.read_ids(begin, a);
      other.read_ids(begin, b);
      const auto diff = std::mismatch(a.begin(), a.end(), b.begin());
      if (diff.first != a.end()) {
        const long long row = begin + (diff.first - a.begin());
        throw ConfigError("--meds '" + other.path() + "': object_data row " + std::to_string(row) + " has id " +
                          std::to_string(*diff.second) + ", --meds '" + first.path() + "' id " +
                          std::to_string(*diff.first) +
                          ": a multi-band run's tiles must list the same objects in the same order");
      }
      // The same id at another place is another object: fitting the two as one mixes galaxies.
      for (auto* v : {&ra_a, &dec_a, &ra_b, &dec_b}) v->resize(static_cast<std::size_t>(n));
      first.read_positions(begin, ra_a, dec_a);
      other.read_positions(begin, ra_b, dec_b);
      for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
        const bool known_a = std::isfinite(ra_a[i]) && std::isfinite(dec_a[i]);
        const bool known_b = std::isfinite(ra_b[i]) && std::isfinite(dec_b[i]);
        if (!known_a && !known_b) continue;  // nothing to compare: the ids match
        const double offset = separation_arcsec(ra_a[i], dec_a[i], ra_b[i], dec_b[i]);
        if (offset <= kMaxBandOffsetArcsec) continue;
        const auto place = [](double ra, double dec) {
          std::string text = "(";  // appended, not "(" + ...: GCC 12 warns falsely (-Wrestrict) on that
          text += number_text(ra);
          text += ", ";
          text += number_text(dec);
          return text + ")";
        };
        char offset_text[32];
        std::snprintf(offset_text, sizeof offset_text, "%.4g", offset);
        throw ConfigError("--meds '" + other.path() + "': object id " + std::to_string(a[i]) + " (object_data row " +
                          std::to_string(begin + static_cast<long long>(i)) + ") is at ra, dec = " +
                          place(ra_b[i], dec_b[i]) + " deg, " + offset_text + " arcsec from its place in --meds '" +
                          first.path() + "' " + place(ra_a[i], dec_a[i]) +
                          ": a multi-band run's tiles must hold the same objects at the same places (within " +
                          number_text(kMaxBandOffsetArcsec) + " arcsec)");
      }
    }
  }
}

MedsObjectReader::MedsObjectReader(MedsFile& tile, const MedsOptions& options, const PsfModel& options_psf)
    : tile_(tile), options_(options), options_psf_(options_psf), source_(options.psf) {
  if (source_ == MedsPsfSource::kAuto) source_ = tile.has_psf_cutouts() ? MedsPsfSource::kCutouts : MedsPsfSource::kPsfex;
  if (source_ == MedsPsfSource::kCutouts && !tile.has_psf_cutouts())
    throw ConfigError("option 'meds_psf' = 'cutouts': " + tile.psf_cutouts_problem());
  models_.resize(tile.images().size());
  model_errors_.resize(tile.images().size());
  if (options_.psf_dir.empty()) options_.psf_dir = std::filesystem::path(tile.path()).parent_path().string();
}

std::filesystem::path MedsObjectReader::psfex_file(const std::string& psf_path) const {
  const std::filesystem::path name(psf_path);
  return name.is_absolute() ? name : std::filesystem::path(options_.psf_dir.empty() ? "." : options_.psf_dir) / name;
}

std::vector<std::string> MedsObjectReader::psfex_files() const {
  std::vector<std::string> files;
  if (source_ != MedsPsfSource::kPsfex) return files;
  for (const MedsImageInfo& info : tile_.images()) {
    if (info.psf_path.empty()) continue;
    const std::string p = psfex_file(info.psf_path).lexically_normal().string();
    if (std::find(files.begin(), files.end(), p) == files.end()) files.push_back(p);
  }
  return files;
}

const PsfexModel* MedsObjectReader::psfex(long long file_id, std::string* problem) {
  const std::size_t i = static_cast<std::size_t>(file_id);
  if (!models_[i] && model_errors_[i].empty()) {
    const std::string& name = tile_.images()[i].psf_path;
    if (name.empty()) {
      model_errors_[i] = tile_.path() + ": image_info row " + std::to_string(file_id) + " names no PSFEx model (psf_path)";
    } else {
      try {
        models_[i] = read_psfex_model(psfex_file(name).string());
      } catch (const std::runtime_error& e) {
        model_errors_[i] = e.what();
      }
    }
  }
  if (!models_[i]) {
    *problem = model_errors_[i];
    return nullptr;
  }
  return &*models_[i];
}

bool MedsObjectReader::cutout_psf(const MedsObject& o, int k, ArenaObservation* obs, std::string* why) {
  const MedsCutout& c = o.cutouts[static_cast<std::size_t>(k)];
  std::shared_ptr<const PsfImage> image;
  switch (source_) {
    case MedsPsfSource::kOptions:
      obs->psf = options_psf_;
      obs->psf_from_image = false;
      return true;
    case MedsPsfSource::kCutouts: {
      if (!c.psf_problem.empty()) {
        *why = c.psf_problem;
        return false;
      }
      auto img = std::make_shared<PsfImage>();
      img->nx = static_cast<int>(c.psf_cols), img->ny = static_cast<int>(c.psf_rows);
      img->pixels.resize(static_cast<std::size_t>(c.psf_rows * c.psf_cols));
      tile_.read_psf_cutout(o, k, img->pixels);
      img->centre_x = c.psf_cutout_col, img->centre_y = c.psf_cutout_row;
      img->oversampling = 1;
      img->pixel_integrated = true;
      image = std::move(img);
      break;
    }
    default: {
      // The source image's PSFEx model at the object's position there (1-based X_IMAGE).
      const PsfexModel* model = psfex(c.file_id, why);
      if (model) image = model->image_at(c.orig_col + 1, c.orig_row + 1, why);
      break;
    }
  }
  if (!image) return false;
  obs->psf = PsfModel::Image(std::move(image));
  obs->psf_from_image = true;
  return true;
}

void MedsObjectReader::read(long long row, int band, ObservationArena* arena, ObjectRecord* record) {
  const int object = arena->objects() - 1;
  BandReading& reading = arena->reading(object, band);
  reading.first = arena->size();
  const MedsObject o = tile_.object(row);
  if (record) {
    record->id = o.id;
    record->survey.number = o.number;
    record->survey.ra = o.ra;
    record->survey.dec = o.dec;
  }
  auto note = [&](const std::string& why) {
    if (reading.problem.empty()) reading.problem = why;
  };
  auto where = [&](int k) { return tile_.path() + ": object " + std::to_string(row) + ", cutout " + std::to_string(k); };
  if (!o.problem.empty()) {
    note(o.problem);
    reading.flags |= kFlagNoUsableEpoch;
    reading.readable = false;
    return;
  }
  if (o.box_size > kMaxFitBoxSize) {
    note(tile_.path() + ": object " + std::to_string(row) + ": column 'box_size' = " + std::to_string(o.box_size) +
         " is larger than a galaxy fit takes (" + std::to_string(kMaxFitBoxSize) + ")");
    reading.flags |= kFlagNoUsableEpoch;
    reading.readable = false;
    return;
  }
  const int box = static_cast<int>(o.box_size);
  const std::size_t npix = static_cast<std::size_t>(box) * box;
  const int first = options_.fit_coadd ? 0 : 1, last = options_.fit_coadd ? 1 : static_cast<int>(o.cutouts.size());
  for (int k = first; k < last && k < static_cast<int>(o.cutouts.size()); ++k) {
    const MedsCutout& c = o.cutouts[static_cast<std::size_t>(k)];
    if (!c.problem.empty()) {
      note(c.problem);
      continue;
    }
    std::span<double> pixels, weight;
    ArenaObservation& obs = arena->add(box, &pixels, &weight);
    tile_.read_cutout(o, k, MedsCutoutType::kImage, pixels);
    if (tile_.has(MedsCutoutType::kWeight))
      tile_.read_cutout(o, k, MedsCutoutType::kWeight, weight);
    else
      std::fill(weight.begin(), weight.end(), 1.0);
    if (tile_.has(MedsCutoutType::kBmask)) {
      bmask_.resize(npix);
      tile_.read_cutout(o, k, MedsCutoutType::kBmask, bmask_);
      for (std::size_t i = 0; i < npix; ++i)
        if (static_cast<std::uint32_t>(static_cast<std::int64_t>(bmask_[i])) & options_.bmask_bits) weight[i] = 0;
    }
    if (options_.uberseg && tile_.has(MedsCutoutType::kSeg)) {
      seg_.resize(npix);
      tile_.read_cutout(o, k, MedsCutoutType::kSeg, seg_);
      apply_uberseg(seg_, box, o.number, weight);
    }
    for (std::size_t i = 0; i < npix; ++i)
      if (!std::isfinite(pixels[i]) || !(weight[i] >= 0) || !std::isfinite(weight[i])) weight[i] = 0, pixels[i] = 0;
    long long unmasked = 0;
    for (double w : weight) unmasked += w > 0;
    reading.pixels_total += static_cast<long long>(npix);
    reading.pixels_unmasked += unmasked;
    if (unmasked == 0) {
      note(where(k) + ": every pixel masked");
      arena->drop_last();
      continue;
    }
    std::string why;
    if (!cutout_psf(o, k, &obs, &why)) {
      note(where(k) + ": PSF: " + why);
      reading.flags |= kFlagPsfCutoutDropped;
      arena->drop_last();
      continue;
    }
    const MedsImageInfo& info = tile_.images()[static_cast<std::size_t>(c.file_id)];
    // A zero point more than kMaxZeroPointOffset magnitudes from the reference (a NaN, 1e30, -100)
    // is a broken record, not a calibration: the cutout would weigh nothing or everything.
    if (!std::isfinite(info.magzp) || std::abs(info.magzp - options_.magzp_ref) > kMaxZeroPointOffset) {
      note(tile_.path() + ": image_info row " + std::to_string(c.file_id) + ": magzp = " + number_text(info.magzp) +
           " is not a usable zero point (more than " + number_text(kMaxZeroPointOffset) +
           " mag from meds_magzp_ref = " + number_text(options_.magzp_ref) + "); object " + std::to_string(row) +
           ", cutout " + std::to_string(k) + " dropped");
      reading.flags |= kFlagBadZeroPoint;
      arena->drop_last();
      continue;
    }
    obs.cutout = k;
    obs.band = band;
    obs.frame = PixelFrame::from_meds(c.dudrow, c.dudcol, c.dvdrow, c.dvdcol, c.cutout_row, c.cutout_col);
    obs.flux_scale = std::pow(10.0, 0.4 * (info.magzp - options_.magzp_ref));
  }
  reading.count = arena->size() - reading.first;
}

MedsObjectSource::MedsObjectSource(const std::vector<std::string>& paths, const MedsOptions& options,
                                   const PsfModel& options_psf) {
  if (paths.empty()) throw ConfigError("--meds: no tile given");
  std::vector<MedsFile*> handles;
  for (const std::string& p : paths) handles.push_back(&tiles_.emplace_back(MedsFile::open(p)));
  check_band_tiles(handles);
  for (MedsFile& tile : tiles_) readers_.emplace_back(tile, options, options_psf);
}

std::vector<std::string> MedsObjectSource::psfex_files() const {
  std::vector<std::string> files;
  for (const MedsObjectReader& r : readers_)
    for (const std::string& p : r.psfex_files())
      if (std::find(files.begin(), files.end(), p) == files.end()) files.push_back(p);
  return files;
}

bool MedsObjectSource::fill(StampBatch& batch) {
  const long long end = end_ >= 0 ? std::min(end_, total_objects()) : total_objects();
  batch.first_object = next_;
  batch.count = static_cast<int>(std::clamp<long long>(end - next_, 0, batch.capacity()));
  ObservationArena& arena = batch.observations;
  arena.clear();
  const int bands = static_cast<int>(readers_.size());
  for (int k = 0; k < batch.count; ++k) {
    ObjectRecord& record = batch.records[static_cast<std::size_t>(k)];
    record = ObjectRecord{};
    arena.begin_object(bands);
    for (int b = 0; b < bands; ++b)
      readers_[static_cast<std::size_t>(b)].read(next_ + k, b, &arena, b == 0 ? &record : nullptr);
  }
  next_ += batch.count;
  return batch.count > 0;
}

}  // namespace stampede::io
