// Filling a metadetection cell's masked pixels (kernels/mask_fill), image and noise field, on the
// reference test's 251 x 251 cell:
//   BM_FillMaskedPixels/0   two bright stars' discs (radii 8 and 16 px), the mask four-fold symmetric
//   BM_FillMaskedPixels/1   the same discs as given
//   BM_FillMaskedPixels/2   a bad column (1 px wide, the cell's height)
// items_per_second counts filled pixels.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/mask_fill.hpp"

namespace {

using namespace stampede::kernels;

constexpr int kSide = 251;

void BM_FillMaskedPixels(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(kSide);
  std::vector<std::uint8_t> mask(n * n, 0), turned;
  if (state.range(0) == 2) {
    for (std::size_t y = 0; y < n; ++y) mask[y * n + 100] = 1;
  } else {
    for (const auto& [cx, cy, r] : {std::array<double, 3>{80, 150, 8}, std::array<double, 3>{170, 90, 16}})
      for (std::size_t y = 0; y < n; ++y)
        for (std::size_t x = 0; x < n; ++x)
          if (std::hypot(static_cast<double>(x) - cx, static_cast<double>(y) - cy) <= r) mask[y * n + x] = 1;
    if (state.range(0) == 0) symmetrise_mask(mask, kSide, &turned);
  }
  std::vector<double> image(n * n), noise(n * n), image0(n * n), noise0(n * n);
  for (std::size_t p = 0; p < n * n; ++p) {
    const double x = static_cast<double>(p % n), y = static_cast<double>(p / n);
    image0[p] = 100 * std::exp(-((x - 125) * (x - 125) + (y - 125) * (y - 125)) / 200.0) + 0.01 * x;
    noise0[p] = std::sin(0.7 * x + 1.3 * y);
  }
  MaskFillScratch scratch;
  long long filled = 0;
  for (auto _ : state) {
    image = image0, noise = noise0;
    const std::span<double> planes[2] = {image, noise};
    filled += fill_masked_pixels(mask, kSide, planes, &scratch);
    benchmark::DoNotOptimize(image.data());
  }
  state.SetItemsProcessed(filled);
}
BENCHMARK(BM_FillMaskedPixels)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
