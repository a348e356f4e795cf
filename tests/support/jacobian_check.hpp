// A renderer's Jacobian images against central differences of its model, column by column:
// within `relative` of the column's largest entry plus the rounding of a central difference of
// images of size ~peak (a few eps * peak / h).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <vector>

#include "engine/render/renderer.hpp"

namespace stampede::testing {

inline void expect_jacobian_matches_differences(Renderer& r, const ParamVector& p, std::span<const Param> free,
                                                double relative = 1e-6) {
  const int npix = r.stamp_size() * r.stamp_size();
  std::vector<double> model(npix), plus(npix), minus(npix);
  std::vector<std::vector<double>> jac(free.size(), std::vector<double>(npix));
  std::vector<double*> cols;
  for (auto& j : jac) cols.push_back(j.data());
  ASSERT_EQ(r.render_with_jacobian(p, free, model, cols), RenderStatus::kOk);
  double peak = 0;
  for (double v : model) peak = std::max(peak, std::abs(v));
  for (std::size_t k = 0; k < free.size(); ++k) {
    const int i = index(free[k]);
    const double h = i <= index(Param::kRadius) ? 1e-6 : 1e-4 * std::max(1.0, std::abs(p[i]));
    ParamVector pp = p, pm = p;
    pp[i] += h;
    pm[i] -= h;
    ASSERT_EQ(r.render(pp, plus), RenderStatus::kOk);
    ASSERT_EQ(r.render(pm, minus), RenderStatus::kOk);
    double max_fd = 0, max_diff = 0;
    for (int q = 0; q < npix; ++q) {
      const double fd = (plus[q] - minus[q]) / (2 * h);
      max_fd = std::max(max_fd, std::abs(fd));
      max_diff = std::max(max_diff, std::abs(fd - jac[k][q]));
    }
    EXPECT_GT(max_fd, 0) << param_name(free[k]);
    EXPECT_LE(max_diff, relative * max_fd + 2e-14 * peak / h) << param_name(free[k]);
  }
}

}  // namespace stampede::testing
