// PSF kernels shared by all threads of a run, built once per distinct PSF. Bounded: per-object
// PSFs (psf_input = moffat_catalog) must not grow memory with the catalogue, so the oldest
// entries are dropped past `capacity` (kernels in use stay alive through their shared_ptr).
#pragma once

#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>

#include "engine/render/psf_kernel.hpp"

namespace stampede {

class PsfKernelCache {
 public:
  PsfKernelCache(const GridGeometry& geometry, std::size_t capacity) : geometry_(geometry), capacity_(capacity) {}

  // The kernel of a Moffat PSF; null (with *error) when it cannot be built. Thread-safe; the build
  // happens outside the lock with the caller's plans (two threads may build the same one once each).
  std::shared_ptr<const PsfKernel> moffat(const kernels::MoffatProfile& psf, FftPlanCache& plans, std::string* error);

 private:
  using Key = std::tuple<double, double, double, double, double>;
  GridGeometry geometry_;
  std::size_t capacity_;
  std::mutex mutex_;
  std::map<Key, std::shared_ptr<const PsfKernel>> kernels_;
  std::deque<Key> order_;
};

}  // namespace stampede
