// Tests for engine/pipeline/observation_arena: the observations a batch carries, and each as the
// one image type (Observation) the fit stage takes.
#include "engine/pipeline/observation_arena.hpp"

#include <gtest/gtest.h>

namespace stampede {
namespace {

TEST(ObservationArena, AnObservationIsTheImageItsEntryDescribes) {
  ObservationArena arena;
  arena.begin_object(2);
  std::span<double> pixels, weights;
  ArenaObservation& first = arena.add(3, &pixels, &weights);
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<double>(i), weights[i] = 0.5;
  first.band = 0;
  first.psf = PsfModel::Moffat({3.0, 2.5, 0.0, 0.0});
  ArenaObservation& second = arena.add(2, &pixels, &weights);
  for (double& v : pixels) v = -1;
  second.band = 1;
  second.frame = PixelFrame::from_meds(0.0, 0.25, 0.25, 0.0, 0.5, 0.5);
  second.flux_scale = 2.0;
  second.weight_kind = WeightKind::kMask;
  second.weighted = false;
  second.psf = PsfModel::Moffat({2.5, 3.0, 0.0, 0.0});

  const Observation a = arena.observation(arena[0]), b = arena.observation(arena[1]);
  ASSERT_EQ(a.pixels.size(), 9u);
  EXPECT_EQ(a.pixels.data(), arena.pixels(arena[0]).data());
  EXPECT_EQ(a.pixels[4], 4.0);
  ASSERT_EQ(a.weight.size(), 9u);
  EXPECT_EQ(a.weight[8], 0.5);
  EXPECT_EQ(a.box_size, 3);
  EXPECT_EQ(a.band, 0);
  EXPECT_EQ(a.psf_model, &arena[0].psf);
  EXPECT_EQ(a.psf, nullptr);  // prepared by the fit stage
  ASSERT_EQ(b.pixels.size(), 4u);
  EXPECT_EQ(b.pixels[0], -1.0);
  EXPECT_TRUE(b.weight.empty());  // no weight map
  EXPECT_EQ(b.box_size, 2);
  EXPECT_EQ(b.band, 1);
  EXPECT_EQ(b.frame.dudx, 0.25);
  EXPECT_EQ(b.frame.x_ref, arena[1].frame.x_ref);
  EXPECT_EQ(b.flux_scale, 2.0);
  EXPECT_EQ(b.weight_kind, WeightKind::kMask);
  EXPECT_EQ(b.psf_model, &arena[1].psf);
}

}  // namespace
}  // namespace stampede
