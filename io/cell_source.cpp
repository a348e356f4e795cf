// The metadetection run's serial reader; see cell_source.hpp.
#include "io/cell_source.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "io/config_error.hpp"
#include "io/option_text.hpp"
#include "io/fits_error.hpp"
#include "io/star_catalogue.hpp"

namespace stampede::io {
namespace {

// The side x side window of an image plane (`width` wide) at the cell's place, row by row into `to`.
template <class T>
void copy_cell(std::span<const T> plane, long width, const CellPlacement& place, int side, T* to) {
  for (int y = 0; y < side; ++y)
    std::copy_n(plane.begin() + static_cast<long>(static_cast<std::size_t>(place.y0 + y) * width + place.x0), side,
                to + static_cast<std::size_t>(y) * side);
}

}  // namespace
namespace {

// For messages: enough digits to tell apart what the 1e-6 checks refuse.
std::string short_number(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

}  // namespace

CellSource::CellSource(const Images& in, const MetadetectOptions& options)
    : inputs_(in.names), options_(options), files_(in.files) {
  for (const std::vector<std::string>& bands : files_) {
    const CellImageShape shape = read_cell_image_shape(bands[0]);
    for (std::size_t b = 1; b < bands.size(); ++b) {
      const CellImageShape other = read_cell_image_shape(bands[b]);
      if (other.width != shape.width || other.height != shape.height)
        throw ConfigError(bands[b] + " is " + std::to_string(other.width) + " x " + std::to_string(other.height) +
                              " pixels, " + bands[0] + " " + std::to_string(shape.width) + " x " +
                              std::to_string(shape.height) + ": a scene's bands must share its pixels");
      if (std::abs(other.pixel_scale / shape.pixel_scale - 1) > 1e-6)
        throw ConfigError(bands[b] + "'s pixel scale " + short_number(other.pixel_scale) + " arcsec differs from " +
                              bands[0] + "'s " + short_number(shape.pixel_scale) + ": a scene's bands must share its pixels");
    }
    add_layout(shape.width, shape.height, bands[0] + ": ");
  }
  for (const std::string& path : in.psfex) {
    try {
      models_.push_back(read_psfex_model(path));
    } catch (const FitsError& e) {
      throw FitsError(std::string("--psfex: ") + e.what());
    }
    // Evaluated once here, so that a sampling the metacal images cannot use (PSF_SAMP is image
    // pixels per sample: only 1 / integer is an image of the cells' pixels) stops the run, not each cell.
    std::string why;
    if (!models_.back().image_at(models_.back().zero_x, models_.back().zero_y, &why))
      throw ConfigError("--psfex " + path + ": " + why);
    psfex_files_.push_back(path);
  }
}

CellSource::CellSource(std::span<const CellImage> bands, const MetadetectOptions& options)
    : inputs_{"image"}, options_(options), files_(1), memory_(bands.data()) {
  if (bands.empty() || bands.size() > static_cast<std::size_t>(kMaxMetadetectBands))
    throw ConfigError("from 1 to " + std::to_string(kMaxMetadetectBands) + " bands' images, not " +
                      std::to_string(bands.size()));
  for (std::size_t b = 0; b < bands.size(); ++b) {
    files_[0].push_back("band " + std::to_string(b));
    if (bands[b].width != bands[0].width || bands[b].height != bands[0].height ||
        std::abs(bands[b].pixel_scale / bands[0].pixel_scale - 1) > 1e-6)
      throw ConfigError("band " + std::to_string(b) + "'s image is " + std::to_string(bands[b].width) + " x " +
                        std::to_string(bands[b].height) + " px at " + format_double(bands[b].pixel_scale) +
                        "\"/px, band 0's " + std::to_string(bands[0].width) + " x " + std::to_string(bands[0].height) +
                        " px at " + format_double(bands[0].pixel_scale) + "\"/px: the bands must share the cell's pixels");
  }
  add_layout(bands[0].width, bands[0].height, "");
}

CellSource::CellSource(const Tile& t, const MetadetectOptions& options) : inputs_(t.paths), options_(options) {
  if (options.keep_unlensed)
    throw ConfigError(t.paths[0] + ": --keep-unlensed needs the scene's shear, which a cell tile does not record "
                          "(give `sim cells`'s image files)");
  for (const std::string& tile : t.paths) {
    tiles_.push_back(std::make_unique<MedsFile>(MedsFile::open(tile)));
    const MedsFile& m = *tiles_.back();
    if (!m.has(MedsCutoutType::kWeight))
      throw ConfigError(tile + ": no weight_cutouts HDU: detection needs the noise level");
    if (!m.has_psf_cutouts()) throw ConfigError(tile + ": no PSF cutouts: " + m.psf_cutouts_problem());
    if (m.size() != tiles_[0]->size())
      throw ConfigError(tile + ": " + std::to_string(m.size()) + " cells (object_data rows), " + t.paths[0] +
                            " " + std::to_string(tiles_[0]->size()) + ": a band's tile must hold the same cells");
  }
  std::vector<CellPlacement> places;
  for (long long row = 0; row < tiles_[0]->size(); ++row) {
    CellPlacement p;
    for (std::size_t b = 0; b < tiles_.size(); ++b) {
      const std::string& tile = t.paths[b];
      const MedsObject o = tiles_[b]->object(row);
      if (!o.problem.empty()) throw ConfigError(tile + ": object_data row " + std::to_string(row) + ": " + o.problem);
      if (o.cutouts.empty()) throw ConfigError(tile + ": object_data row " + std::to_string(row) + " has no cutout");
      const MedsCutout& c = o.cutouts[0];
      if (b == 0) {
        if (2L * options.cell_buffer >= o.box_size)
          throw ConfigError(tile + ": cell " + std::to_string(row) + " is " + std::to_string(o.box_size) +
                                " pixels, not more than twice --cell-buffer " + std::to_string(options.cell_buffer));
        max_tile_box_ = std::max(max_tile_box_, o.box_size);
        p.x0 = static_cast<int>(c.orig_start_col), p.y0 = static_cast<int>(c.orig_start_row);
        p.keep_x0 = p.keep_y0 = options.cell_buffer - 0.5;
        p.keep_x1 = p.keep_y1 = o.box_size - options.cell_buffer - 0.5;
        boxes_.push_back(o.box_size);
      } else if (o.box_size != boxes_.back() || c.orig_start_col != p.x0 || c.orig_start_row != p.y0) {
        throw ConfigError(tile + ": cell " + std::to_string(row) + " is " + std::to_string(o.box_size) +
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

long long CellSource::max_cell_pixels() const {
  const long long side = std::max<long long>(options_.cell_size, max_tile_box_);
  return side * side;
}

void CellSource::skip_to(long long index) {
  next_ = index;
  file_ = 0;
  while (file_ < static_cast<int>(layouts_.size()) && index >= static_cast<long long>(layouts_[file_].size()))
    index -= static_cast<long long>(layouts_[file_].size()), ++file_;
  in_file_ = index;
}

bool CellSource::fill(StampBatch& batch) {
  CellBatch& data = batch.payload<CellBatch>();
  data.cells.clear();
  data.stars.clear();
  data.noise_used = 0, data.bits_used = 0, data.mfrac_used = 0;
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

// The tile's next cell into the batch: a band per tile, each an observation, with its noise
// cutout where the tiles have them.
void CellSource::fill_tile_cell(StampBatch& batch, CellBatch& data) {
  const int bands = static_cast<int>(tiles_.size());
  const int size = static_cast<int>(boxes_[static_cast<std::size_t>(in_file_)]);
  const std::size_t npix = static_cast<std::size_t>(size) * size;
  CellBatch::Cell cell;
  cell.place = layouts_[0][in_file_];
  cell.first_observation = static_cast<int>(batch.observations.size()), cell.bands = bands;
  const bool noise = options_.noise_plane &&
                     std::all_of(tiles_.begin(), tiles_.end(), [](const auto& t) { return t->has(MedsCutoutType::kNoise); });
  if (noise) cell.noise_offset = static_cast<long long>(data.add_noise(npix, bands));
  batch.observations.begin_object(bands);
  for (int b = 0; b < bands; ++b) {
    MedsFile& tile = *tiles_[static_cast<std::size_t>(b)];
    const std::string where = inputs_[static_cast<std::size_t>(b)] + ": cell " + std::to_string(in_file_);
    const MedsObject o = tile.object(in_file_);
    const MedsCutout& c = o.cutouts[0];
    const double det = c.dudcol * c.dvdrow - c.dudrow * c.dvdcol, scale = std::sqrt(std::abs(det));
    if (!(scale > 0) || std::abs(c.dudrow) > 1e-6 * scale || std::abs(c.dvdcol) > 1e-6 * scale ||
        std::abs(c.dudcol - c.dvdrow) > 1e-6 * scale)
      throw ConfigError(where + ": its WCS Jacobian is not the pixel scale times the unit matrix "
                            "(du/dcol = dv/drow, no rotation): not supported yet");
    if (b == 0) {
      cell.pixel_scale = scale;
    } else if (std::abs(scale / cell.pixel_scale - 1) > 1e-6) {
      throw ConfigError(where + ": its pixel scale " + std::to_string(scale) + " arcsec differs from " +
                            inputs_[0] + "'s " + std::to_string(cell.pixel_scale) + ": the bands must share the cell's pixels");
    }
    cell_.width = cell_.height = size;
    cell_.pixel_scale = scale;
    cell_.pixels.resize(npix), cell_.weight.resize(npix), mask_.clear(), cell_.noise.clear();
    tile.read_cutout(o, 0, MedsCutoutType::kImage, cell_.pixels);
    tile.read_cutout(o, 0, MedsCutoutType::kWeight, cell_.weight);
    if (tile.has(MedsCutoutType::kBmask)) {
      mask_.resize(npix);
      tile.read_cutout(o, 0, MedsCutoutType::kBmask, mask_);
    }
    if (noise) {
      cell_.noise.resize(npix);
      tile.read_cutout(o, 0, MedsCutoutType::kNoise, cell_.noise);
    }
    bits_scratch_.resize(npix);
    if (tile.has(MedsCutoutType::kBmask)) {
      mask_bits(mask_, bits_scratch_);
      or_bits(bits_scratch_, npix, 0, data, &cell);
    }
    if (tile.has(MedsCutoutType::kMfrac)) {
      plane_scratch_.resize(npix);
      tile.read_cutout(o, 0, MedsCutoutType::kMfrac, plane_scratch_);
      if (const std::string why = mfrac_problem(plane_scratch_, size); !why.empty())
        throw ConfigError(where + ": mfrac_cutouts: " + why);
      add_mfrac(plane_scratch_, npix, bands, data, &cell);
    }
    if (tile.has(MedsCutoutType::kOrmask)) {
      plane_scratch_.resize(npix);
      tile.read_cutout(o, 0, MedsCutoutType::kOrmask, plane_scratch_);
      mask_bits(plane_scratch_, bits_scratch_);
      or_bits(bits_scratch_, npix, 1, data, &cell);
    }
    try {
      apply_cell_masks(mask_, &cell_);
    } catch (const std::invalid_argument& e) {
      throw ConfigError(where + ": " + e.what());
    }
    if (!c.psf_problem.empty()) throw ConfigError(where + ": " + c.psf_problem);
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
    check_sky(pixels, weights, b, bands, &cell);
    if (noise)
      std::copy(cell_.noise.begin(), cell_.noise.end(),
                data.noise.begin() + cell.noise_offset + static_cast<long long>(b * npix));
  }
  add_stars(cell.place.x0, cell.place.y0, size, data, &cell);
  data.cells.push_back(std::move(cell));
  batch.records[batch.count].id = next_;
  ++batch.count, ++in_file_, ++next_;
}

// The scene's next cell into the batch: a band per file, each an observation, with its NOISE
// plane where every band has one; its PSF the file's or the PSFEx model's at the cell.
void CellSource::fill_image_cell(StampBatch& batch, CellBatch& data) {
  const int bands = static_cast<int>(files_[static_cast<std::size_t>(file_)].size());
  if (loaded_ != file_) {
    images_.resize(static_cast<std::size_t>(bands));
    psfs_.clear();
    for (int b = 0; b < bands; ++b) {
      if (!memory_) images_[static_cast<std::size_t>(b)] = read_cell_image(files_[file_][b], models_.empty());
      if (models_.empty()) psfs_.push_back(PsfModel::Image(image(b).psf));
    }
    const CellImage& first = image(0);
    const CelestialWcs* wcs = first.wcs ? &*first.wcs : nullptr;
    if (!star_hdu_.empty() && !memory_)
      stars_ = read_star_table(files_[file_][0], star_margin_, star_hdu_).discs(wcs, first.pixel_scale, files_[file_][0]);
    if (catalogue_) stars_ = catalogue_->discs(wcs, first.pixel_scale, files_[file_][0]);
    loaded_ = file_;
  }
  const CellPlacement& place = layouts_[file_][in_file_];
  const int s = options_.cell_size;
  const std::size_t npix = static_cast<std::size_t>(s) * s;
  CellBatch::Cell cell;
  cell.file = file_, cell.place = place, cell.pixel_scale = image(0).pixel_scale;
  if (options_.keep_unlensed) {
    if (!std::isfinite(image(0).g1) || !std::isfinite(image(0).g2))
      throw ConfigError(files_[file_][0] + ": --keep-unlensed needs the scene's shear, header keys G1 and G2 "
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
    const CellImage& im = image(b);
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
    copy_cell(std::span<const double>(im.pixels), im.width, place, s, pixels.data());
    copy_cell(std::span<const double>(im.weight), im.width, place, s, weights.data());
    if (noise) copy_cell(std::span<const double>(im.noise), im.width, place, s, data.noise.data() + band_noise);
    // Nothing to measure: said with the image's reasons, so a NaN image is not taken for bad weights.
    if (cell.problem.empty() && im.masked > 0 && std::all_of(weights.begin(), weights.end(), [](double w) { return w == 0; }))
      cell.problem = std::string(bands > 1 ? "band " + std::to_string(b) + ": " : "") +
                     "every pixel of the cell is masked (the image's " + std::to_string(im.masked) + " masked pixels: " +
                     im.masked_text() + ")";
    check_sky(pixels, weights, b, bands, &cell);
    if (!im.mfrac.empty()) {
      plane_scratch_.resize(npix);
      copy_cell(std::span<const double>(im.mfrac), im.width, place, s, plane_scratch_.data());
      add_mfrac(plane_scratch_, npix, bands, data, &cell);
    }
    for (int k = 0; k < 2; ++k) {
      const std::vector<std::int32_t>& plane = k == 0 ? im.bmask : im.ormask;
      if (plane.empty()) continue;
      bits_scratch_.resize(npix);
      copy_cell(std::span<const std::int32_t>(plane), im.width, place, s, bits_scratch_.data());
      or_bits(bits_scratch_, npix, k, data, &cell);
    }
  }
  add_stars(cell.place.x0, cell.place.y0, s, data, &cell);
  data.cells.push_back(std::move(cell));
  batch.records[batch.count].id = next_;
  ++batch.count, ++in_file_, ++next_;
}

void CellSource::check_sky(std::span<const double> pixels, std::span<const double> weights, int band, int bands,
                           CellBatch::Cell* cell) {
  const double sky = cell_sky_level(pixels, weights, &sky_scratch_);
  if (const std::string why = cell_sky_problem(sky); cell->problem.empty() && !why.empty())
    cell->problem = std::string(bands > 1 ? "band " + std::to_string(band) + ": " : "") + why;
}

void CellSource::add_mfrac(std::span<const double> plane, std::size_t npix, int bands, CellBatch& data,
                           CellBatch::Cell* cell) {
  if (cell->mfrac_offset < 0) cell->mfrac_offset = static_cast<long long>(data.add_mfrac(npix));
  double* to = data.mfrac.data() + cell->mfrac_offset;
  for (std::size_t p = 0; p < npix; ++p) to[p] += plane[p] / bands;
}

void CellSource::or_bits(std::span<const std::int32_t> bits, std::size_t npix, int plane, CellBatch& data,
                         CellBatch::Cell* cell) {
  if (cell->bits_offset < 0) cell->bits_offset = static_cast<long long>(data.add_bits(npix));
  std::int32_t* to = data.bits.data() + cell->bits_offset + static_cast<long long>(static_cast<std::size_t>(plane) * npix);
  for (std::size_t p = 0; p < npix; ++p) to[p] |= bits[p];
}

void CellSource::set_stars(StarCatalogue stars) {
  if (stars.sky && !tiles_.empty())
    throw ConfigError(stars.where + " places its stars by ra, dec: a cell tile's WCS is not read (give x, y in the "
                      "tile's pixels)");
  if (!stars.sky) stars_ = stars.stars;  // the same discs in every input
  catalogue_ = std::move(stars);
}

void CellSource::add_stars(double x0, double y0, int side, CellBatch& data, CellBatch::Cell* cell) const {
  cell->first_star = data.stars.size();
  for (const StarDisc& s : stars_) {
    const StarDisc in{s.x - x0, s.y - y0, s.radius};
    if (in.x + in.radius < 0 || in.y + in.radius < 0 || in.x - in.radius > side - 1 || in.y - in.radius > side - 1) continue;
    data.stars.push_back(in);
  }
  cell->stars = data.stars.size() - cell->first_star;
}

void CellSource::add_layout(long width, long height, const std::string& where) {
  std::string why;
  layouts_.push_back(cell_layout(width, height, options_.cell_size, options_.cell_buffer, &why));
  if (layouts_.back().empty()) throw ConfigError(where + why);
  total_ += static_cast<long long>(layouts_.back().size());
}

}  // namespace stampede::io
