// No heap allocation per stamp in steady state: after the first fit has warmed up the fitter,
// further fits allocate nothing, with either renderer. Counted by replacing the global operator
// new in this binary and, outside sanitizer builds (whose runtimes own malloc), malloc and
// posix_memalign too, so C allocations (FFTW's buffers, a library's temporary) are caught as well.
#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>

#include "engine/fit/fitter.hpp"
#include "engine/render/renderer_factory.hpp"
#include "support/reference_data.hpp"

namespace {
std::atomic<long> g_allocations{0};
}

// A replacement global new/delete pair over malloc/free is the standard pattern; GCC 12 still
// warns (-Wmismatched-new-delete) where it inlines the replacement delete under the sanitizers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__) && defined(__GLIBC__)
// glibc's own entry points, which the interposed ones forward to.
extern "C" void* __libc_malloc(std::size_t);
extern "C" void* __libc_memalign(std::size_t, std::size_t);
extern "C" void* malloc(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(n);
}
extern "C" int posix_memalign(void** p, std::size_t alignment, std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  *p = __libc_memalign(alignment, n);
  return *p ? 0 : ENOMEM;
}
#endif

namespace stampede {
namespace {

class FitterAllocation : public ::testing::TestWithParam<RendererKind> {};

TEST_P(FitterAllocation, SteadyStateFitsAllocateNothing) {
  const auto cases = testing::load_render_cases();
  FftPlanCache plans(FftPlanning::kEstimate);
  FitterOptions fo;
  fo.renderer = GetParam();
  fo.render.stamp_size = 39;
  fo.noise_sigma = 0.1;
  std::string err;
  auto psf = make_renderer(fo.renderer, fo.render, fo.model, plans)->prepare_psf(testing::case_psf(cases[6]), &err);
  ASSERT_TRUE(psf) << err;
  Fitter fitter(fo, psf, plans);
  ASSERT_TRUE(IsUsable(fitter.fit(cases[6].image).status));  // warm-up
  const long before = g_allocations.load();
  int fitted = 0;
  for (int id : {6, 7, 8, 9, 10}) {
    const FitResult r = fitter.fit(cases[id].image);
    fitted += IsUsable(r.status) ? 1 : 0;
  }
  const long during = g_allocations.load() - before;
  EXPECT_EQ(fitted, 5);
  EXPECT_EQ(during, 0) << "heap allocations during 5 steady-state fits";
}

INSTANTIATE_TEST_SUITE_P(BothRenderers, FitterAllocation,
                         ::testing::Values(RendererKind::kUpsampled, RendererKind::kExact),
                         [](const auto& info) { return info.param == RendererKind::kExact ? "exact" : "upsampled"; });

}  // namespace
}  // namespace stampede
