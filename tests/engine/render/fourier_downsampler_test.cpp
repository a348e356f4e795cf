// Downsampling in Fourier space is the same operation as the paper's inverse transform at model
// resolution followed by a block average: checked on random images for several U1, stamps and
// (odd, even) offsets of the stamp within the grid.
#include "engine/render/fourier_downsampler.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/render/psf_kernel.hpp"
#include "kernels/downsample.hpp"

namespace stampede {
namespace {

TEST(FourierDownsampler, EqualsFullInverseThenBlockAverage) {
  for (int upsampling : {1, 3, 5})
    for (int stamp : {25, 39})
      for (int padding : {0, 4}) {
        RenderOptions ro;
        ro.stamp_size = stamp;
        ro.upsampling = upsampling;
        ro.padding = padding;
        const GridGeometry g(ro);
        ASSERT_EQ(g.size % upsampling, 0);
        FftPlanCache plans(FftPlanning::kEstimate);
        PsfModel psf;
        psf.moffat = {3.0, 2.85, 0.05, -0.02, 0.0};
        std::string err;
        auto kernel = PsfKernel::build(psf, g, plans, &err);
        ASSERT_TRUE(kernel) << err;
        FftConvolver& fft = plans.get(g.size);
        AlignedBuffer a = fft.make_real_buffer(), b = fft.make_real_buffer();
        auto* pa = static_cast<double*>(a.data());
        auto* pb = static_cast<double*>(b.data());
        std::uint64_t state = 12345;
        double peak = 0;
        for (int i = 0; i < g.size * g.size; ++i) {
          state = state * 6364136223846793005ull + 1442695040888963407ull;
          pa[i] = pb[i] = static_cast<double>(state >> 11) * 0x1.0p-53;
        }
        std::vector<double> expected(static_cast<std::size_t>(stamp) * stamp), folded(expected.size());
        fft.convolve(pa, kernel->spectrum());
        kernels::block_average(pa, g.size, g.upsampling, g.offset, stamp, expected.data());
        FourierDownsampler down(g);
        down.apply(fft.transform(pb), kernel->folded_spectrum(), folded.data());
        double worst = 0;
        for (std::size_t i = 0; i < expected.size(); ++i) {
          peak = std::max(peak, std::abs(expected[i]));
          worst = std::max(worst, std::abs(folded[i] - expected[i]));
        }
        EXPECT_LT(worst, 1e-13 * peak) << "U1 " << upsampling << " stamp " << stamp << " padding " << padding
                                       << " offset " << g.offset;
      }
}

}  // namespace
}  // namespace stampede
