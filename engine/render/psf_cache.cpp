// Shared PSF kernel cache; see psf_cache.hpp.
#include "engine/render/psf_cache.hpp"

namespace stampede {

std::shared_ptr<const PsfKernel> PsfKernelCache::moffat(const kernels::MoffatProfile& psf, FftPlanCache& plans,
                                                        std::string* error) {
  const Key key{psf.beta, psf.fwhm, psf.e1, psf.e2, psf.truncation};
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = kernels_.find(key);
    if (it != kernels_.end()) return it->second;
  }
  PsfOptions options;
  options.type = PsfType::kMoffat;
  options.moffat = psf;
  auto kernel = PsfKernel::build(options, geometry_, plans, error);
  if (!kernel) return nullptr;
  std::lock_guard<std::mutex> lock(mutex_);
  auto [it, inserted] = kernels_.emplace(key, kernel);
  if (inserted) {
    order_.push_back(key);
    while (order_.size() > capacity_) {
      kernels_.erase(order_.front());
      order_.pop_front();
    }
  }
  return it->second;
}

}  // namespace stampede
