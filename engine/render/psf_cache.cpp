// Shared prepared-PSF cache; see psf_cache.hpp.
#include "engine/render/psf_cache.hpp"

namespace stampede {

PsfCache::Key PsfCache::key_of(const PsfModel& psf) {
  switch (psf.kind) {
    case PsfKind::kMoffat: {
      const kernels::MoffatProfile& m = psf.moffat;
      return {static_cast<int>(psf.kind), m.beta, m.fwhm, m.e1, m.e2, m.truncation, nullptr};
    }
    case PsfKind::kAiry:
      return {static_cast<int>(psf.kind), psf.airy.lambda_over_d, psf.airy.obscuration, 0.0, 0.0, 0.0, nullptr};
    case PsfKind::kGaussian:
      return {static_cast<int>(psf.kind), psf.gaussian.fwhm, psf.gaussian.e1, psf.gaussian.e2, 0.0, 0.0, nullptr};
    case PsfKind::kImage: break;
  }
  return {static_cast<int>(psf.kind), 0.0, 0.0, 0.0, 0.0, 0.0, psf.image.get()};
}

std::shared_ptr<const PreparedPsf> PsfCache::get(const PsfModel& psf, Renderer& renderer, std::string* error) {
  const Key key = key_of(psf);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.find(key);
    if (it != entries_.end()) return it->second.prepared;
  }
  auto prepared = renderer.prepare_psf(psf, error);
  if (!prepared) return nullptr;
  std::lock_guard<std::mutex> lock(mutex_);
  auto [it, inserted] = entries_.emplace(key, Entry{prepared, psf.kind == PsfKind::kImage ? psf.image : nullptr});
  if (!inserted) return it->second.prepared;  // another thread stored it first
  order_.push_back(key);
  while (order_.size() > capacity_) {
    entries_.erase(order_.front());
    order_.pop_front();
  }
  return prepared;
}

std::size_t PsfCache::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_.size();
}

}  // namespace stampede
