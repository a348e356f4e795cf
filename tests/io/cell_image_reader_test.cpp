// The metadetection image reader's sky check (io/cell_image_reader): the sky level from a cell's
// faintest pixels is its offset, in the noise's units, under sources covering much of the cell,
// with noise and without it; masked pixels take no part; too few pixels give no level; the problem
// names the level beyond the limit only.
#include "io/cell_image_reader.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace stampede::io {
namespace {

struct Plane {
  std::vector<double> pixels, weight;
};

// side x side pixels of noise sigma (0: none) plus `sky`, with a round Gaussian source of sigma
// 3 px and peak 50 sigma (noiseless: 50) per 1,000 pixels scattered over it (their light above
// 0.1 sigma covers a third of the cell), weights 1 / sigma^2.
Plane scene(int side, double sigma, double sky, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  std::uniform_real_distribution<double> where(0, side);
  const double unit = sigma > 0 ? sigma : 1;
  Plane p;
  p.pixels.assign(static_cast<std::size_t>(side) * side, sky * unit);
  p.weight.assign(p.pixels.size(), 1 / (unit * unit));
  for (double& v : p.pixels) v += sigma * gauss(rng);
  for (int s = 0; s < side * side / 1000; ++s) {
    const double cx = where(rng), cy = where(rng);
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < side; ++x)
        p.pixels[static_cast<std::size_t>(y) * side + x] +=
            50 * unit * std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / 18.0);
  }
  return p;
}

TEST(CellSky, LevelIsTheOffsetUnderSourcesWithNoiseAndWithout) {
  std::vector<double> scratch;
  for (const double sky : {-4.0, 0.0, 0.6, 3.0}) {
    const Plane noisy = scene(160, 2.5, sky, 11);
    EXPECT_NEAR(cell_sky_level(noisy.pixels, noisy.weight, &scratch), sky, 0.3) << sky;
    const Plane noiseless = scene(160, 0, sky, 12);
    EXPECT_NEAR(cell_sky_level(noiseless.pixels, noiseless.weight, &scratch), sky, 1e-6) << sky;
  }
  // A small cell (80 pixels below its 1 % quantile at most): still within a few tenths.
  const Plane small = scene(48, 1.0, 2.5, 13);
  EXPECT_NEAR(cell_sky_level(small.pixels, small.weight, &scratch), 2.5, 0.4);
}

TEST(CellSky, MaskedPixelsTakeNoPartAndTooFewGiveNoLevel) {
  std::vector<double> scratch;
  Plane p = scene(100, 1.0, 0.0, 14);
  for (std::size_t i = 0; i < p.pixels.size(); i += 3) p.pixels[i] = -1e6, p.weight[i] = 0;
  EXPECT_NEAR(cell_sky_level(p.pixels, p.weight, &scratch), 0.0, 0.3);
  std::vector<double> few(63, 7.0), weight(63, 1.0);
  EXPECT_TRUE(std::isnan(cell_sky_level(few, weight, &scratch)));
  few.push_back(7.0), weight.push_back(1.0);
  EXPECT_NEAR(cell_sky_level(few, weight, &scratch), 7.0, 1e-12);
}

TEST(CellSky, ProblemNamesALevelBeyondTheLimitOnly) {
  const std::string high = cell_sky_problem(6.25);
  EXPECT_NE(high.find("sky at +6.25 sigma of its noise"), std::string::npos) << high;
  EXPECT_NE(high.find("background-subtracted"), std::string::npos) << high;
  EXPECT_NE(cell_sky_problem(-2.5).find("sky at -2.50 sigma"), std::string::npos);
  EXPECT_EQ(cell_sky_problem(kMaxCellSkyLevel), "");
  EXPECT_EQ(cell_sky_problem(-1.9), "");
  EXPECT_EQ(cell_sky_problem(NAN), "");
}

}  // namespace
}  // namespace stampede::io
