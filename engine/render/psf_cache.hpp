// Prepared PSFs shared by all threads of a run, built once per distinct PSF model. Bounded:
// per-object PSFs (psf_input = moffat_catalog) must not grow memory with the catalogue, so the
// oldest entries are dropped past `capacity` (PSFs in use stay alive through their shared_ptr).
//
// One cache serves one renderer kind and options (a run's): the key is the PSF model alone,
// analytic kinds by their parameters, images by identity (the entry keeps its image alive, so the
// address cannot be reused by another image while the entry exists).
#pragma once

#include <cstddef>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>

#include "engine/model/psf_model.hpp"
#include "engine/render/renderer.hpp"

namespace stampede {

class PsfCache {
 public:
  explicit PsfCache(std::size_t capacity) : capacity_(capacity) {}

  // The prepared form of `psf`, built by renderer.prepare_psf on a miss; null (with *error) when it
  // cannot be built (failures are not cached). Thread-safe; the build happens outside the lock with
  // the caller's renderer (two threads may build the same one once each; the first stored wins).
  std::shared_ptr<const PreparedPsf> get(const PsfModel& psf, Renderer& renderer, std::string* error);

  std::size_t size() const;

 private:
  // Kind, then the analytic parameters (zero where unused), then the image's address.
  using Key = std::tuple<int, double, double, double, double, double, const PsfImage*>;
  struct Entry {
    std::shared_ptr<const PreparedPsf> prepared;
    std::shared_ptr<const PsfImage> image;  // keeps the keyed address alive
  };
  static Key key_of(const PsfModel& psf);

  std::size_t capacity_;
  mutable std::mutex mutex_;
  std::map<Key, Entry> entries_;
  std::deque<Key> order_;
};

}  // namespace stampede
