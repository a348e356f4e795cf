// The objects of a MEDS tile, or of one tile per band, as the pipeline's serial reader stage reads
// them (`stampede fit --meds`): for each object_data row, every usable single-epoch cutout of every
// band goes into the batch's observation arena (engine/pipeline/observation_arena.hpp) with its
// pixels, its weights masked (zero weight, bmask bits, uberseg from the seg map, non-finite
// pixels), its frame (the WCS Jacobian), its flux scale to the reference zero point and its PSF
// (the tile's psf cutout, the source image's PSFEx model at the object's position there, or the
// run's analytic PSF), not yet prepared. The batch then carries everything its fit needs: any
// thread or MPI rank fits it without opening the tile, and the fits depend on that object alone.
//
// A bad object is not a bad file: what makes a cutout or an object unusable is recorded in its
// band's reading (flags, the first problem naming file, object and cutout), and the fit stage
// turns it into a flagged row.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "engine/model/psfex_model.hpp"
#include "engine/pipeline/stamp_batch.hpp"
#include "io/meds_file.hpp"
#include "io/meds_options.hpp"

namespace stampede::io {

// A box larger than this is a flagged object: a fit renders each cutout on a Fourier grid of about
// (box + 57)^2 complex values per renderer and derivative, so a corrupt box size would cost
// gigabytes; DES and LSST boxes are <= 256.
inline constexpr long long kMaxFitBoxSize = 1024;

// Reads one tile's objects, one band of them, into an arena.
class MedsObjectReader {
 public:
  // `tile` must outlive it. options_psf: every cutout's PSF when options.psf = kOptions. Throws
  // ConfigError for options the tile cannot serve (meds_psf = cutouts without psf cutouts).
  MedsObjectReader(MedsFile& tile, const MedsOptions& options, const PsfModel& options_psf);
  // Row `row`'s cutouts as band `band` of the arena's current object (begin_object called); the
  // object's identity into *record (id, number, ra, dec) when not null.
  void read(long long row, int band, ObservationArena* arena, ObjectRecord* record);
  // The PSFEx files the reads would use (image_info's psf_path resolved against meds_psf_dir), in
  // image_info order, without repeats; empty unless the PSFs come from PSFEx models.
  std::vector<std::string> psfex_files() const;
  const MedsFile& tile() const { return tile_; }
  MedsPsfSource psf_source() const { return source_; }  // resolved: never kAuto

 private:
  std::filesystem::path psfex_file(const std::string& psf_path) const;
  // The PSFEx model of image_info row `file_id`, loaded on first use; null with *problem if not.
  const PsfexModel* psfex(long long file_id, std::string* problem);
  // Cutout k's PSF in its pixels; false with *why if there is none.
  bool cutout_psf(const MedsObject& o, int k, ArenaObservation* obs, std::string* why);

  MedsFile& tile_;
  MedsOptions options_;
  PsfModel options_psf_;
  MedsPsfSource source_;
  std::vector<std::optional<PsfexModel>> models_;
  std::vector<std::string> model_errors_;
  std::vector<double> seg_, bmask_;
};

// The pipeline's source over one tile or one per band (the same objects in the same order).
class MedsObjectSource final : public StampSource {
 public:
  // Opens every tile (a FitsError names one that cannot be), checks that they list the same objects
  // (check_band_tiles) and that the options can serve them (ConfigError).
  MedsObjectSource(const std::vector<std::string>& paths, const MedsOptions& options, const PsfModel& options_psf);
  long long total_objects() const override { return tiles_.front().size(); }
  void skip_to(long long index) override { next_ = index; }
  void set_end(long long end) override { end_ = end; }
  bool fill(StampBatch& batch) override;
  // The PSFEx files of every tile, without repeats.
  std::vector<std::string> psfex_files() const;

 private:
  std::deque<MedsFile> tiles_;  // a deque: the readers hold references into it
  std::vector<MedsObjectReader> readers_;
  long long next_ = 0, end_ = -1;
};

// How far (arcsec) an object's ra, dec in another band's tile may lie from the first tile's. Tiles
// cut from one detection catalogue agree exactly; 1 arcsec allows per-band astrometry and rounding,
// and is about a galaxy's size: farther, the id names another object on the sky (a tile of another
// field, or one whose object_data was renumbered).
inline constexpr double kMaxBandOffsetArcsec = 1.0;

// Throws ConfigError unless every tile lists the objects of the first in the same order at the
// same places (within kMaxBandOffsetArcsec; an object without a finite position in any tile is not
// compared): the message names the tile, and the row and ids that differ first (or the object
// counts), or the tiles, the object's id and row and the offset.
void check_band_tiles(std::span<MedsFile* const> tiles);

// Uberseg: in a box_size^2 seg cutout, zero the weight of every pixel whose nearest labelled seg
// pixel (Euclidean, pixel centres) belongs to another object than `number`; ties keep the pixel.
// A cutout with no labelled pixel is left alone.
void apply_uberseg(std::span<const double> seg, int box_size, std::int64_t number, std::span<double> weight);

}  // namespace stampede::io
