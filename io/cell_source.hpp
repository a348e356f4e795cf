// The serial reader of a metadetection run (the pipeline's source): the run's cells in order,
// each with its bands' pixels, weights, NOISE planes and PSF, from image files (a scene per file,
// cut into cells by engine/metadetect/cell_layout, read whole when its first cell is due), a cell
// tile per band (each object_data row a cell), or one image in memory (Python's arrays). The cells
// go into the batch's CellBatch payload (engine/metadetect/cell_batch.hpp).
//
// Every problem of the inputs that stops the run throws io::ConfigError or io::FitsError naming the
// file, HDU, row or cell: in the constructor where the files' headers show it (before any thread
// starts), else when the cell is read. A cell whose PSFEx model fails there is not an error: the
// cell carries the problem and is measured as one flagged row.
#pragma once

#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "engine/metadetect/cell_batch.hpp"
#include "engine/metadetect/cell_layout.hpp"
#include "engine/metadetect/metadetect_options.hpp"
#include "engine/model/psf_model.hpp"
#include "engine/pipeline/stamp_batch.hpp"
#include "io/cell_image_reader.hpp"
#include "io/meds_file.hpp"
#include "io/psfex_file.hpp"
#include "io/star_catalogue.hpp"

namespace stampede::io {

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
  CellSource(const Images& in, const MetadetectOptions& options);
  // An image in memory per band (not copied: they must outlive the source), each the same size
  // and pixel scale.
  CellSource(std::span<const CellImage> bands, const MetadetectOptions& options);
  // A cell tile (DES Y6's "pizza slices"): each object_data row a cell, cutout 0 its coadd with a
  // weight (and bmask, noise) cutout and its PSF in the psf HDU; the cell's place in the tile from
  // orig_start_row/col, its pixel scale from the WCS Jacobian (which must be the scale times the
  // unit matrix: the metacal shear is applied in the cell's pixels). Several bands: a tile per
  // band, whose rows are the same cells (the same box and place in each).
  struct Tile {
    std::vector<std::string> paths;  // a tile per band
  };
  CellSource(const Tile& t, const MetadetectOptions& options);

  // Bright stars' discs in every input's pixels (0-based; the image's, or a cell tile's): each cell
  // carries those that reach it, in its own pixels (engine/metadetect/star_disc).
  // A catalogue of ra, dec is placed on each image by its WCS (a cell tile's cells: refused).
  void set_stars(StarCatalogue stars);
  // Or each image file's own stars: its (first band's) HDU `extname`, read with the scene, radii
  // widened by `margin` (io/star_catalogue).
  void set_star_hdu(std::string extname, double margin) { star_hdu_ = std::move(extname), star_margin_ = margin; }

  long long total_objects() const override { return total_; }
  // The largest cell's pixels (SEP's pixel stack must hold a whole cell above the threshold).
  long long max_cell_pixels() const;
  void set_end(long long end) override { end_ = end; }
  void skip_to(long long index) override;
  // The input (file, template or tile) a cell's CellBatch::Cell::file names.
  const std::string& input(int file) const { return inputs_[static_cast<std::size_t>(file)]; }
  bool fill(StampBatch& batch) override;

 private:
  void fill_tile_cell(StampBatch& batch, CellBatch& data);
  void fill_image_cell(StampBatch& batch, CellBatch& data);
  void add_layout(long width, long height, const std::string& where);
  // The stars reaching the side x side cell whose pixel (0, 0) is the input's (x0, y0), into the batch.
  void add_stars(double x0, double y0, int side, CellBatch& data, CellBatch::Cell* cell) const;
  // A band's masked fractions (npix of the cell) added into the cell's mean over `bands` (a band
  // without a plane adds none).
  static void add_mfrac(std::span<const double> plane, std::size_t npix, int bands, CellBatch& data,
                        CellBatch::Cell* cell);
  // A band's mask bits (plane 0 BMASK, 1 ORMASK; npix of the cell) OR'ed into the cell's.
  static void or_bits(std::span<const std::int32_t> bits, std::size_t npix, int plane, CellBatch& data,
                      CellBatch::Cell* cell);
  // Sets the cell's problem (where it has none) when band's sky is not background-subtracted.
  void check_sky(std::span<const double> pixels, std::span<const double> weights, int band, int bands,
                 CellBatch::Cell* cell);
  const CellImage& image(int band) const {
    return memory_ ? memory_[band] : images_[static_cast<std::size_t>(band)];
  }

  std::vector<std::string> inputs_;
  MetadetectOptions options_;
  std::vector<std::vector<std::string>> files_;  // image files: per scene, a file per band
  std::vector<PsfexModel> models_;               // a PSFEx model per band; empty: the files' PSFs
  std::vector<std::string> psfex_files_;
  const CellImage* memory_ = nullptr;
  std::vector<std::unique_ptr<MedsFile>> tiles_;  // a cell tile per band
  std::vector<long long> boxes_;  // the tiles' cell sides
  long long max_tile_box_ = 0;    // the largest, found while laying out the cells
  CellImage cell_;  // a tile's cell as read
  std::vector<double> mask_, plane_scratch_;  // a tile's bmask cutout; an mfrac or ormask plane
  std::vector<std::int32_t> bits_scratch_;    // a plane's bits
  std::vector<double> sky_scratch_;
  std::vector<StarDisc> stars_;  // the current file's discs
  std::optional<StarCatalogue> catalogue_;
  std::string star_hdu_;
  double star_margin_ = 0;
  std::vector<std::vector<CellPlacement>> layouts_;
  long long total_ = 0, next_ = 0, in_file_ = 0, end_ = std::numeric_limits<long long>::max();
  int file_ = 0, loaded_ = -1;
  std::vector<CellImage> images_;  // the loaded scene's, a band each
  std::vector<PsfModel> psfs_;     // their PSF HDUs'
};

}  // namespace stampede::io
