// Tests for io/result_columns: the schema table is indexed by ResultField, each column has the
// accessors of its type, the getters and setters of every column invert each other, and grid and
// catalogue tables differ only in their position columns.
#include "io/result_columns.hpp"

#include <gtest/gtest.h>

#include <string_view>

#include <bit>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

namespace stampede::io {
namespace {

TEST(ResultColumns, IndexedByFieldWithTheAccessorsOfTheirType) {
  for (int f = 0; f < kNumResultFields; ++f) {
    const ResultColumn& c = result_column(static_cast<ResultField>(f));
    EXPECT_EQ(static_cast<int>(c.field), f) << c.name;
    EXPECT_STREQ(column_name(c.field), c.name);
    EXPECT_LE(std::strlen(c.description), 68u) << c.name;  // one FITS string card
    if (c.type == ColumnType::kFloat64) {
      EXPECT_TRUE(c.real && c.set_real && !c.integer && !c.set_integer) << c.name;
    } else {
      EXPECT_TRUE(c.integer && c.set_integer && !c.real && !c.set_real) << c.name;
    }
  }
  EXPECT_STREQ(column_name(ResultField::kSnr), "snr");
  EXPECT_STREQ(column_name(ResultField::kIterations), "n_iter");
}

TEST(ResultColumns, SettersInvertGetters) {
  ObjectRecord r;
  // Distinct values per column, so a getter reading another column's field is caught.
  for (int f = 0; f < kNumResultFields; ++f) {
    const ResultColumn& c = result_column(static_cast<ResultField>(f));
    if (c.type == ColumnType::kFloat64) {
      c.set_real(r, 0.5 + f);
    } else {
      c.set_integer(r, c.type == ColumnType::kUInt32 ? (1LL << 31) + f : f + 1);
    }
  }
  for (int f = 0; f < kNumResultFields; ++f) {
    const ResultColumn& c = result_column(static_cast<ResultField>(f));
    if (c.type == ColumnType::kFloat64) {
      EXPECT_EQ(c.real(r), 0.5 + f) << c.name;
    } else {
      EXPECT_EQ(c.integer(r), c.type == ColumnType::kUInt32 ? (1LL << 31) + f : f + 1) << c.name;
    }
  }
  EXPECT_EQ(r.fit.params[index(Param::kE2)], 0.5 + static_cast<int>(ResultField::kE2));
  EXPECT_EQ(r.fit.status, static_cast<FitStatus>(static_cast<int>(ResultField::kStatus) + 1));
}

TEST(ResultColumns, GridAndCatalogueTablesShareTheFitColumns) {
  const auto grid = result_columns(PositionColumns::kGrid);
  const auto cat = result_columns(PositionColumns::kCatalogue);
  ASSERT_EQ(grid.size(), cat.size());
  EXPECT_EQ(grid[1].field, ResultField::kIx);
  EXPECT_EQ(cat[1].field, ResultField::kXImage);
  EXPECT_STRNE(grid[0].description, cat[0].description);  // what the id means differs
  for (std::size_t i = 3; i < grid.size(); ++i) {
    EXPECT_EQ(grid[i].field, cat[i].field);
    EXPECT_EQ(grid[i].field, static_cast<ResultField>(static_cast<int>(ResultField::kX0) + i - 3));
  }
  EXPECT_EQ(catalog_columns(PositionColumns::kGrid).size(), grid.size());
  EXPECT_EQ(catalog_columns(PositionColumns::kCatalogue)[2], "y_image");
}

// A survey metacal table is the survey table, then the metacal columns (the sheared fits' radii in
// arcsec, as the survey's radius), then gamma_fwhm; the survey table alone has none of them.
TEST(ResultColumns, SurveyMetacalTablesAddTheMetacalColumnsAndGamma) {
  const auto survey = result_columns(PositionColumns::kSurvey);
  const auto metacal = result_columns(PositionColumns::kSurvey, true);
  ASSERT_EQ(metacal.size(), survey.size() + kNumMetacalFields + 1);
  for (std::size_t i = 0; i < survey.size(); ++i) EXPECT_EQ(metacal[i].field, survey[i].field);
  for (int k = 0; k < kNumMetacalFields; ++k) {
    const ResultColumn& c = metacal[survey.size() + k];
    EXPECT_EQ(c.field, static_cast<ResultField>(static_cast<int>(ResultField::kR11) + k));
    EXPECT_STREQ(c.unit, std::string_view(c.name).starts_with("radius_") ? "arcsec" : "") << c.name;
  }
  EXPECT_EQ(metacal.back().field, ResultField::kGammaFwhm);
  EXPECT_STREQ(metacal.back().unit, "arcsec");
  for (const ResultColumn& c : survey) EXPECT_NE(c.field, ResultField::kR11);
}

// FITS column lookup ignores case: with bands G and g, flux_G and flux_g were one column to
// CFITSIO, so a reader (and merge) got G's values for both. Such names are refused, naming both.
TEST(ResultColumns, BandNamesThatDifferOnlyInCaseAreRefused) {
  std::string why;
  EXPECT_FALSE(are_band_names({"r", "G", "i", "g"}, &why));
  EXPECT_NE(why.find("bands 'G' and 'g' differ only in case"), std::string::npos) << why;
  EXPECT_FALSE(are_band_names({"g", "r", "g"}, &why));
  EXPECT_NE(why.find("band 'g' is given twice"), std::string::npos) << why;
  EXPECT_TRUE(are_band_names({"g", "r", "i", "z", "Y"}, &why)) << why;
  try {
    const ResultSchema schema(PositionColumns::kSurvey, false, {"DES_z", "des_Z"});
    ADD_FAILURE() << "bands DES_z and des_Z accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'DES_z' and 'des_Z' differ only in case"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stampede::io
