// Batches on the wire; see batch_messages.hpp.
#include "tools/mpi/batch_messages.hpp"

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace stampede::mpi_driver {

namespace {

static_assert(std::is_trivially_copyable_v<ObjectRecord>, "rows travel as bytes");
static_assert(std::is_trivially_copyable_v<kernels::MoffatProfile>, "PSFs travel as bytes");
static_assert(std::is_trivially_copyable_v<kernels::AiryProfile>, "PSFs travel as bytes");
static_assert(std::is_trivially_copyable_v<PixelFrame>, "frames travel as bytes");

struct Header {
  int count, arena_objects, arena_bands, arena_observations, any_weighted;
  long long sequence, first_object, arena_pixels;
};

// One band of one object as read, less its problem text (which follows it).
struct ReadingWire {
  std::uint32_t flags;
  int readable, first, count;
  long long pixels_total, pixels_unmasked;
  std::uint64_t problem_length;
};

// One observation less its PSF image's samples (which follow it).
struct ObservationWire {
  std::uint64_t offset;
  int box_size, cutout, band, psf_from_image, psf_kind, weight_kind, weighted;
  PixelFrame frame;
  double flux_scale;
  kernels::MoffatProfile moffat;
  kernels::AiryProfile airy;
  int image_nx, image_ny, image_oversampling, image_pixel_integrated;
  double image_centre_x, image_centre_y;
};

class Writer {
 public:
  explicit Writer(std::vector<char>* out) : out_(out) { out_->clear(); }
  template <class T>
  void put(const T* p, std::size_t n) {
    const std::size_t at = out_->size();
    out_->resize(at + n * sizeof(T));
    if (n > 0) std::memcpy(out_->data() + at, p, n * sizeof(T));
  }
  template <class T>
  void put(const T& v) {
    put(&v, 1);
  }
  void put_text(const std::string& s) {
    const std::uint64_t n = s.size();
    put(n);
    put(s.data(), s.size());
  }

 private:
  std::vector<char>* out_;
};

class Reader {
 public:
  Reader(const char* data, std::size_t size) : data_(data), size_(size) {}
  template <class T>
  void get(T* p, std::size_t n) {
    if (n > (size_ - at_) / sizeof(T)) throw std::runtime_error("MPI batch message is truncated");
    if (n > 0) std::memcpy(p, data_ + at_, n * sizeof(T));
    at_ += n * sizeof(T);
  }
  template <class T>
  T get() {
    T v;
    get(&v, 1);
    return v;
  }
  void get_text(std::string* s, std::uint64_t n) {
    if (n > size_ - at_) throw std::runtime_error("MPI batch message is truncated");
    s->assign(data_ + at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
  }

 private:
  const char* data_;
  std::size_t size_;
  std::size_t at_ = 0;
};

}  // namespace

void pack_batch(const StampBatch& b, std::vector<char>* out) {
  const ObservationArena& arena = b.observations;
  // A grid without a weight map has no weights to send (its arena's weight slots are unused).
  int any_weighted = 0;
  for (int k = 0; k < arena.size(); ++k) any_weighted |= arena[k].weighted ? 1 : 0;
  Writer w(out);
  w.put(Header{b.count, arena.objects(), arena.bands(), arena.size(), any_weighted, b.sequence, b.first_object,
               static_cast<long long>(arena.pixels_used())});
  w.put(b.records.data(), static_cast<std::size_t>(b.count));
  for (int o = 0; o < arena.objects(); ++o)
    for (int band = 0; band < arena.bands(); ++band) {
      const BandReading& r = arena.reading(o, band);
      w.put(ReadingWire{r.flags, r.readable, r.first, r.count, r.pixels_total, r.pixels_unmasked, r.problem.size()});
      w.put(r.problem.data(), r.problem.size());
    }
  for (int k = 0; k < arena.size(); ++k) {
    const ArenaObservation& o = arena[k];
    ObservationWire ow{};
    ow.offset = o.offset, ow.box_size = o.box_size, ow.cutout = o.cutout, ow.band = o.band;
    ow.psf_from_image = o.psf_from_image, ow.psf_kind = static_cast<int>(o.psf.kind);
    ow.weight_kind = static_cast<int>(o.weight_kind), ow.weighted = o.weighted;
    ow.frame = o.frame, ow.flux_scale = o.flux_scale, ow.moffat = o.psf.moffat, ow.airy = o.psf.airy;
    const PsfImage* image = o.psf.kind == PsfKind::kImage ? o.psf.image.get() : nullptr;
    if (image) {
      ow.image_nx = image->nx, ow.image_ny = image->ny, ow.image_oversampling = image->oversampling;
      ow.image_pixel_integrated = image->pixel_integrated;
      ow.image_centre_x = image->centre_x, ow.image_centre_y = image->centre_y;
    }
    w.put(ow);
    if (image) {
      w.put(static_cast<std::uint64_t>(image->pixels.size()));
      w.put(image->pixels.data(), image->pixels.size());
    }
  }
  w.put(arena.pixel_data(), arena.pixels_used());
  if (any_weighted) w.put(arena.weight_data(), arena.pixels_used());
}

void unpack_batch(const char* data, std::size_t size, StampBatch* b) {
  Reader r(data, size);
  const Header h = r.get<Header>();
  if (h.count < 0 || h.count > b->capacity() || h.arena_objects < h.count)
    throw std::runtime_error("MPI batch message does not fit this rank's batches");
  b->begin(h.first_object);
  b->count = h.count;
  b->sequence = h.sequence;
  r.get(b->records.data(), static_cast<std::size_t>(h.count));
  ObservationArena& arena = b->observations;
  for (int o = 0; o < h.arena_objects; ++o) {
    arena.begin_object(h.arena_bands);
    for (int band = 0; band < h.arena_bands; ++band) {
      const ReadingWire rw = r.get<ReadingWire>();
      BandReading& reading = arena.reading(o, band);
      reading.flags = rw.flags, reading.readable = rw.readable != 0, reading.first = rw.first, reading.count = rw.count;
      reading.pixels_total = rw.pixels_total, reading.pixels_unmasked = rw.pixels_unmasked;
      r.get_text(&reading.problem, rw.problem_length);
    }
  }
  for (int k = 0; k < h.arena_observations; ++k) {
    const ObservationWire ow = r.get<ObservationWire>();
    std::span<double> pixels, weights;
    ArenaObservation& o = arena.add(ow.box_size, &pixels, &weights);
    if (o.offset != ow.offset) throw std::runtime_error("MPI batch message: observations out of order");
    o.cutout = ow.cutout, o.band = ow.band, o.psf_from_image = ow.psf_from_image != 0;
    o.frame = ow.frame, o.flux_scale = ow.flux_scale;
    o.weight_kind = static_cast<WeightKind>(ow.weight_kind), o.weighted = ow.weighted != 0;
    o.psf.kind = static_cast<PsfKind>(ow.psf_kind);
    o.psf.moffat = ow.moffat, o.psf.airy = ow.airy;
    o.psf.image.reset();
    if (o.psf.kind == PsfKind::kImage) {
      auto image = std::make_shared<PsfImage>();
      image->nx = ow.image_nx, image->ny = ow.image_ny, image->oversampling = ow.image_oversampling;
      image->pixel_integrated = ow.image_pixel_integrated != 0;
      image->centre_x = ow.image_centre_x, image->centre_y = ow.image_centre_y;
      const auto samples = r.get<std::uint64_t>();
      if (samples > size) throw std::runtime_error("MPI batch message is truncated");
      image->pixels.resize(static_cast<std::size_t>(samples));
      r.get(image->pixels.data(), image->pixels.size());
      o.psf.image = std::move(image);
    }
  }
  if (static_cast<long long>(arena.pixels_used()) != h.arena_pixels)
    throw std::runtime_error("MPI batch message: the observations' pixels do not add up");
  r.get(arena.pixel_data(), arena.pixels_used());
  if (h.any_weighted) r.get(arena.weight_data(), arena.pixels_used());
}

void pack_results(const StampBatch& b, std::vector<char>* out) {
  Writer w(out);
  w.put(b.records.data(), static_cast<std::size_t>(b.count));
  for (int k = 0; k < b.count; ++k) w.put_text(b.problems[static_cast<std::size_t>(k)]);
}

void unpack_results(const char* data, std::size_t size, StampBatch* b) {
  Reader r(data, size);
  r.get(b->records.data(), static_cast<std::size_t>(b->count));
  for (int k = 0; k < b->count; ++k) r.get_text(&b->problems[static_cast<std::size_t>(k)], r.get<std::uint64_t>());
}

void pack_recipe(const app::WorkerRecipe& recipe, std::vector<char>* out) {
  Writer w(out);
  w.put_text(recipe.kind);
  w.put(recipe.batch_size);
  w.put(static_cast<std::uint64_t>(recipe.lines.size()));
  for (const auto& [key, value] : recipe.lines) {
    w.put_text(key);
    w.put_text(value);
  }
}

app::WorkerRecipe unpack_recipe(const char* data, std::size_t size) {
  Reader r(data, size);
  app::WorkerRecipe recipe;
  r.get_text(&recipe.kind, r.get<std::uint64_t>());
  recipe.batch_size = r.get<int>();
  const auto lines = r.get<std::uint64_t>();
  if (lines > size) throw std::runtime_error("MPI recipe message is truncated");
  recipe.lines.resize(static_cast<std::size_t>(lines));
  for (auto& [key, value] : recipe.lines) {
    r.get_text(&key, r.get<std::uint64_t>());
    r.get_text(&value, r.get<std::uint64_t>());
  }
  return recipe;
}

}  // namespace stampede::mpi_driver
