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

#include "app/version.hpp"
#include "engine/metadetect/cell_layout.hpp"
#include "engine/metadetect/cell_measurer.hpp"
#include "engine/pipeline/pipeline.hpp"
#include "io/cell_image_reader.hpp"
#include "io/config_error.hpp"
#include "io/file_digest.hpp"
#include "io/meds_file.hpp"
#include "io/metadetect_writer.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"

namespace stampede::app {
namespace {

constexpr int kMaxProblems = 100;

// A batch's cells (what the source read) and the rows they yield (what the fit stage measured).
struct CellBatch : BatchExtension {
  struct Cell {
    int file = 0;
    CellPlacement place;
    double pixel_scale = 0;
  };
  std::vector<Cell> cells;
  std::vector<MetadetectRow> rows;
  std::vector<std::string> problems;  // per cell, "" none
};

CellBatch& cell_batch(StampBatch& b) {
  if (!b.extension) b.extension = std::make_unique<CellBatch>();
  return static_cast<CellBatch&>(*b.extension);
}
const CellBatch& cell_batch(const StampBatch& b) { return static_cast<const CellBatch&>(*b.extension); }

// The serial reader: every file's cells in order, a file read whole when its first cell is due.
class CellSource : public StampSource {
 public:
  CellSource(const std::vector<std::string>& inputs, const MetadetectOptions& options) : inputs_(inputs), options_(options) {
    for (const std::string& path : inputs_) {
      const io::CellImageShape shape = io::read_cell_image_shape(path);
      add_layout(shape.width, shape.height, path + ": ");
    }
  }
  // One image in memory (not copied: it must outlive the source).
  CellSource(const io::CellImage& image, const MetadetectOptions& options)
      : inputs_{"image"}, options_(options), memory_(&image) {
    add_layout(image.width, image.height, "");
  }
  // A cell tile (DES Y6's "pizza slices"): each object_data row a cell, cutout 0 its coadd with a
  // weight (and bmask) cutout and its PSF in the psf HDU; the cell's place in the tile from
  // orig_start_row/col, its pixel scale from the WCS Jacobian (which must be the scale times the
  // unit matrix: the metacal shear is applied in the cell's pixels).
  struct Tile {
    std::string path;
  };
  CellSource(const Tile& t, const MetadetectOptions& options) : inputs_{t.path}, options_(options) {
    const std::string& tile = t.path;
    tile_ = std::make_unique<io::MedsFile>(io::MedsFile::open(tile));
    if (!tile_->has(io::MedsCutoutType::kWeight))
      throw io::ConfigError(tile + ": no weight_cutouts HDU: detection needs the noise level");
    if (!tile_->has_psf_cutouts()) throw io::ConfigError(tile + ": no PSF cutouts: " + tile_->psf_cutouts_problem());
    std::vector<CellPlacement> places;
    for (long long row = 0; row < tile_->size(); ++row) {
      const io::MedsObject o = tile_->object(row);
      if (!o.problem.empty()) throw io::ConfigError(tile + ": object_data row " + std::to_string(row) + ": " + o.problem);
      if (o.cutouts.empty()) throw io::ConfigError(tile + ": object_data row " + std::to_string(row) + " has no cutout");
      const io::MedsCutout& c = o.cutouts[0];
      if (2L * options.cell_buffer >= o.box_size)
        throw io::ConfigError(tile + ": cell " + std::to_string(row) + " is " + std::to_string(o.box_size) +
                              " pixels, not more than twice --cell-buffer " + std::to_string(options.cell_buffer));
      max_tile_box_ = std::max(max_tile_box_, o.box_size);
      CellPlacement p;
      p.x0 = static_cast<int>(c.orig_start_col), p.y0 = static_cast<int>(c.orig_start_row);
      p.keep_x0 = p.keep_y0 = options.cell_buffer - 0.5;
      p.keep_x1 = p.keep_y1 = o.box_size - options.cell_buffer - 0.5;
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
    batch.observations.clear();
    batch.first_object = next_;
    batch.count = 0;
    while (batch.count < batch.capacity() && file_ < static_cast<int>(layouts_.size()) && next_ < end_) {
      if (in_file_ >= static_cast<long long>(layouts_[file_].size())) {
        ++file_, in_file_ = 0;
        continue;
      }
      if (tile_) {
        fill_tile_cell(batch, data);
        continue;
      }
      if (loaded_ != file_) {
        if (!memory_) image_ = io::read_cell_image(inputs_[file_]);
        psf_ = PsfModel::Image(image().psf);
        loaded_ = file_;
      }
      const CellPlacement& place = layouts_[file_][in_file_];
      const int s = options_.cell_size;
      batch.observations.begin_object(1);
      std::span<double> pixels, weights;
      ArenaObservation& o = batch.observations.add(s, &pixels, &weights);
      o.psf = psf_;
      for (int y = 0; y < s; ++y) {
        const std::size_t from = static_cast<std::size_t>(place.y0 + y) * image().width + place.x0;
        std::copy_n(image().pixels.begin() + from, s, pixels.begin() + static_cast<std::size_t>(y) * s);
        std::copy_n(image().weight.begin() + from, s, weights.begin() + static_cast<std::size_t>(y) * s);
      }
      data.cells.push_back({file_, place, image().pixel_scale});
      batch.records[batch.count].id = next_;
      ++batch.count, ++in_file_, ++next_;
    }
    return batch.count > 0;
  }

 private:
  // The tile's next cell into the batch.
  void fill_tile_cell(StampBatch& batch, CellBatch& data) {
    const std::string where = inputs_[0] + ": cell " + std::to_string(in_file_);
    const io::MedsObject o = tile_->object(in_file_);
    const io::MedsCutout& c = o.cutouts[0];
    const double det = c.dudcol * c.dvdrow - c.dudrow * c.dvdcol, scale = std::sqrt(std::abs(det));
    if (!(scale > 0) || std::abs(c.dudrow) > 1e-6 * scale || std::abs(c.dvdcol) > 1e-6 * scale ||
        std::abs(c.dudcol - c.dvdrow) > 1e-6 * scale)
      throw io::ConfigError(where + ": its WCS Jacobian is not the pixel scale times the unit matrix "
                            "(du/dcol = dv/drow, no rotation): not supported yet");
    const int size = static_cast<int>(o.box_size);
    const std::size_t npix = static_cast<std::size_t>(size) * size;
    cell_.width = cell_.height = size;
    cell_.pixel_scale = scale;
    cell_.pixels.resize(npix), cell_.weight.resize(npix), mask_.clear();
    tile_->read_cutout(o, 0, io::MedsCutoutType::kImage, cell_.pixels);
    tile_->read_cutout(o, 0, io::MedsCutoutType::kWeight, cell_.weight);
    if (tile_->has(io::MedsCutoutType::kBmask)) {
      mask_.resize(npix);
      tile_->read_cutout(o, 0, io::MedsCutoutType::kBmask, mask_);
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
    tile_->read_psf_cutout(o, 0, img->pixels);
    img->centre_x = c.psf_cutout_col, img->centre_y = c.psf_cutout_row;
    batch.observations.begin_object(1);
    std::span<double> pixels, weights;
    ArenaObservation& obs = batch.observations.add(size, &pixels, &weights);
    obs.psf = PsfModel::Image(std::move(img));
    std::copy(cell_.pixels.begin(), cell_.pixels.end(), pixels.begin());
    std::copy(cell_.weight.begin(), cell_.weight.end(), weights.begin());
    data.cells.push_back({0, layouts_[0][in_file_], scale});
    batch.records[batch.count].id = next_;
    ++batch.count, ++in_file_, ++next_;
  }

  void add_layout(long width, long height, const std::string& where) {
    std::string why;
    layouts_.push_back(cell_layout(width, height, options_.cell_size, options_.cell_buffer, &why));
    if (layouts_.back().empty()) throw io::ConfigError(where + why);
    total_ += static_cast<long long>(layouts_.back().size());
  }
  const io::CellImage& image() const { return memory_ ? *memory_ : image_; }

  std::vector<std::string> inputs_;
  MetadetectOptions options_;
  const io::CellImage* memory_ = nullptr;
  std::unique_ptr<io::MedsFile> tile_;
  long long max_tile_box_ = 0;  // the tile's largest cell side, found while laying out its cells
  io::CellImage cell_;  // a tile's cell as read
  std::vector<double> mask_;
  std::vector<std::vector<CellPlacement>> layouts_;
  long long total_ = 0, next_ = 0, in_file_ = 0, end_ = std::numeric_limits<long long>::max();
  int file_ = 0, loaded_ = -1;
  io::CellImage image_;
  PsfModel psf_;
};

class CellFitter : public BatchFitter {
 public:
  explicit CellFitter(const MetadetectOptions& options) : measurer_(options) {}
  void fit(StampBatch& batch) override {
    CellBatch& data = cell_batch(batch);
    data.rows.clear();
    data.problems.assign(static_cast<std::size_t>(batch.count), "");
    for (int k = 0; k < batch.count; ++k) {
      const ArenaObservation& o = batch.observations[k];
      const CellBatch::Cell& c = data.cells[static_cast<std::size_t>(k)];
      MetadetectCell cell;
      cell.index = batch.records[k].id;
      cell.size = o.box_size;
      cell.pixels = batch.observations.pixels(o);
      cell.weight = batch.observations.weights(o);
      cell.origin_x = c.place.x0, cell.origin_y = c.place.y0;
      cell.pixel_scale = c.pixel_scale;
      cell.psf = &o.psf;
      cell.keep_x0 = c.place.keep_x0, cell.keep_x1 = c.place.keep_x1;
      cell.keep_y0 = c.place.keep_y0, cell.keep_y1 = c.place.keep_y1;
      measurer_.measure(cell, &data.rows, &data.problems[static_cast<std::size_t>(k)]);
    }
  }

 private:
  CellMeasurer measurer_;
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

std::string number_text(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

// The options as header keys and fingerprint lines (one list: what identifies the run is what the
// header records).
std::vector<std::pair<std::string, std::string>> option_keys(const MetadetectOptions& o) {
  const DetectionOptions& d = o.detection;
  const DetectionStampOptions& s = o.stamp;
  return {{"CELLSIZE", std::to_string(o.cell_size)},
          {"CELLBUF", std::to_string(o.cell_buffer)},
          {"MCSTEP", number_text(o.step)},
          {"MCPSFDIL", number_text(o.psf_dilation)},
          {"FIXNOISE", o.fixnoise ? "T" : "F"},
          {"PEROBJMC", o.per_object_metacal ? "T" : "F"},
          {"MCSEED", std::to_string(o.seed)},
          {"WFWHM", number_text(o.weight_fwhm)},
          {"DETTHR", number_text(d.threshold)},
          {"DETMINA", std::to_string(d.min_area)},
          {"DBLCONT", number_text(d.deblend_contrast)},
          {"DBLNTHR", std::to_string(d.deblend_thresholds)},
          {"FILTFWHM", number_text(d.filter_fwhm)},
          {"FILTSIZE", std::to_string(d.filter_size)},
          {"CLEAN", d.clean ? "T" : "F"},
          {"CLEANPAR", number_text(d.clean_param)},
          {"BOXRFAC", number_text(s.radius_factor)},
          {"BOXRMIN", number_text(s.radius_min)},
          {"BOXPAD", number_text(s.padding)},
          {"BOXMIN", std::to_string(s.box_min)},
          {"BOXMAX", std::to_string(s.box_max)}};
}

}  // namespace

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
  if (options.shards < 1 || options.shard < 0 || options.shard >= options.shards)
    throw io::ConfigError("--shard " + std::to_string(options.shard) + "/" + std::to_string(options.shards) +
                          ": must be I/N with 0 <= I < N");
  for (const std::string& in : options.inputs)
    if (io::same_file(in, options.output)) throw io::ConfigError("the output '" + options.output + "' is the input");
  const io::OutputLock lock = io::OutputLock::acquire(options.output);
  if (!options.resume) io::refuse_to_replace(options.output, options.overwrite);

  if (options.tile && options.inputs.size() != 1)
    throw io::ConfigError("--meds takes one cell tile (the bands of a tile are not supported yet)");
  CellSource source = options.tile ? CellSource(CellSource::Tile{options.inputs[0]}, options.metadetect)
                                   : CellSource(options.inputs, options.metadetect);
  io::MetadetectWriterOptions wo;
  wo.path = options.output;
  std::string fingerprint = "stampede " + std::string(program_version()) + " metadetect\n";
  wo.header.emplace_back("INPUTS", options.tile ? "cell tile" : "images");
  fingerprint += options.tile ? "cell tile\n" : "images\n";
  for (const auto& [key, value] : option_keys(options.metadetect)) {
    wo.header.emplace_back(key, value);
    fingerprint += key + "=" + value + "\n";
  }
  for (std::size_t i = 0; i < options.inputs.size(); ++i) {
    const io::FileDigest d = io::digest_file(options.inputs[i]);
    const std::string n = std::to_string(i + 1);
    wo.header.emplace_back("INPUT" + n, options.inputs[i]);
    wo.header.emplace_back("DIGEST" + n, d.text());
    fingerprint += "input " + options.inputs[i] + " " + d.text() + "\n";
  }
  wo.header.emplace_back("NCELLS", std::to_string(source.total_objects()));
  const long long total = source.total_objects();
  const long long begin = total * options.shard / options.shards, end = total * (options.shard + 1) / options.shards;
  if (options.shards > 1) {
    const std::string shard = std::to_string(options.shard) + "/" + std::to_string(options.shards);
    wo.header.emplace_back("SHARD", shard);
    fingerprint += "shard " + shard + "\n";
  }
  wo.header_types = {{"CELLSIZE", io::HeaderValueType::kInteger}, {"CELLBUF", io::HeaderValueType::kInteger},
                     {"MCSTEP", io::HeaderValueType::kReal},      {"MCPSFDIL", io::HeaderValueType::kReal},
                     {"WFWHM", io::HeaderValueType::kReal},       {"DETTHR", io::HeaderValueType::kReal},
                     {"DETMINA", io::HeaderValueType::kInteger},  {"DBLCONT", io::HeaderValueType::kReal},
                     {"DBLNTHR", io::HeaderValueType::kInteger},  {"FILTFWHM", io::HeaderValueType::kReal},
                     {"FILTSIZE", io::HeaderValueType::kInteger}, {"NCELLS", io::HeaderValueType::kInteger}};
  wo.fingerprint = fingerprint;

  MetadetectRunSummary summary;
  std::unique_ptr<io::MetadetectWriter> writer;
  if (options.resume) {
    writer = io::MetadetectWriter::resume(wo, &summary.cells_resumed);
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
