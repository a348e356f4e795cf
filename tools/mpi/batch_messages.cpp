// Batches on the wire; see batch_messages.hpp.
#include "tools/mpi/batch_messages.hpp"

#include <cstring>
#include <stdexcept>
#include <type_traits>

namespace stampede::mpi_driver {

namespace {

static_assert(std::is_trivially_copyable_v<ObjectRecord>, "rows travel as bytes");
static_assert(std::is_trivially_copyable_v<kernels::MoffatProfile>, "per-object PSFs travel as bytes");

struct Header {
  int count, stamp_size, has_weights, weights_are_mask, per_object_psf;
  long long sequence, first_object;
};

template <class T>
void put(std::vector<char>* out, std::size_t* at, const T* p, std::size_t n) {
  std::memcpy(out->data() + *at, p, n * sizeof(T));
  *at += n * sizeof(T);
}
template <class T>
void get(const char* data, std::size_t size, std::size_t* at, T* p, std::size_t n) {
  if (*at + n * sizeof(T) > size) throw std::runtime_error("MPI batch message is truncated");
  std::memcpy(p, data + *at, n * sizeof(T));
  *at += n * sizeof(T);
}

}  // namespace

std::size_t max_batch_message(int capacity, int stamp_size, bool per_object_psf) {
  const std::size_t npix = static_cast<std::size_t>(stamp_size) * stamp_size;
  return sizeof(Header) + 2 * capacity * npix * sizeof(double) + capacity * sizeof(ObjectRecord) +
         (per_object_psf ? capacity * sizeof(kernels::MoffatProfile) : 0);
}

void pack_batch(const StampBatch& b, std::vector<char>* out) {
  const bool per_object = !b.psf.empty();
  const std::size_t n = static_cast<std::size_t>(b.count) * b.npix();
  out->resize(sizeof(Header) + (b.has_weights ? 2 : 1) * n * sizeof(double) + b.count * sizeof(ObjectRecord) +
              (per_object ? b.count * sizeof(kernels::MoffatProfile) : 0));
  const Header h{b.count, b.stamp_size, b.has_weights, b.weights_are_mask, per_object, b.sequence, b.first_object};
  std::size_t at = 0;
  put(out, &at, &h, 1);
  put(out, &at, b.pixels.data(), n);
  if (b.has_weights) put(out, &at, b.weights.data(), n);
  put(out, &at, b.records.data(), static_cast<std::size_t>(b.count));
  for (int k = 0; per_object && k < b.count; ++k) {
    if (b.psf[k].kind != PsfKind::kMoffat)
      throw std::runtime_error("the MPI driver sends per-object PSFs only as Moffat profiles");
    put(out, &at, &b.psf[k].moffat, 1);
  }
}

void unpack_batch(const char* data, std::size_t size, StampBatch* b) {
  Header h{};
  std::size_t at = 0;
  get(data, size, &at, &h, 1);
  if (h.stamp_size != b->stamp_size || h.count < 0 || h.count > b->capacity() ||
      (h.per_object_psf != 0) != !b->psf.empty())
    throw std::runtime_error("MPI batch message does not fit this rank's batches");
  b->count = h.count;
  b->sequence = h.sequence;
  b->first_object = h.first_object;
  b->has_weights = h.has_weights != 0;
  b->weights_are_mask = h.weights_are_mask != 0;
  const std::size_t n = static_cast<std::size_t>(h.count) * b->npix();
  get(data, size, &at, b->pixels.data(), n);
  if (b->has_weights) get(data, size, &at, b->weights.data(), n);
  get(data, size, &at, b->records.data(), static_cast<std::size_t>(h.count));
  for (int k = 0; h.per_object_psf && k < h.count; ++k) {
    kernels::MoffatProfile m;
    get(data, size, &at, &m, 1);
    b->psf[k] = PsfModel::Moffat(m);
  }
}

}  // namespace stampede::mpi_driver
