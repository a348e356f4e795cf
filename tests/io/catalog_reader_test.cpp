// Tests for io/catalog_reader: a table written by CatalogWriter reads back with every column equal
// (doubles bitwise, NaN and -0 included; 64-bit ids and unsigned flags exactly), by field, in
// chunks and as records; columns outside the schema by name; a missing column is an error naming
// the file, the HDU and the column.
#include "io/catalog_reader.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "io/catalog_writer.hpp"
#include "support/error_assertions.hpp"
#include "support/result_records.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

using stampede::testing::make_records;

bool same_double(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b) ||
         (std::isnan(a) && std::isnan(b));
}

class CatalogReaderTest : public ::testing::TestWithParam<PositionColumns> {
 protected:
  std::string write(const std::vector<ObjectRecord>& rows, PositionColumns positions) {
    CatalogWriterOptions o;
    o.path = scratch_.path("fit.fits");
    o.positions = positions;
    auto w = CatalogWriter::create(o);
    w->append(rows);
    w->finish();
    return o.path;
  }
  stampede::testing::ScratchDir scratch_{"stampede_catalog_reader_"};
};

TEST_P(CatalogReaderTest, RoundTripsEveryColumn) {
  const PositionColumns positions = GetParam();
  const auto rows = make_records(300, positions);  // more than one writer chunk
  CatalogReader reader = CatalogReader::open(write(rows, positions));
  EXPECT_EQ(reader.rows(), 300);
  EXPECT_EQ(reader.positions(), positions);

  const std::vector<ObjectRecord> back = reader.records(0, reader.rows());
  ASSERT_EQ(back.size(), rows.size());
  for (const ResultColumn& c : result_columns(positions)) {
    const std::vector<double> column = reader.column(c.field);
    ASSERT_EQ(column.size(), rows.size()) << c.name;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (c.type == ColumnType::kFloat64) {
        ASSERT_TRUE(same_double(c.real(back[i]), c.real(rows[i]))) << c.name << " row " << i;
        ASSERT_TRUE(same_double(column[i], c.real(rows[i]))) << c.name << " row " << i;
      } else {
        ASSERT_EQ(c.integer(back[i]), c.integer(rows[i])) << c.name << " row " << i;  // ids exact
        if (std::abs(c.integer(rows[i])) < (1LL << 53)) {  // doubles hold integers exactly to 2^53
          ASSERT_EQ(column[i], static_cast<double>(c.integer(rows[i]))) << c.name << " row " << i;
        }
      }
    }
  }
  // A chunk in the middle, by field and by name.
  std::vector<double> chunk(7);
  reader.column_rows(ResultField::kE1Err, 290, chunk);
  for (std::size_t i = 0; i < chunk.size(); ++i) {
    EXPECT_TRUE(same_double(chunk[i], rows[290 + i].fit.e1_err)) << i;
  }
  const std::vector<ObjectRecord> tail = reader.records(295, 5);
  ASSERT_EQ(tail.size(), 5u);
  EXPECT_EQ(tail[4].id, rows[299].id);
  EXPECT_EQ(tail[4].flags, rows[299].flags);
}

INSTANTIATE_TEST_SUITE_P(BothLayouts, CatalogReaderTest,
                         ::testing::Values(PositionColumns::kGrid, PositionColumns::kCatalogue),
                         [](const auto& info) {
                           return info.param == PositionColumns::kGrid ? "Grid" : "Catalogue";
                         });

// A metacal run's table: the metacal columns after the fit columns, read back bitwise, and the
// reader tells such a table from a plain one.
TEST(CatalogReader, RoundTripsAMetacalTable) {
  stampede::testing::ScratchDir scratch("stampede_catalog_reader_");
  for (const PositionColumns positions : {PositionColumns::kGrid, PositionColumns::kCatalogue}) {
    const auto rows = make_records(40, positions);
    CatalogWriterOptions o;
    o.path = scratch.path("metacal.fits");
    o.positions = positions;
    o.metacal = true;
    {
      auto w = CatalogWriter::create(o);
      w->append(rows);
      w->finish();
    }
    CatalogReader reader = CatalogReader::open(o.path);
    EXPECT_TRUE(reader.metacal());
    EXPECT_EQ(result_columns(positions, true).size(), result_columns(positions).size() + kNumMetacalFields);
    const std::vector<ObjectRecord> back = reader.records(0, reader.rows());
    ASSERT_EQ(back.size(), rows.size());
    for (const ResultColumn& c : result_columns(positions, true))
      for (std::size_t i = 0; i < rows.size(); ++i) {
        if (c.type == ColumnType::kFloat64)
          ASSERT_TRUE(same_double(c.real(back[i]), c.real(rows[i]))) << c.name << " row " << i;
        else
          ASSERT_EQ(c.integer(back[i]), c.integer(rows[i])) << c.name << " row " << i;
      }
    std::filesystem::remove(o.path);
  }
  // A plain table is not one.
  const std::string plain = scratch.path("plain.fits");
  CatalogWriterOptions o;
  o.path = plain;
  auto w = CatalogWriter::create(o);
  w->append(make_records(3, PositionColumns::kGrid));
  w->finish();
  EXPECT_FALSE(CatalogReader::open(plain).metacal());
}

TEST(CatalogReader, MissingColumnNamesFileHduAndColumn) {
  stampede::testing::ScratchDir scratch("stampede_catalog_reader_");
  const std::string path = scratch.path("bare.fits");
  {
    FitsFile f = FitsFile::create(path, false);
    f.write_empty_image();
    f.write_table("RESULTS", {{"id", true, {0, 1}}, {"e1", false, {0.1, 0.2}},
                              {"e1_cal", false, {0.3, 0.4}}});
  }
  std::string msg = error_of<FitsError>(
      [&] { CatalogReader::open(path, {ResultField::kId, ResultField::kE1, ResultField::kSnr}); });
  EXPECT_TRUE(Contains(msg, path));
  EXPECT_TRUE(Contains(msg, "RESULTS"));
  EXPECT_TRUE(Contains(msg, "no column 'snr'"));

  CatalogReader reader = CatalogReader::open(path, {ResultField::kId, ResultField::kE1});
  EXPECT_EQ(reader.column("e1_cal"), (std::vector<double>{0.3, 0.4}));  // outside the schema
  EXPECT_TRUE(reader.has(ResultField::kE1));
  EXPECT_FALSE(reader.has(ResultField::kE2));
  msg = error_of<FitsError>([&] { reader.column(ResultField::kPsfE1); });
  EXPECT_TRUE(Contains(msg, "no column 'psf_e1'"));
  msg = error_of<FitsError>([&] { reader.records(0, 2); });
  EXPECT_TRUE(Contains(msg, "no column 'ix'"));  // the first grid column it lacks

  // A file without a RESULTS table.
  const std::string image = scratch.path("image.fits");
  {
    FitsFile f = FitsFile::create(image, false);
    f.write_empty_image();
  }
  EXPECT_TRUE(Contains(error_of<FitsError>([&] { CatalogReader::open(image); }), image));
}

}  // namespace
}  // namespace stampede::io
