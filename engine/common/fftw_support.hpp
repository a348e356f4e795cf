// What every FFTW user in the process shares: the planner lock, wisdom files and FFTW-aligned
// storage. Apart from the fitting renderer's plans (engine/render/fft_plans.hpp) so that the
// simulator, which makes plans of its own, does not depend on the renderers.
#pragma once

#include <cstddef>
#include <mutex>
#include <string>

namespace stampede {

// The one lock around every FFTW planner call in the process.
std::mutex& fftw_planner_mutex();

// FFTW wisdom: plans made with kMeasure are recorded, and a later run that loads the same wisdom
// makes the same plans (so its results are bitwise identical). False when the file is missing or
// unreadable (load) or cannot be written (save).
bool load_fftw_wisdom(const std::string& path);
bool save_fftw_wisdom(const std::string& path);

// fftw_malloc'd storage: SIMD-aligned as the plans expect.
class AlignedBuffer {
 public:
  AlignedBuffer() = default;
  explicit AlignedBuffer(std::size_t bytes);
  AlignedBuffer(AlignedBuffer&& other) noexcept;
  AlignedBuffer& operator=(AlignedBuffer&& other) noexcept;
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;
  ~AlignedBuffer();
  void* data() const { return data_; }

 private:
  void* data_ = nullptr;
};

}  // namespace stampede
