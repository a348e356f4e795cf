// No heap allocation per stamp in steady state: after the first fit has warmed up the fitter,
// further fits allocate nothing. Counted by replacing the global operator new in this binary.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "engine/fit/fitter.hpp"
#include "engine/render/psf_kernel.hpp"
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

namespace stampede {
namespace {

TEST(FitterAllocation, SteadyStateFitsAllocateNothing) {
  const auto cases = testing::load_render_cases();
  FftPlanCache plans(FftPlanning::kEstimate);
  FitterOptions fo;
  fo.render.stamp_size = 39;
  fo.noise_sigma = 0.1;
  std::string err;
  auto kernel = PsfKernel::build(testing::case_psf(cases[6]), GridGeometry(fo.render), plans, &err);
  ASSERT_TRUE(kernel) << err;
  Fitter fitter(fo, kernel, plans);
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

}  // namespace
}  // namespace stampede
