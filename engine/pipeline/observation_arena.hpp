// The observations a batch carries for its objects: ragged, each object with any number of them (a
// grid or catalogue stamp: one, in its pixel grid; a MEDS object: its cutouts over one band or
// several), of any box size, their pixels and weights in one arena per batch. A batch is reused for
// the whole run, so the arena grows to the largest batch seen and then allocates nothing.
//
// The serial reader stage fills it (pixels read, masks applied, PSFs looked up); the parallel fit
// stage prepares each PSF for its renderer and fits. What reading found (flags, the first problem,
// pixel counts) travels with each object and band, so the fit stage decides the row from the whole
// story.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "engine/fit/observation.hpp"
#include "engine/model/pixel_frame.hpp"
#include "engine/model/psf_model.hpp"

namespace stampede {

// One usable cutout as read: its pixels and weights at `offset` in the arena, its PSF not yet
// prepared (that is numerics: the fit stage's). The fit stage takes it as the one image type,
// ObservationArena::observation.
struct ArenaObservation {
  std::size_t offset = 0;  // first of box_size^2 pixels in ObservationArena::pixels / weights
  int box_size = 0;
  int cutout = 0;          // its index among the object's cutouts in its tile (for messages)
  int band = 0;
  PixelFrame frame;
  double flux_scale = 1;   // data = flux_scale x model (the zero point's factor)
  PsfModel psf;            // in the cutout's pixels (a stamp's: its catalogue or caller's PSF, if any)
  bool psf_from_image = false;  // psf is the tile's PSF cutout or a PSFEx model's image
  // A grid or catalogue stamp's weights may be a mask, or absent (no weight map: the fit's
  // noise_sigma on every pixel).
  WeightKind weight_kind = WeightKind::kInverseVariance;
  bool weighted = true;
};

// What reading one band of one object found.
struct BandReading {
  std::uint32_t flags = 0;   // input flags (object_record.hpp) raised while reading
  bool readable = true;      // false: the object or its box cannot be fitted (nothing was read)
  long long pixels_total = 0, pixels_unmasked = 0;  // of the cutouts read (masked fraction's terms)
  int first = 0, count = 0;  // its observations in the arena
  std::string problem;       // the first reason a cutout or the object was not used ("" none)
};

class ObservationArena {
 public:
  // Starts a batch: no objects, no observations (the storage is kept).
  void clear() {
    objects_ = 0;
    observations_.clear();
    used_ = 0;
  }
  // Starts the next object with `bands` readings (all cleared).
  void begin_object(int bands) {
    const std::size_t need = static_cast<std::size_t>(objects_ + 1) * static_cast<std::size_t>(bands);
    if (readings_.size() < need) readings_.resize(need);
    for (int b = 0; b < bands; ++b) readings_[static_cast<std::size_t>(objects_) * bands + b] = BandReading{};
    bands_ = bands;
    ++objects_;
  }
  BandReading& reading(int object, int band) {
    return readings_[static_cast<std::size_t>(object) * bands_ + band];
  }
  const BandReading& reading(int object, int band) const {
    return readings_[static_cast<std::size_t>(object) * bands_ + band];
  }
  int bands() const { return bands_; }
  int objects() const { return objects_; }
  // Space for one more observation of box_size^2 pixels: its entry (offset and box set) and spans
  // to fill. Spans stay valid until the next add().
  ArenaObservation& add(int box_size, std::span<double>* pixels, std::span<double>* weights) {
    const std::size_t npix = static_cast<std::size_t>(box_size) * box_size;
    if (pixels_.size() < used_ + npix) pixels_.resize(used_ + npix), weights_.resize(used_ + npix);
    ArenaObservation& o = observations_.emplace_back();
    o.offset = used_;
    o.box_size = box_size;
    used_ += npix;
    *pixels = std::span<double>(pixels_.data() + o.offset, npix);
    *weights = std::span<double>(weights_.data() + o.offset, npix);
    return o;
  }
  // The next object as one stamp in its pixel grid (one band, one observation): its entry and
  // spans to fill, as add().
  ArenaObservation& add_stamp(int box_size, std::span<double>* pixels, std::span<double>* weights) {
    begin_object(1);
    BandReading& r = reading(objects_ - 1, 0);
    r.first = size();
    r.count = 1;
    return add(box_size, pixels, weights);
  }
  // Object `object`'s first observation (a stamp's only one).
  const ArenaObservation& first_of(int object) const { return (*this)[reading(object, 0).first]; }
  // Drops the last observation added (a cutout found unusable after its pixels were read).
  void drop_last() {
    used_ = observations_.back().offset;
    observations_.pop_back();
  }
  int size() const { return static_cast<int>(observations_.size()); }
  const ArenaObservation& operator[](int k) const { return observations_[static_cast<std::size_t>(k)]; }
  ArenaObservation& operator[](int k) { return observations_[static_cast<std::size_t>(k)]; }
  std::span<const double> pixels(const ArenaObservation& o) const {
    return {pixels_.data() + o.offset, static_cast<std::size_t>(o.box_size) * o.box_size};
  }
  // Empty for an observation without weights (ArenaObservation::weighted).
  std::span<const double> weights(const ArenaObservation& o) const {
    if (!o.weighted) return {};
    return {weights_.data() + o.offset, static_cast<std::size_t>(o.box_size) * o.box_size};
  }
  // o as the fits, metacal and metadetection take an image: its pixels and weights here (valid
  // until the next add()), its PSF as the model read; the prepared PSF is the fit stage's to set.
  Observation observation(const ArenaObservation& o) const {
    Observation image;
    image.pixels = pixels(o), image.weight = weights(o);
    image.box_size = o.box_size;
    image.frame = o.frame;
    image.flux_scale = o.flux_scale;
    image.band = o.band;
    image.weight_kind = o.weight_kind;
    image.psf_model = &o.psf;
    return image;
  }
  std::size_t pixels_used() const { return used_; }
  // For a transport (the MPI driver): the raw arrays of pixels_used() values, the observations
  // having been added in the sender's order (add() lays them out alike).
  double* pixel_data() { return pixels_.data(); }
  double* weight_data() { return weights_.data(); }
  const double* pixel_data() const { return pixels_.data(); }
  const double* weight_data() const { return weights_.data(); }

 private:
  std::vector<ArenaObservation> observations_;
  std::vector<BandReading> readings_;
  std::vector<double> pixels_, weights_;
  std::size_t used_ = 0;
  int objects_ = 0;
  int bands_ = 1;
};

}  // namespace stampede
