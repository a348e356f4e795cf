// Every compiled instruction set's wrap kernels against the scalar reference: the copies' light
// and its derivatives at the Chebyshev nodes of a stamp, and the interpolation.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "kernels/sersic.hpp"
#include "kernels/wrapped_wings.hpp"

namespace stampede::kernels {
namespace {

TEST(WrappedWingsIsa, EverySetMatchesTheScalarReference) {
  WingComponent c;
  c.x0 = 20.3;
  c.y0 = 17.6;
  c.q = ellipse_quadratic(0.4, -0.2, 2.5);
  c.b = sersic_b(4.0);
  c.s = 0.125;
  c.root = SersicRoot::kEighthRoot;
  ellipse_quadratic_derivatives(0.4, -0.2, 2.5, &c.dq_de1, &c.dq_de2);
  c.du_dr_over_u = -0.8;
  const BlurMoments m{3.9, 0.2, 4.1};
  std::vector<CopyOffset> copies;
  copies.reserve(25);
  significant_copies(c, 96, 39, 2, 1e-12, &copies);
  ASSERT_FALSE(copies.empty());
  const int nodes = 11;  // 121 points: a vector tail for every width
  const ChebyshevStamp grid(39, nodes, Isa::kScalar);
  std::vector<double> x, y;
  for (int j = 0; j < nodes; ++j)
    for (int i = 0; i < nodes; ++i) x.push_back(grid.node(i)), y.push_back(grid.node(j));
  const int count = nodes * nodes;
  const WrapKernels& ref = wrap_kernels(Isa::kScalar);
  std::vector<double> rv(count, 0.5), rimg(39 * 39, 1.0), scratch(nodes * 39);
  std::vector<std::vector<double>> rd(kWingDerivatives, std::vector<double>(count, -0.25));
  std::vector<double*> rcols;
  for (auto& col : rd) rcols.push_back(col.data());
  ref.add_wings(c, m, copies.data(), static_cast<int>(copies.size()), x.data(), y.data(), count, 3.0, rv.data(), -2.0,
                rcols.data());
  grid.add_interpolated(rv.data(), rimg.data(), scratch.data());
  int tested = 0;
  for (Isa isa : {Isa::kSse42, Isa::kAvx2, Isa::kAvx512}) {
    const WrapKernels* k = wrap_kernels_for(isa);
    if (!k) continue;
    ++tested;
    std::vector<double> v(count, 0.5), img(39 * 39, 1.0);
    std::vector<std::vector<double>> d(kWingDerivatives, std::vector<double>(count, -0.25));
    std::vector<double*> cols;
    for (auto& col : d) cols.push_back(col.data());
    k->add_wings(c, m, copies.data(), static_cast<int>(copies.size()), x.data(), y.data(), count, 3.0, v.data(), -2.0,
                 cols.data());
    const ChebyshevStamp g(39, nodes, isa);
    g.add_interpolated(v.data(), img.data(), scratch.data());
    for (int j = 0; j < count; ++j) {
      EXPECT_NEAR(v[j], rv[j], 1e-13 * std::abs(rv[j]) + 1e-300) << k->name << " point " << j;
      for (int q = 0; q < kWingDerivatives; ++q)
        EXPECT_NEAR(d[q][j], rd[q][j], 1e-12 * std::abs(rd[q][j]) + 1e-14) << k->name << " derivative " << q;
    }
    for (int p = 0; p < 39 * 39; ++p) EXPECT_NEAR(img[p], rimg[p], 1e-14) << k->name << " pixel " << p;
  }
  std::printf("%d vector sets tested against the scalar reference\n", tested);
}

}  // namespace
}  // namespace stampede::kernels
