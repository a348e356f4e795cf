// FFTW's shared state and aligned storage; see fftw_support.hpp.
#include "engine/common/fftw_support.hpp"

#include <fftw3.h>

#include <cstring>
#include <new>
#include <utility>

namespace stampede {

std::mutex& fftw_planner_mutex() {
  static std::mutex mutex;
  return mutex;
}

bool load_fftw_wisdom(const std::string& path) {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  return fftw_import_wisdom_from_filename(path.c_str()) != 0;
}

bool save_fftw_wisdom(const std::string& path) {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  return fftw_export_wisdom_to_filename(path.c_str()) != 0;
}

AlignedBuffer::AlignedBuffer(std::size_t bytes) : data_(fftw_malloc(bytes)) {
  if (!data_) throw std::bad_alloc();
  std::memset(data_, 0, bytes);
}
AlignedBuffer::AlignedBuffer(AlignedBuffer&& other) noexcept : data_(std::exchange(other.data_, nullptr)) {}
AlignedBuffer& AlignedBuffer::operator=(AlignedBuffer&& other) noexcept {
  if (this != &other) {
    if (data_) fftw_free(data_);
    data_ = std::exchange(other.data_, nullptr);
  }
  return *this;
}
AlignedBuffer::~AlignedBuffer() {
  if (data_) fftw_free(data_);
}

}  // namespace stampede
