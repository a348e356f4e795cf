// A metadetection run; see metadetect_run.hpp.
#include "app/metadetect_run.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <chrono>
#include <limits>
#include <memory>
#include <sstream>

#include "app/run_fingerprint.hpp"
#include "app/run_harness.hpp"
#include "app/version.hpp"
#include "engine/metacal/metacal_type.hpp"
#include "engine/metadetect/cell_layout.hpp"
#include "engine/metadetect/cell_measurer.hpp"
#include "engine/metadetect/sep_detection.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "io/cell_image_reader.hpp"
#include "io/config_error.hpp"
#include "io/file_digest.hpp"
#include "io/fits_error.hpp"
#include "io/meds_file.hpp"
#include "io/metadetect_writer.hpp"
#include "io/durable_file.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"
#include "io/psfex_file.hpp"
#include "io/result_columns.hpp"

namespace stampede::app {
namespace {

constexpr int kMaxProblems = 100;

std::string number_text(double v, int digits = 17) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}
// For messages: enough digits to tell apart what the 1e-6 checks refuse.
std::string short_number(double v) { return number_text(v, 9); }

// A batch's cells (what the source read) and the rows they yield (what the fit stage measured).
struct CellBatch : BatchExtension {
  struct Cell {
    int file = 0;
    CellPlacement place;
    double pixel_scale = 0;
    double lens_g1 = 0, lens_g2 = 0;  // keep_unlensed: the file's recorded shear
    int first_observation = 0, bands = 1;  // its bands' observations in the arena, in band order
    // Its bands' NOISE planes, consecutive in `noise` from here (none: -1).
    long long noise_offset = -1;
    std::string problem;  // why it cannot be measured (its PSFEx model fails there); "" none
  };
  std::vector<Cell> cells;
  std::vector<double> noise;  // the batch's noise planes (kept between batches)
  std::size_t noise_used = 0;
  std::vector<MetadetectRow> rows;
  std::vector<std::string> problems;  // per cell, "" none

  // Space for the next cell's `bands` noise planes of npix pixels: their first value's offset.
  std::size_t add_noise(std::size_t npix, int bands) {
    const std::size_t at = noise_used;
    noise_used += npix * static_cast<std::size_t>(bands);
    if (noise.size() < noise_used) noise.resize(noise_used);
    return at;
  }
};

CellBatch& cell_batch(StampBatch& b) {
  if (!b.extension) b.extension = std::make_unique<CellBatch>();
  return static_cast<CellBatch&>(*b.extension);
}
const CellBatch& cell_batch(const StampBatch& b) { return static_cast<const CellBatch&>(*b.extension); }

// The serial reader: every file's cells in order, a file read whole when its first cell is due.
class CellSource : public StampSource {
 public:
  // Image files: each scene a file per band (the bands' images the same size and pixel scale),
  // named in messages by `names` (its path or template); `psfex` a PSFEx model file per band, or
  // none (each file's PSF HDU).
  struct Images {
    std::vector<std::string> names;
    std::vector<std::vector<std::string>> files;
    std::vector<std::string> psfex;
  };
  CellSource(const Images& in, const MetadetectOptions& options)
      : inputs_(in.names), options_(options), files_(in.files) {
    for (const std::vector<std::string>& bands : files_) {
      const io::CellImageShape shape = io::read_cell_image_shape(bands[0]);
      for (std::size_t b = 1; b < bands.size(); ++b) {
        const io::CellImageShape other = io::read_cell_image_shape(bands[b]);
        if (other.width != shape.width || other.height != shape.height)
          throw io::ConfigError(bands[b] + " is " + std::to_string(other.width) + " x " + std::to_string(other.height) +
                                " pixels, " + bands[0] + " " + std::to_string(shape.width) + " x " +
                                std::to_string(shape.height) + ": a scene's bands must share its pixels");
        if (std::abs(other.pixel_scale / shape.pixel_scale - 1) > 1e-6)
          throw io::ConfigError(bands[b] + "'s pixel scale " + short_number(other.pixel_scale) + " arcsec differs from " +
                                bands[0] + "'s " + short_number(shape.pixel_scale) + ": a scene's bands must share its pixels");
      }
      add_layout(shape.width, shape.height, bands[0] + ": ");
    }
    for (const std::string& path : in.psfex) {
      try {
        models_.push_back(io::read_psfex_model(path));
      } catch (const io::FitsError& e) {
        throw io::FitsError(std::string("--psfex: ") + e.what());
      }
      // Evaluated once here, so that a sampling the metacal images cannot use (PSF_SAMP is image
      // pixels per sample: only 1 / integer is an image of the cells' pixels) stops the run, not each cell.
      std::string why;
      if (!models_.back().image_at(models_.back().zero_x, models_.back().zero_y, &why))
        throw io::ConfigError("--psfex " + path + ": " + why);
      psfex_files_.push_back(path);
    }
  }
  // One image in memory (not copied: it must outlive the source).
  CellSource(const io::CellImage& image, const MetadetectOptions& options)
      : inputs_{"image"}, options_(options), files_{{"image"}}, memory_(&image) {
    add_layout(image.width, image.height, "");
  }
  // A cell tile (DES Y6's "pizza slices"): each object_data row a cell, cutout 0 its coadd with a
  // weight (and bmask, noise) cutout and its PSF in the psf HDU; the cell's place in the tile from
  // orig_start_row/col, its pixel scale from the WCS Jacobian (which must be the scale times the
  // unit matrix: the metacal shear is applied in the cell's pixels). Several bands: a tile per
  // band, whose rows are the same cells (the same box and place in each).
  struct Tile {
    std::vector<std::string> paths;  // a tile per band
  };
  CellSource(const Tile& t, const MetadetectOptions& options) : inputs_(t.paths), options_(options) {
    if (options.keep_unlensed)
      throw io::ConfigError(t.paths[0] + ": --keep-unlensed needs the scene's shear, which a cell tile does not record "
                            "(give `sim cells`'s image files)");
    for (const std::string& tile : t.paths) {
      tiles_.push_back(std::make_unique<io::MedsFile>(io::MedsFile::open(tile)));
      const io::MedsFile& m = *tiles_.back();
      if (!m.has(io::MedsCutoutType::kWeight))
        throw io::ConfigError(tile + ": no weight_cutouts HDU: detection needs the noise level");
      if (!m.has_psf_cutouts()) throw io::ConfigError(tile + ": no PSF cutouts: " + m.psf_cutouts_problem());
      if (m.size() != tiles_[0]->size())
        throw io::ConfigError(tile + ": " + std::to_string(m.size()) + " cells (object_data rows), " + t.paths[0] +
                              " " + std::to_string(tiles_[0]->size()) + ": a band's tile must hold the same cells");
    }
    std::vector<CellPlacement> places;
    for (long long row = 0; row < tiles_[0]->size(); ++row) {
      CellPlacement p;
      for (std::size_t b = 0; b < tiles_.size(); ++b) {
        const std::string& tile = t.paths[b];
        const io::MedsObject o = tiles_[b]->object(row);
        if (!o.problem.empty()) throw io::ConfigError(tile + ": object_data row " + std::to_string(row) + ": " + o.problem);
        if (o.cutouts.empty()) throw io::ConfigError(tile + ": object_data row " + std::to_string(row) + " has no cutout");
        const io::MedsCutout& c = o.cutouts[0];
        if (b == 0) {
          if (2L * options.cell_buffer >= o.box_size)
            throw io::ConfigError(tile + ": cell " + std::to_string(row) + " is " + std::to_string(o.box_size) +
                                  " pixels, not more than twice --cell-buffer " + std::to_string(options.cell_buffer));
          max_tile_box_ = std::max(max_tile_box_, o.box_size);
          p.x0 = static_cast<int>(c.orig_start_col), p.y0 = static_cast<int>(c.orig_start_row);
          p.keep_x0 = p.keep_y0 = options.cell_buffer - 0.5;
          p.keep_x1 = p.keep_y1 = o.box_size - options.cell_buffer - 0.5;
          boxes_.push_back(o.box_size);
        } else if (o.box_size != boxes_.back() || c.orig_start_col != p.x0 || c.orig_start_row != p.y0) {
          throw io::ConfigError(tile + ": cell " + std::to_string(row) + " is " + std::to_string(o.box_size) +
                                " pixels from (" + std::to_string(c.orig_start_col) + ", " +
                                std::to_string(c.orig_start_row) + "), in " + t.paths[0] + " " +
                                std::to_string(boxes_.back()) + " from (" + std::to_string(p.x0) + ", " +
                                std::to_string(p.y0) + "): a band's tile must hold the same cells");
        }
      }
      places.push_back(p);
    }
    total_ = static_cast<long long>(places.size());
    layouts_.push_back(std::move(places));
  }
  long long total_objects() const override { return total_; }
  // The largest cell's pixels (SEP's pixel stack must hold a whole cell above the threshold).
  long long max_cell_pixels() const {
    const long long side = std::max<long long>(options_.cell_size, max_tile_box_);
    return side * side;
  }
  void set_end(long long end) override { end_ = end; }
  void skip_to(long long index) override {
    next_ = index;
    file_ = 0;
    while (file_ < static_cast<int>(layouts_.size()) && index >= static_cast<long long>(layouts_[file_].size()))
      index -= static_cast<long long>(layouts_[file_].size()), ++file_;
    in_file_ = index;
  }
  const std::string& input(int file) const { return inputs_[file]; }
  bool fill(StampBatch& batch) override {
    CellBatch& data = cell_batch(batch);
    data.cells.clear();
    data.noise_used = 0;
    batch.observations.clear();
    batch.first_object = next_;
    batch.count = 0;
    while (batch.count < batch.capacity() && file_ < static_cast<int>(layouts_.size()) && next_ < end_) {
      if (in_file_ >= static_cast<long long>(layouts_[file_].size())) {
        ++file_, in_file_ = 0;
        continue;
      }
      if (!tiles_.empty()) {
        fill_tile_cell(batch, data);
        continue;
      }
      fill_image_cell(batch, data);
    }
    return batch.count > 0;
  }

 private:
  // The tile's next cell into the batch: a band per tile, each an observation, with its noise
  // cutout where the tiles have them.
  void fill_tile_cell(StampBatch& batch, CellBatch& data) {
    const int bands = static_cast<int>(tiles_.size());
    const int size = static_cast<int>(boxes_[static_cast<std::size_t>(in_file_)]);
    const std::size_t npix = static_cast<std::size_t>(size) * size;
    CellBatch::Cell cell;
    cell.place = layouts_[0][in_file_];
    cell.first_observation = static_cast<int>(batch.observations.size()), cell.bands = bands;
    const bool noise = options_.noise_plane &&
                       std::all_of(tiles_.begin(), tiles_.end(), [](const auto& t) { return t->has(io::MedsCutoutType::kNoise); });
    if (noise) cell.noise_offset = static_cast<long long>(data.add_noise(npix, bands));
    batch.observations.begin_object(bands);
    for (int b = 0; b < bands; ++b) {
      io::MedsFile& tile = *tiles_[static_cast<std::size_t>(b)];
      const std::string where = inputs_[static_cast<std::size_t>(b)] + ": cell " + std::to_string(in_file_);
      const io::MedsObject o = tile.object(in_file_);
      const io::MedsCutout& c = o.cutouts[0];
      const double det = c.dudcol * c.dvdrow - c.dudrow * c.dvdcol, scale = std::sqrt(std::abs(det));
      if (!(scale > 0) || std::abs(c.dudrow) > 1e-6 * scale || std::abs(c.dvdcol) > 1e-6 * scale ||
          std::abs(c.dudcol - c.dvdrow) > 1e-6 * scale)
        throw io::ConfigError(where + ": its WCS Jacobian is not the pixel scale times the unit matrix "
                              "(du/dcol = dv/drow, no rotation): not supported yet");
      if (b == 0) {
        cell.pixel_scale = scale;
      } else if (std::abs(scale / cell.pixel_scale - 1) > 1e-6) {
        throw io::ConfigError(where + ": its pixel scale " + std::to_string(scale) + " arcsec differs from " +
                              inputs_[0] + "'s " + std::to_string(cell.pixel_scale) + ": the bands must share the cell's pixels");
      }
      cell_.width = cell_.height = size;
      cell_.pixel_scale = scale;
      cell_.pixels.resize(npix), cell_.weight.resize(npix), mask_.clear(), cell_.noise.clear();
      tile.read_cutout(o, 0, io::MedsCutoutType::kImage, cell_.pixels);
      tile.read_cutout(o, 0, io::MedsCutoutType::kWeight, cell_.weight);
      if (tile.has(io::MedsCutoutType::kBmask)) {
        mask_.resize(npix);
        tile.read_cutout(o, 0, io::MedsCutoutType::kBmask, mask_);
      }
      if (noise) {
        cell_.noise.resize(npix);
        tile.read_cutout(o, 0, io::MedsCutoutType::kNoise, cell_.noise);
      }
      try {
        io::apply_cell_masks(mask_, &cell_);
      } catch (const std::invalid_argument& e) {
        throw io::ConfigError(where + ": " + e.what());
      }
      if (!c.psf_problem.empty()) throw io::ConfigError(where + ": " + c.psf_problem);
      auto img = std::make_shared<PsfImage>();
      img->nx = static_cast<int>(c.psf_cols), img->ny = static_cast<int>(c.psf_rows);
      img->pixels.resize(static_cast<std::size_t>(c.psf_rows * c.psf_cols));
      tile.read_psf_cutout(o, 0, img->pixels);
      img->centre_x = c.psf_cutout_col, img->centre_y = c.psf_cutout_row;
      std::span<double> pixels, weights;
      ArenaObservation& obs = batch.observations.add(size, &pixels, &weights);
      obs.band = b;
      obs.psf = PsfModel::Image(std::move(img));
      std::copy(cell_.pixels.begin(), cell_.pixels.end(), pixels.begin());
      std::copy(cell_.weight.begin(), cell_.weight.end(), weights.begin());
      if (noise)
        std::copy(cell_.noise.begin(), cell_.noise.end(),
                  data.noise.begin() + cell.noise_offset + static_cast<long long>(b * npix));
    }
    data.cells.push_back(std::move(cell));
    batch.records[batch.count].id = next_;
    ++batch.count, ++in_file_, ++next_;
  }

  // The scene's next cell into the batch: a band per file, each an observation, with its NOISE
  // plane where every band has one; its PSF the file's or the PSFEx model's at the cell.
  void fill_image_cell(StampBatch& batch, CellBatch& data) {
    const int bands = static_cast<int>(files_[static_cast<std::size_t>(file_)].size());
    if (loaded_ != file_) {
      images_.resize(static_cast<std::size_t>(bands));
      psfs_.clear();
      for (int b = 0; b < bands; ++b) {
        if (!memory_) images_[static_cast<std::size_t>(b)] = io::read_cell_image(files_[file_][b], models_.empty());
        if (models_.empty()) psfs_.push_back(PsfModel::Image(image(b).psf));
      }
      loaded_ = file_;
    }
    const CellPlacement& place = layouts_[file_][in_file_];
    const int s = options_.cell_size;
    const std::size_t npix = static_cast<std::size_t>(s) * s;
    CellBatch::Cell cell;
    cell.file = file_, cell.place = place, cell.pixel_scale = image(0).pixel_scale;
    if (options_.keep_unlensed) {
      if (!std::isfinite(image(0).g1) || !std::isfinite(image(0).g2))
        throw io::ConfigError(files_[file_][0] + ": --keep-unlensed needs the scene's shear, header keys G1 and G2 "
                              "of HDU 0 (as `stampede sim cells` writes them)");
      cell.lens_g1 = image(0).g1, cell.lens_g2 = image(0).g2;
    }
    cell.first_observation = static_cast<int>(batch.observations.size()), cell.bands = bands;
    bool noise = options_.noise_plane;
    for (int b = 0; b < bands; ++b) noise = noise && !image(b).noise.empty();
    if (noise) cell.noise_offset = static_cast<long long>(data.add_noise(npix, bands));
    batch.observations.begin_object(bands);
    const PsfexPosition at = cell_psfex_position(place, s);
    for (int b = 0; b < bands; ++b) {
      const io::CellImage& im = image(b);
      std::span<double> pixels, weights;
      ArenaObservation& o = batch.observations.add(s, &pixels, &weights);
      o.band = b;
      if (models_.empty()) {
        o.psf = psfs_[static_cast<std::size_t>(b)];
      } else {
        std::string why;
        if (auto psf = models_[static_cast<std::size_t>(b)].image_at(at.x_image, at.y_image, &why))
          o.psf = PsfModel::Image(std::move(psf));
        else if (cell.problem.empty())
          cell.problem = psfex_files_[static_cast<std::size_t>(b)] + ": " + why;
      }
      const long long band_noise = cell.noise_offset + static_cast<long long>(b * npix);
      for (int y = 0; y < s; ++y) {
        const std::size_t from = static_cast<std::size_t>(place.y0 + y) * im.width + place.x0;
        std::copy_n(im.pixels.begin() + from, s, pixels.begin() + static_cast<std::size_t>(y) * s);
        std::copy_n(im.weight.begin() + from, s, weights.begin() + static_cast<std::size_t>(y) * s);
        if (noise) std::copy_n(im.noise.begin() + from, s, data.noise.begin() + band_noise + static_cast<long long>(y) * s);
      }
    }
    data.cells.push_back(std::move(cell));
    batch.records[batch.count].id = next_;
    ++batch.count, ++in_file_, ++next_;
  }

  void add_layout(long width, long height, const std::string& where) {
    std::string why;
    layouts_.push_back(cell_layout(width, height, options_.cell_size, options_.cell_buffer, &why));
    if (layouts_.back().empty()) throw io::ConfigError(where + why);
    total_ += static_cast<long long>(layouts_.back().size());
  }
  const io::CellImage& image(int band) const { return memory_ ? *memory_ : images_[static_cast<std::size_t>(band)]; }

  std::vector<std::string> inputs_;
  MetadetectOptions options_;
  std::vector<std::vector<std::string>> files_;  // image files: per scene, a file per band
  std::vector<PsfexModel> models_;               // a PSFEx model per band; empty: the files' PSFs
  std::vector<std::string> psfex_files_;
  const io::CellImage* memory_ = nullptr;
  std::vector<std::unique_ptr<io::MedsFile>> tiles_;  // a cell tile per band
  std::vector<long long> boxes_;  // the tiles' cell sides
  long long max_tile_box_ = 0;    // the largest, found while laying out the cells
  io::CellImage cell_;  // a tile's cell as read
  std::vector<double> mask_;
  std::vector<std::vector<CellPlacement>> layouts_;
  long long total_ = 0, next_ = 0, in_file_ = 0, end_ = std::numeric_limits<long long>::max();
  int file_ = 0, loaded_ = -1;
  std::vector<io::CellImage> images_;  // the loaded scene's, a band each
  std::vector<PsfModel> psfs_;         // their PSF HDUs'
};

class CellFitter : public BatchFitter {
 public:
  explicit CellFitter(const MetadetectOptions& options) : measurer_(options) {}
  void fit(StampBatch& batch) override {
    CellBatch& data = cell_batch(batch);
    data.rows.clear();
    data.problems.assign(static_cast<std::size_t>(batch.count), "");
    for (int k = 0; k < batch.count; ++k) {
      const CellBatch::Cell& c = data.cells[static_cast<std::size_t>(k)];
      if (!c.problem.empty()) {  // one flagged row, as the measurer writes for a cell it cannot measure
        MetadetectRow r;
        r.cell = batch.records[k].id;
        r.shear_type = static_cast<int>(MetacalType::kNoshear);
        r.flags = kMetadetectCellFailed;
        data.rows.push_back(r);
        data.problems[static_cast<std::size_t>(k)] = c.problem;
        continue;
      }
      const ArenaObservation& o = batch.observations[c.first_observation];
      const std::size_t npix = static_cast<std::size_t>(o.box_size) * o.box_size;
      auto noise = [&](int b) {
        return c.noise_offset < 0 ? std::span<const double>()
                                  : std::span<const double>(data.noise).subspan(c.noise_offset + b * npix, npix);
      };
      MetadetectCell cell;
      cell.index = batch.records[k].id;
      cell.size = o.box_size;
      cell.pixels = batch.observations.pixels(o);
      cell.weight = batch.observations.weights(o);
      cell.noise = noise(0);
      other_bands_.clear();
      for (int b = 1; b < c.bands; ++b) {
        const ArenaObservation& ob = batch.observations[c.first_observation + b];
        other_bands_.push_back({batch.observations.pixels(ob), batch.observations.weights(ob), noise(b), &ob.psf});
      }
      cell.other_bands = other_bands_;
      cell.origin_x = c.place.x0, cell.origin_y = c.place.y0;
      cell.pixel_scale = c.pixel_scale;
      cell.psf = &o.psf;
      cell.keep_x0 = c.place.keep_x0, cell.keep_x1 = c.place.keep_x1;
      cell.keep_y0 = c.place.keep_y0, cell.keep_y1 = c.place.keep_y1;
      cell.lens_g1 = c.lens_g1, cell.lens_g2 = c.lens_g2;
      measurer_.measure(cell, &data.rows, &data.problems[static_cast<std::size_t>(k)]);
    }
  }

 private:
  CellMeasurer measurer_;
  std::vector<MetadetectBand> other_bands_;
};

class CellSink : public BatchSink {
 public:
  CellSink(io::MetadetectWriter& writer, const CellSource& source, MetadetectRunSummary* summary)
      : writer_(writer), source_(source), summary_(summary) {}
  void write(const StampBatch& batch) override {
    const CellBatch& data = cell_batch(batch);
    writer_.append(data.rows, batch.count);
    summary_->cells += batch.count;
    summary_->rows += static_cast<long long>(data.rows.size());
    for (int k = 0; k < batch.count; ++k) {
      const std::string& p = data.problems[static_cast<std::size_t>(k)];
      if (p.empty()) continue;
      ++summary_->cells_failed;
      if (summary_->problems.size() < kMaxProblems)
        summary_->problems.push_back(source_.input(data.cells[static_cast<std::size_t>(k)].file) + " cell " +
                                     std::to_string(batch.records[k].id) + ": " + p);
    }
  }

 private:
  io::MetadetectWriter& writer_;
  const CellSource& source_;
  MetadetectRunSummary* summary_;
};

// Python's: the rows kept in memory.
class CollectingSink : public BatchSink {
 public:
  void write(const StampBatch& batch) override {
    const CellBatch& data = cell_batch(batch);
    rows.insert(rows.end(), data.rows.begin(), data.rows.end());
    for (const std::string& p : data.problems) failed += !p.empty();
  }
  std::vector<MetadetectRow> rows;
  long long failed = 0;
};

// The options as header keys and fingerprint lines (one list: what identifies the run is what the
// header records).
std::vector<std::pair<std::string, std::string>> option_keys(const MetadetectOptions& o) {
  const DetectionOptions& d = o.detection;
  const DetectionStampOptions& s = o.stamp;
  return {{"CELLSIZE", std::to_string(o.cell_size)},
          {"CELLBUF", std::to_string(o.cell_buffer)},
          {"MCSTEP", number_text(o.step)},
          {"MCPSFDIL", number_text(o.psf_dilation)},
          {"MCRECONV", reconvolution_rule_name(o.reconvolution)},
          {"FIXNOISE", o.fixnoise ? "T" : "F"},
          {"IMGPREC", o.double_images ? "double" : "single"},
          {"PEROBJMC", o.per_object_metacal ? "T" : "F"},
          {"NOISEPLN", o.noise_plane ? "T" : "F"},
          {"MCSEED", std::to_string(o.seed)},
          {"MEASURE", metadetect_measurement_name(o.measurement)},
          {"WFWHM", number_text(o.weight_fwhm_arcsec())},
          {"RECENTRE", o.recentre ? "T" : "F"},
          {"KEEPUNL", o.keep_unlensed ? "T" : "F"},
          {"DETECTOR", detector_kind_name(d.detector)},
          {"DETTHR", number_text(d.threshold)},
          {"DETMINA", std::to_string(d.min_area)},
          {"DBLCONT", number_text(d.deblend_contrast)},
          {"DBLNTHR", std::to_string(d.deblend_thresholds)},
          {"FILTFWHM", number_text(d.filter_fwhm)},
          {"FILTSIZE", std::to_string(d.filter_size)},
          {"CLEAN", d.clean ? "T" : "F"},
          {"CLEANPAR", number_text(d.clean_param)},
          {"STAMPSZ", std::to_string(s.size)},
          {"BOXRFAC", number_text(s.radius_factor)},
          {"BOXRMIN", number_text(s.radius_min)},
          {"BOXPAD", number_text(s.padding)},
          {"BOXMIN", std::to_string(s.box_min)},
          {"BOXMAX", std::to_string(s.box_max)}};
}

// What stands for the band's name in an image path or --psfex.
constexpr std::string_view kBandField = "{band}";

bool has_band_field(const std::string& path) { return path.find(kBandField) != std::string::npos; }

std::vector<std::string> image_bands(const MetadetectRunOptions& options);

}  // namespace

std::string expand_band(const std::string& path, const std::string& band) {
  std::string out = path;
  for (std::size_t at = out.find(kBandField); at != std::string::npos; at = out.find(kBandField, at + band.size()))
    out.replace(at, kBandField.size(), band);
  return out;
}

namespace {

// Image files' bands: --bands names what `{band}` stands for in every path.
std::vector<std::string> image_bands(const MetadetectRunOptions& options) {
  std::vector<std::pair<std::string, std::string>> templates;  // (what, path)
  for (const std::string& in : options.inputs) templates.emplace_back("image path", in);
  if (!options.psfex.empty()) templates.emplace_back("--psfex", options.psfex);
  const std::vector<std::string>& names = options.bands;
  const std::size_t n = names.size();
  if (n == 0) {
    for (const auto& [what, path] : templates)
      if (has_band_field(path))
        throw io::ConfigError(what + " '" + path + "' holds '{band}' but no --bands names the bands it stands for");
    return {};
  }
  if (n > static_cast<std::size_t>(kMaxMetadetectBands))
    throw io::ConfigError("--bands names " + std::to_string(n) + " bands: at most " + std::to_string(kMaxMetadetectBands));
  if (std::string why; !io::are_band_names(names, &why)) throw io::ConfigError("--bands: " + why);
  if (n > 1) {
    for (const auto& [what, path] : templates)
      if (!has_band_field(path))
        throw io::ConfigError("--bands names " + std::to_string(n) + " bands but " + what + " '" + path +
                              "' holds no '{band}': each is a template, read once per band with {band} its name");
    for (const std::string& in : options.inputs)
      for (std::size_t b = 0; b < n; ++b)
        for (std::size_t a = 0; a < b; ++a)
          if (io::same_file(expand_band(in, names[a]), expand_band(in, names[b])))
            throw io::ConfigError("image " + expand_band(in, names[b]) + " is bands " + names[a] + " and " + names[b] +
                                  " of '" + in + "'");
  }
  return names;
}

// What measures one band only, whichever input carries the bands; `give` says how to give one.
void refuse_bands_for_one_band_measurements(const MetadetectOptions& o, std::size_t bands, const std::string& give) {
  if (bands < 2) return;
  if (o.per_object_metacal) throw io::ConfigError("--per-object-metacal measures one band: " + give);
  if (is_model_fit(o.measurement))
    throw io::ConfigError(std::string("--measurement ") + metadetect_measurement_name(o.measurement) +
                          " fits one band: " + give + ", or measure the bands with wmom or pgauss");
}

}  // namespace

std::vector<std::string> metadetect_bands(const MetadetectRunOptions& options) {
  if (!options.tile) {
    std::vector<std::string> names = image_bands(options);
    refuse_bands_for_one_band_measurements(options.metadetect, names.size(), "give --bands one band");
    return names;
  }
  if (!options.psfex.empty())
    throw io::ConfigError("--psfex gives image files' PSF: a --meds cell tile has its own PSF cutouts");
  const std::size_t n = options.inputs.size();
  if (n > static_cast<std::size_t>(kMaxMetadetectBands))
    throw io::ConfigError(std::to_string(n) + " --meds tiles: at most " + std::to_string(kMaxMetadetectBands) + " bands");
  if (!options.bands.empty() && options.bands.size() != n)
    throw io::ConfigError("--bands names " + std::to_string(options.bands.size()) + " band" +
                          (options.bands.size() == 1 ? "" : "s") + " but " + std::to_string(n) + " --meds tile" +
                          (n == 1 ? " is" : "s are") + " given: one tile per band, in the order of --bands");
  if (options.bands.empty() && n == 1) return {};
  std::vector<std::string> names = options.bands;
  if (names.empty())
    for (std::size_t b = 0; b < n; ++b) {
      // Appended, not "b" + to_string(b): GCC 12 warns (-Wrestrict) falsely on that concatenation.
      std::string name = "b";
      name += std::to_string(b);
      names.push_back(std::move(name));
    }
  if (std::string why; !io::are_band_names(names, &why)) throw io::ConfigError("--bands: " + why);
  for (std::size_t b = 0; b < n; ++b)
    for (std::size_t a = 0; a < b; ++a)
      if (io::same_file(options.inputs[a], options.inputs[b]))
        throw io::ConfigError("--meds " + options.inputs[b] + " is given twice (bands " + names[a] + " and " + names[b] + ")");
  refuse_bands_for_one_band_measurements(options.metadetect, n, "give one --meds tile");
  return names;
}

namespace {

// Every file a run reads: the inputs (each image path expanded per band, scene by scene), then the
// PSFEx models (one per band).
struct MetadetectFiles {
  CellSource::Images images;
  std::vector<std::string> files;
};

MetadetectFiles files_read(const MetadetectRunOptions& options, const std::vector<std::string>& bands) {
  MetadetectFiles out;
  if (options.tile) {
    out.files = options.inputs;
    return out;
  }
  const std::vector<std::string> names = bands.empty() ? std::vector<std::string>{""} : bands;
  for (const std::string& in : options.inputs) {
    out.images.names.push_back(in);
    out.images.files.emplace_back();
    for (const std::string& b : names) out.images.files.back().push_back(expand_band(in, b));
    out.files.insert(out.files.end(), out.images.files.back().begin(), out.images.files.back().end());
  }
  if (!options.psfex.empty())
    for (const std::string& b : names) out.images.psfex.push_back(expand_band(options.psfex, b));
  return out;
}

}  // namespace

void check_metadetect_outputs(const MetadetectRunOptions& options, const std::vector<std::string>& parts) {
  const MetadetectFiles read = files_read(options, metadetect_bands(options));
  for (const std::string& in : read.files)
    if (io::same_file(in, options.output)) throw io::ConfigError("the output '" + options.output + "' is the input");
  for (const std::string& p : read.images.psfex)
    if (io::same_file(p, options.output)) throw io::ConfigError("the output '" + options.output + "' is --psfex");
  // Nor may an input be one of the files written beside the output, or a part (a failed run removes them).
  std::vector<io::RunOutput> outputs = {table_output("-o", options.output)};
  for (const std::string& part : parts) outputs.push_back(table_output("-o (a rank's part)", part));
  std::vector<io::RunInput> reads;
  for (const std::string& in : read.files) reads.push_back({"input", io::fits_root_name(in)});
  for (const std::string& p : read.images.psfex) reads.push_back({"--psfex", p});
  io::check_outputs(outputs, reads, true);
  if (!options.resume) io::refuse_to_replace(options.output, options.overwrite);
}

std::vector<MetadetectRow> metadetect_image(const io::CellImage& image, const MetadetectOptions& options, int threads,
                                            long long* cells_failed) {
  std::string why;
  if (!options.IsValid(&why)) throw io::ConfigError(why);
  CellSource source(image, options);
  CollectingSink sink;
  set_detection_pixel_stack(static_cast<long long>(options.cell_size) * options.cell_size);
  PipelineOptions po;
  po.threads = threads;
  po.batch_size = 2;
  run_pipeline(source, sink, [&] { return std::make_unique<CellFitter>(options); }, po);
  if (cells_failed) *cells_failed = sink.failed;
  return std::move(sink.rows);
}

MetadetectRunSummary run_metadetect(const MetadetectRunOptions& options,
                                    const std::function<void(const MetadetectProgress&)>& progress) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  std::string why;
  if (!options.metadetect.IsValid(&why)) throw io::ConfigError(why);
  if (options.inputs.empty()) throw io::ConfigError("no input image: give IMAGE.fits or --input-list");
  if (options.output.empty()) throw io::ConfigError("no output: give -o OUT.fits");
  if (options.cells_per_batch < 1) throw io::ConfigError("cells per batch must be >= 1");
  shard_range(0, options.shard, options.shards);  // checks the shard before anything is read
  const std::vector<std::string> bands = metadetect_bands(options);
  const MetadetectFiles read = files_read(options, bands);
  const CellSource::Images& images = read.images;
  const std::vector<std::string>& files = read.files;
  check_metadetect_outputs(options);
  const io::OutputLock lock = io::OutputLock::acquire(options.output);

  CellSource source = options.tile ? CellSource(CellSource::Tile{options.inputs}, options.metadetect)
                                   : CellSource(images, options.metadetect);
  io::MetadetectWriterOptions wo;
  wo.path = options.output;
  wo.bands = bands;
  std::string fingerprint = "stampede " + std::string(program_version()) + " metadetect\n";
  wo.header.emplace_back("INPUTS", options.tile ? "cell tile" : "images");
  fingerprint += options.tile ? "cell tile\n" : "images\n";
  if (!bands.empty()) {
    std::string names;
    for (const std::string& b : bands) names += (names.empty() ? "" : ",") + b;
    wo.header.emplace_back("BANDS", names);
    fingerprint += "bands " + names + "\n";
  }
  for (const auto& [key, value] : option_keys(options.metadetect)) {
    wo.header.emplace_back(key, value);
    fingerprint += key + "=" + value + "\n";
  }
  for (std::size_t i = 0; i < files.size(); ++i) {
    const io::FileDigest d = io::digest_file(files[i]);
    const std::string n = std::to_string(i + 1);
    wo.header.emplace_back("INPUT" + n, files[i]);
    wo.header.emplace_back("DIGEST" + n, d.text());
    fingerprint += "input " + files[i] + " " + d.text() + "\n";
  }
  for (std::size_t i = 0; i < images.psfex.size(); ++i) {
    const io::FileDigest d = io::digest_file(images.psfex[i]);
    const std::string n = std::to_string(i + 1);
    wo.header.emplace_back("PSFEX" + n, images.psfex[i]);
    wo.header.emplace_back("PSFEXD" + n, d.text());
    fingerprint += "psfex " + images.psfex[i] + " " + d.text() + "\n";
  }
  wo.header.emplace_back("NCELLS", std::to_string(source.total_objects()));
  const ShardRange range = shard_range(source.total_objects(), options.shard, options.shards);
  const long long begin = range.begin, end = range.end;
  // RUNFP identifies the measurement, not the shard: the shards' tables join into the whole run's.
  const std::string runfp = RunFingerprint().text(fingerprint).hex();
  wo.header.emplace_back(kRunFingerprintKey, runfp);
  if (options.shards > 1) {
    wo.header.emplace_back(kShardKey, shard_text(options.shard, options.shards));
    fingerprint += "shard " + shard_text(options.shard, options.shards) + "\n";
  }
  wo.header_types = {{"CELLSIZE", io::HeaderValueType::kInteger}, {"CELLBUF", io::HeaderValueType::kInteger},
                     {"MCSTEP", io::HeaderValueType::kReal},      {"MCPSFDIL", io::HeaderValueType::kReal},
                     {"WFWHM", io::HeaderValueType::kReal},       {"DETTHR", io::HeaderValueType::kReal},
                     {"DETMINA", io::HeaderValueType::kInteger},  {"DBLCONT", io::HeaderValueType::kReal},
                     {"DBLNTHR", io::HeaderValueType::kInteger},  {"FILTFWHM", io::HeaderValueType::kReal},
                     {"FILTSIZE", io::HeaderValueType::kInteger}, {"NCELLS", io::HeaderValueType::kInteger},
                     {"STAMPSZ", io::HeaderValueType::kInteger}};
  wo.fingerprint = fingerprint;

  MetadetectRunSummary summary;
  if (options.resume && is_this_runs_complete_table(options.output, "METADETECT", runfp)) {
    summary.skipped = true;
    return summary;
  }
  std::unique_ptr<io::MetadetectWriter> writer;
  if (options.resume) {
    writer = io::MetadetectWriter::resume(wo, &summary.cells_resumed, &summary.resume_started);
  } else {
    writer = io::MetadetectWriter::create(wo);
  }
  source.skip_to(begin + summary.cells_resumed);
  source.set_end(end);
  try {
    // SEP's pixel stack is global: sized for a whole cell above the threshold before threads start.
    set_detection_pixel_stack(source.max_cell_pixels());
    CellSink sink(*writer, source, &summary);
    PipelineOptions po;
    po.threads = options.threads;
    po.batch_size = options.cells_per_batch;
    po.stop = options.stop;
    const long long resumed = summary.cells_resumed;
    const PipelineSummary ran = run_pipeline(
        source, sink, [&] { return std::make_unique<CellFitter>(options.metadetect); }, po,
        [&](const PipelineProgress& p) {
          if (progress) progress({resumed + p.objects_done, end - begin, p.seconds});
        });
    summary.threads = ran.threads;
    summary.stopped = ran.stopped;
    if (!ran.stopped) writer->finish();
  } catch (...) {
    writer->abandon();
    throw;
  }
  summary.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

}  // namespace stampede::app
