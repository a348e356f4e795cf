// Tests for PSFEx model evaluation (engine/model/psfex_model): the basis order and polynomial
// against a sum written out term by term, normalisation, and what makes a model unusable.
#include "engine/model/psfex_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace stampede {
namespace {

// Degree 2 on 5 x 4 samples; basis image k holds distinct values so any mix-up of terms shows.
PsfexModel degree_two() {
  PsfexModel m;
  m.degree = 2;
  m.zero_x = 100.5, m.zero_y = 80.0, m.scale_x = 201.0, m.scale_y = 160.0;
  m.nx = 5, m.ny = 4;
  m.basis.resize(6 * 20);
  for (int k = 0; k < 6; ++k)
    for (int p = 0; p < 20; ++p) m.basis[k * 20 + p] = (k == 0 ? 1.0 : 0.01 * (k + 1)) * (1 + std::sin(3.0 * p + k));
  return m;
}

TEST(PsfexModel, TermsFollowTheDocumentedOrder) {
  const PsfexModel m = degree_two();
  const double x = 37.25, y = 150.5, xs = (x - 100.5) / 201.0, ys = (y - 80.0) / 160.0;
  // d = 2: 1, x, x^2, y, xy, y^2.
  const double c[6] = {1, xs, xs * xs, ys, xs * ys, ys * ys};
  std::vector<double> want(20, 0.0);
  double sum = 0;
  for (int p = 0; p < 20; ++p) {
    for (int k = 0; k < 6; ++k) want[p] += c[k] * m.basis[k * 20 + p];
    sum += want[p];
  }
  std::vector<double> got(20);
  std::string error;
  ASSERT_TRUE(m.evaluate(x, y, got, &error)) << error;
  for (int p = 0; p < 20; ++p) EXPECT_NEAR(got[p], want[p] / sum, 1e-15) << p;
  std::vector<double> coefficients(6);
  m.coefficients(x, y, coefficients);
  for (int k = 0; k < 6; ++k) EXPECT_DOUBLE_EQ(coefficients[k], c[k]);
}

TEST(PsfexModel, ImageAtIsCentredOnTheMiddleSampleAndOversampledByOneOverSampling) {
  PsfexModel m = degree_two();
  m.sampling = 0.5;
  std::string error;
  const auto img = m.image_at(10, 20, &error);
  ASSERT_TRUE(img) << error;
  EXPECT_EQ(img->oversampling, 2);
  EXPECT_EQ(img->centre_x, 2.0);  // 5 / 2
  EXPECT_EQ(img->centre_y, 2.0);  // 4 / 2
  EXPECT_TRUE(img->pixel_integrated);
  m.sampling = 0.7;
  EXPECT_FALSE(m.image_at(10, 20, &error));
  EXPECT_NE(error.find("PSF_SAMP"), std::string::npos) << error;
}

TEST(PsfexModel, AModelThatSumsToZeroOrInconsistentSizesAreRefused) {
  PsfexModel m = degree_two();
  std::string why;
  EXPECT_TRUE(m.IsValid(&why)) << why;
  for (double& v : m.basis) v = 0;
  std::vector<double> out(20);
  EXPECT_FALSE(m.evaluate(1, 1, out, &why));
  EXPECT_NE(why.find("sums to"), std::string::npos) << why;
  m = degree_two();
  m.basis.pop_back();
  EXPECT_FALSE(m.IsValid(&why));
  EXPECT_NE(why.find("PSF_MASK holds 119 values"), std::string::npos) << why;
}

}  // namespace
}  // namespace stampede
