// The per-object PSF cache: one shared prepared PSF per distinct model, bounded, failures not
// cached, safe under concurrent lookups (the TSan build runs this too).
#include "engine/render/psf_cache.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "engine/render/renderer_factory.hpp"

namespace stampede {
namespace {

RenderOptions small_options() {
  RenderOptions ro;
  ro.stamp_size = 15;
  ro.upsampling = 3;
  ro.padding = 2;
  return ro;
}

PsfModel moffat(double fwhm, double e2 = 0.0) { return PsfModel::Moffat({3.0, fwhm, 0.0, e2, 0.0}); }

struct PsfCacheTest : ::testing::Test {
  FftPlanCache plans{FftPlanning::kEstimate};
  std::unique_ptr<Renderer> renderer = make_renderer(RendererKind::kUpsampled, small_options(), ModelOptions{}, plans);
};

TEST_F(PsfCacheTest, SamePsfGivesTheSameSharedKernel) {
  PsfCache cache(8);
  std::string err;
  auto a = cache.get(moffat(2.5), *renderer, &err);
  ASSERT_TRUE(a) << err;
  EXPECT_EQ(cache.get(moffat(2.5), *renderer, &err), a);
  EXPECT_EQ(cache.size(), 1u);
  // A truncated Moffat and an Airy disc are keyed by their parameters too.
  auto t = cache.get(PsfModel::Moffat({3.0, 2.5, 0.0, 0.0, 4.0}), *renderer, &err);
  auto y = cache.get(PsfModel::Airy({2.0, 0.0}), *renderer, &err);
  ASSERT_TRUE(t && y) << err;
  EXPECT_EQ(cache.get(PsfModel::Moffat({3.0, 2.5, 0.0, 0.0, 4.0}), *renderer, &err), t);
  EXPECT_EQ(cache.get(PsfModel::Airy({2.0, 0.0}), *renderer, &err), y);
  // An image by identity: the same image object hits, an equal copy is another entry.
  auto img = std::make_shared<PsfImage>();
  img->nx = img->ny = 5;
  img->pixels.assign(25, 0.0);
  img->pixels[12] = 1.0;
  auto i1 = cache.get(PsfModel::Image(img), *renderer, &err);
  ASSERT_TRUE(i1) << err;
  EXPECT_EQ(cache.get(PsfModel::Image(img), *renderer, &err), i1);
  EXPECT_NE(cache.get(PsfModel::Image(std::make_shared<PsfImage>(*img)), *renderer, &err), i1);
  EXPECT_EQ(cache.size(), 5u);
}

TEST_F(PsfCacheTest, DistinctPsfsGiveDistinctKernels) {
  PsfCache cache(8);
  std::string err;
  auto a = cache.get(moffat(2.5), *renderer, &err);
  auto b = cache.get(moffat(2.5, 0.05), *renderer, &err);
  auto c = cache.get(moffat(3.0), *renderer, &err);
  auto d = cache.get(PsfModel::Airy({2.5, 0.0}), *renderer, &err);
  ASSERT_TRUE(a && b && c && d) << err;
  EXPECT_NE(a, b);
  EXPECT_NE(a, c);
  EXPECT_NE(b, c);
  EXPECT_NE(a, d);
  EXPECT_NE(a->yy(), b->yy());  // really another PSF, not a copy
  EXPECT_EQ(cache.size(), 4u);
}

TEST_F(PsfCacheTest, CapacityDropsTheOldest) {
  PsfCache cache(2);
  std::string err;
  auto first = cache.get(moffat(2.0), *renderer, &err);
  auto second = cache.get(moffat(2.5), *renderer, &err);
  auto third = cache.get(moffat(3.0), *renderer, &err);
  ASSERT_TRUE(first && second && third) << err;
  EXPECT_EQ(cache.size(), 2u);
  // The oldest was dropped (its kernel lives on in `first`): asking again builds a new one.
  EXPECT_EQ(cache.get(moffat(2.5), *renderer, &err), second);
  EXPECT_EQ(cache.get(moffat(3.0), *renderer, &err), third);
  auto again = cache.get(moffat(2.0), *renderer, &err);
  EXPECT_NE(again, first);
  EXPECT_EQ(again->xx(), first->xx());
  EXPECT_EQ(cache.size(), 2u);
}

TEST_F(PsfCacheTest, UnbuildablePsfGivesNullAndAnError) {
  PsfCache cache(8);
  std::string err;
  EXPECT_FALSE(cache.get(PsfModel::Moffat({0.8, 2.5, 0.0, 0.0, 0.0}), *renderer, &err));
  EXPECT_NE(err.find("psf_beta = 0.8"), std::string::npos) << err;
  auto img = std::make_shared<PsfImage>();
  img->nx = img->ny = 5;
  img->pixels.assign(25, 0.0);
  err.clear();
  EXPECT_FALSE(cache.get(PsfModel::Image(img), *renderer, &err));
  EXPECT_NE(err.find("cannot be normalised"), std::string::npos) << err;
  EXPECT_EQ(cache.size(), 0u);  // failures are not cached
}

TEST(PsfCache, ConcurrentLookupsShareOneKernelPerPsf) {
  constexpr int kDistinct = 6, kLookups = 600;
  PsfCache cache(1024);
  std::vector<std::shared_ptr<const PreparedPsf>> got(kLookups);
  std::atomic<int> failures{0};
  // Plain threads, each with its renderer, taking every kThreads-th lookup: their joins are what
  // ThreadSanitizer sees (the uninstrumented libtbb's parallel_for join is not).
  constexpr int kThreads = 4;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      FftPlanCache plans(FftPlanning::kEstimate);
      const std::unique_ptr<Renderer> renderer =
          make_renderer(RendererKind::kUpsampled, small_options(), ModelOptions{}, plans);
      for (int i = t; i < kLookups; i += kThreads) {
        std::string err;
        got[i] = cache.get(moffat(2.0 + 0.25 * (i % kDistinct)), *renderer, &err);
        if (!got[i])
          ++failures;
        else
          renderer->set_psf(got[i]);
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(cache.size(), static_cast<std::size_t>(kDistinct));
  // Each PSF's lookups after the cache settled return the stored kernel; a thread that lost the
  // race to store may hold its own equal build.
  FftPlanCache plans(FftPlanning::kEstimate);
  auto renderer = make_renderer(RendererKind::kUpsampled, small_options(), ModelOptions{}, plans);
  for (int i = 0; i < kLookups; ++i) {
    std::string err;
    auto stored = cache.get(moffat(2.0 + 0.25 * (i % kDistinct)), *renderer, &err);
    EXPECT_EQ(got[i]->xx(), stored->xx());
  }
}

}  // namespace
}  // namespace stampede
