// Grid geometry: the FFT grid's size and the sub-pixel coordinate convention.
#include "engine/render/render_options.hpp"

#include <gtest/gtest.h>

namespace stampede {
namespace {

TEST(RenderOptions, SubpixelCentresFollowTheDataConvention) {
  RenderOptions ro;  // 39 px, U1 = 5, padding 4: 235 -> 240 sub-pixels, stamp from sub-pixel 22
  const GridGeometry g(ro);
  EXPECT_EQ(g.grid_size(), 240);
  EXPECT_EQ(g.data_offset(), 22);
  const kernels::SubpixelGrid s = g.subpixel_grid();
  // Data pixel 0 covers [-0.5, 0.5): its first sub-pixel's centre is at -0.5 + 0.1.
  EXPECT_NEAR(s.origin + s.step * g.data_offset(), -0.4, 1e-12);
  // The middle sub-pixel of pixel 19 is centred on 19.
  EXPECT_NEAR(s.origin + s.step * (g.data_offset() + 19 * 5 + 2), 19.0, 1e-12);
}

TEST(RenderOptions, ValidationNamesTheOption) {
  RenderOptions ro;
  ro.upsampling = 0;
  std::string why;
  EXPECT_FALSE(ro.IsValid(&why));
  EXPECT_NE(why.find("upsampling = 0"), std::string::npos) << why;
  ro = RenderOptions{};
  ro.n_central_pixel_upsampling = 65;
  EXPECT_FALSE(ro.IsValid(&why));
  EXPECT_NE(why.find("n_central_pixel_upsampling = 65"), std::string::npos) << why;
  EXPECT_TRUE(RenderOptions{}.IsValid(&why));
}

}  // namespace
}  // namespace stampede
