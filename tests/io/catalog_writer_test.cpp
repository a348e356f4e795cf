// Tests for io/catalog_writer: exact round trips of every column through the FITS table and the
// text file (NaN, -0, inf, 64-bit ids, unsigned flags), header contents, the partial/checkpoint
// life cycle, resume after simulated and real (SIGKILL) crashes compared byte for byte with an
// uninterrupted run, and the CatalogError cases (nothing to resume, different run, corrupt
// partials, unwritable paths, reserved header keys).
#include "io/catalog_writer.hpp"

#include <fcntl.h>
#include <fitsio.h>
#include <gtest/gtest.h>

#include "support/error_assertions.hpp"
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "support/file_size_limit.hpp"
#include "support/result_records.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

namespace fs = std::filesystem;

using stampede::testing::kNaN;
using stampede::testing::make_records;

// One table cell: integer columns compare as integers, D columns bitwise.
struct Cell {
  bool integer = false;
  long long i = 0;
  double d = 0;
};

// The expected row, restated here independently of the writer's column table.
std::vector<Cell> expected_row(const ObjectRecord& r, PositionColumns positions) {
  std::vector<Cell> v;
  auto I = [&](long long x) { v.push_back({true, x, 0}); };
  auto D = [&](double x) { v.push_back({false, 0, x}); };
  I(r.id);
  if (positions == PositionColumns::kGrid) {
    I(r.ix);
    I(r.iy);
  } else {
    D(r.x_image);
    D(r.y_image);
  }
  for (Param p : {Param::kX0, Param::kY0, Param::kE1, Param::kE2, Param::kRadius, Param::kBulgeA,
                  Param::kDiscA}) {
    D(r.fit.params[index(p)]);
  }
  for (double x : {r.fit.bulge_flux, r.fit.disc_flux, r.fit.flux, r.fit.e1_err, r.fit.e2_err,
                   r.fit.snr, r.fit.chi2, r.fit.likelihood}) {
    D(x);
  }
  I(r.fit.iterations);
  I(r.fit.evaluations);
  I(static_cast<int>(r.fit.stop_reason));
  I(static_cast<int>(r.fit.status));
  I(r.flags);
  for (double x : {r.time_us, r.psf_e1, r.psf_e2, r.psf_fwhm}) D(x);
  return v;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The RESULTS table as names plus rows of cells, read with CFITSIO in each column's own type.
struct Table {
  std::vector<std::string> names;
  std::vector<std::vector<Cell>> rows;
};

Table read_table(const std::string& path) {
  Table t;
  fitsfile* f = nullptr;
  int status = 0;
  fits_open_diskfile(&f, path.c_str(), READONLY, &status);
  fits_movnam_hdu(f, BINARY_TBL, const_cast<char*>("RESULTS"), 0, &status);
  int ncols = 0;
  LONGLONG nrows = 0;
  fits_get_num_cols(f, &ncols, &status);
  fits_get_num_rowsll(f, &nrows, &status);
  EXPECT_EQ(status, 0) << "cannot read the RESULTS table of " << path;
  if (status != 0) return t;
  t.rows.assign(static_cast<std::size_t>(nrows), std::vector<Cell>(ncols));
  for (int c = 1; c <= ncols; ++c) {
    char name[FLEN_VALUE] = {};
    const std::string key = "TTYPE" + std::to_string(c);
    fits_read_key(f, TSTRING, key.c_str(), name, nullptr, &status);
    t.names.emplace_back(name);
    int typecode = 0;
    long repeat = 0, width = 0;
    fits_get_coltype(f, c, &typecode, &repeat, &width, &status);
    if (typecode == TDOUBLE) {
      std::vector<double> v(static_cast<std::size_t>(nrows));
      fits_read_col(f, TDOUBLE, c, 1, 1, nrows, nullptr, v.data(), nullptr, &status);
      for (LONGLONG r = 0; r < nrows; ++r) t.rows[r][c - 1] = {false, 0, v[r]};
    } else {
      std::vector<LONGLONG> v(static_cast<std::size_t>(nrows));
      fits_read_col(f, TLONGLONG, c, 1, 1, nrows, nullptr, v.data(), nullptr, &status);
      for (LONGLONG r = 0; r < nrows; ++r) t.rows[r][c - 1] = {true, v[r], 0};
    }
  }
  EXPECT_EQ(status, 0) << "cannot read the columns of " << path;
  int close_status = 0;
  fits_close_file(f, &close_status);
  return t;
}

void expect_table(const std::string& path, const std::vector<ObjectRecord>& records,
                  PositionColumns positions) {
  const Table t = read_table(path);
  EXPECT_EQ(t.names, catalog_columns(positions));
  ASSERT_EQ(t.rows.size(), records.size());
  for (std::size_t r = 0; r < records.size(); ++r) {
    const std::vector<Cell> want = expected_row(records[r], positions);
    ASSERT_EQ(t.rows[r].size(), want.size());
    for (std::size_t c = 0; c < want.size(); ++c) {
      const Cell& got = t.rows[r][c];
      ASSERT_EQ(got.integer, want[c].integer) << "column " << t.names[c];
      if (want[c].integer) {
        ASSERT_EQ(got.i, want[c].i) << "row " << r << " column " << t.names[c];
      } else {
        ASSERT_TRUE(same_bits(got.d, want[c].d))
            << "row " << r << " column " << t.names[c] << ": " << got.d << " != " << want[c].d;
      }
    }
  }
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot open " << path;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void append_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::app);
  out << bytes;
  ASSERT_TRUE(out.good());
}

void expect_text(const std::string& path, const std::vector<ObjectRecord>& records,
                 PositionColumns positions) {
  std::istringstream in(read_bytes(path));
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  std::string header = "#";
  for (const std::string& name : catalog_columns(positions)) header += " " + name;
  EXPECT_EQ(line, header);
  std::size_t r = 0;
  for (; std::getline(in, line); ++r) {
    ASSERT_LT(r, records.size()) << "extra line: " << line;
    const std::vector<Cell> want = expected_row(records[r], positions);
    std::istringstream tokens(line);
    std::string token;
    std::size_t c = 0;
    for (; tokens >> token; ++c) {
      ASSERT_LT(c, want.size()) << "extra field in line " << r;
      if (want[c].integer) {
        EXPECT_EQ(std::stoll(token), want[c].i) << "line " << r << " field " << c;
        EXPECT_EQ(token.find_first_not_of("-0123456789"), std::string::npos) << token;
      } else {
        const double got = std::strtod(token.c_str(), nullptr);
        if (std::isnan(want[c].d)) {
          EXPECT_TRUE(std::isnan(got)) << "line " << r << " field " << c << ": " << token;
        } else {
          EXPECT_TRUE(same_bits(got, want[c].d))
              << "line " << r << " field " << c << ": " << token << " vs " << want[c].d;
        }
      }
    }
    EXPECT_EQ(c, want.size()) << "line " << r;
  }
  EXPECT_EQ(r, records.size());
}

// Appends records[first, first + sizes[0]), then the next sizes[1], ...
long long append_batches(CatalogWriter& w, const std::vector<ObjectRecord>& records,
                         long long first, const std::vector<long long>& sizes) {
  for (long long n : sizes) {
    w.append(std::span(records).subspan(static_cast<std::size_t>(first),
                                        static_cast<std::size_t>(n)));
    first += n;
  }
  return first;
}

class CatalogWriterTest : public ::testing::Test {
 protected:
  CatalogWriterOptions options(const std::string& subdir = "") const {
    const fs::path d = subdir.empty() ? scratch_.dir() : scratch_.dir() / subdir;
    fs::create_directories(d);
    CatalogWriterOptions o;
    o.path = (d / "out.fits").string();
    o.text_path = (d / "out.txt").string();
    o.fingerprint = "input=/data/set_0.fits\nstamp_size=39\nnoise_sigma=0.001";
    o.header = {{"stamp_size", "39"}, {"noise_sigma", "0.001"}, {"psf_input", "moffat"}};
    return o;
  }

  // The outputs of an uninterrupted run writing `records` in one batch.
  std::pair<std::string, std::string> reference(const std::vector<ObjectRecord>& records) {
    const CatalogWriterOptions o = options("reference");
    auto w = CatalogWriter::create(o);
    w->append(records);
    w->finish();
    return {read_bytes(o.path), read_bytes(o.text_path)};
  }

  stampede::testing::ScratchDir scratch_{"catalog_writer_test."};
};

TEST(CatalogColumns, NamesInTableOrder) {
  const std::vector<std::string> fit = {
      "x0",     "y0",     "e1",     "e2",          "radius", "bulge_A", "disc_A",  "bulge_flux",
      "disc_flux", "flux", "e1_err", "e2_err",     "snr",    "chi2",    "likelihood", "n_iter",
      "n_eval", "stop_reason", "status", "flags", "time_us", "psf_e1", "psf_e2", "psf_fwhm"};
  std::vector<std::string> grid = {"id", "ix", "iy"};
  grid.insert(grid.end(), fit.begin(), fit.end());
  std::vector<std::string> cat = {"id", "x_image", "y_image"};
  cat.insert(cat.end(), fit.begin(), fit.end());
  EXPECT_EQ(catalog_columns(PositionColumns::kGrid), grid);
  EXPECT_EQ(catalog_columns(PositionColumns::kCatalogue), cat);
}

TEST_F(CatalogWriterTest, WritesAllRowsInOrderWithHeaderAndText) {
  CatalogWriterOptions o = options();
  const std::string long_value(150, 'v');
  const std::string quoted = "it's a 'quoted' value, long enough to need CONTINUE cards: " +
                             std::string(40, 'q') + "'" + std::string(30, 'z');
  o.header.emplace_back("INPUT", long_value);
  o.header.emplace_back("a_very_long_configuration_key_name_for_hierarch", quoted);
  o.header.emplace_back("padding", "3");
  o.header.emplace_back("PADDING", "4");  // repeated: the last value wins
  o.header.emplace_back("empty_value", "");
  const auto records = make_records(708, PositionColumns::kGrid);

  auto w = CatalogWriter::create(o);
  EXPECT_TRUE(fs::exists(o.path + ".partial"));
  EXPECT_TRUE(fs::exists(o.text_path + ".partial"));
  EXPECT_TRUE(fs::exists(o.path + ".checkpoint"));
  EXPECT_FALSE(fs::exists(o.path));
  // 700 rows: more than one internal chunk of 256.
  append_batches(*w, records, 0, {5, 700, 3});
  EXPECT_EQ(w->rows(), 708);
  w->finish();
  EXPECT_EQ(w->rows(), 708);

  EXPECT_TRUE(fs::exists(o.path));
  EXPECT_TRUE(fs::exists(o.text_path));
  EXPECT_FALSE(fs::exists(o.path + ".partial"));
  EXPECT_FALSE(fs::exists(o.text_path + ".partial"));
  EXPECT_FALSE(fs::exists(o.path + ".checkpoint"));
  EXPECT_FALSE(fs::exists(o.path + ".checkpoint.tmp"));

  expect_table(o.path, records, PositionColumns::kGrid);
  expect_text(o.text_path, records, PositionColumns::kGrid);

  // Through the project's own reader too: doubles bitwise, NaN as NaN.
  FitsFile f = FitsFile::open_read(o.path);
  f.move_to("RESULTS");
  EXPECT_EQ(f.table_rows(), 708);
  const std::vector<double> e1_err = f.read_column("e1_err");
  const std::vector<double> flags = f.read_column("flags");
  for (std::size_t i = 0; i < records.size(); ++i) {
    ASSERT_TRUE(same_bits(e1_err[i], records[i].fit.e1_err) ||
                (std::isnan(e1_err[i]) && std::isnan(records[i].fit.e1_err)))
        << i;
    ASSERT_EQ(flags[i], static_cast<double>(records[i].flags)) << i;  // TZERO applied
  }

  // Configuration keys, with long and HIERARCH values intact.
  EXPECT_EQ(f.key_string("stamp_size"), "39");
  EXPECT_EQ(f.key_string("NOISE_SIGMA"), "0.001");
  EXPECT_EQ(f.key_string("psf_input"), "moffat");
  EXPECT_EQ(f.key_string("INPUT"), long_value);
  EXPECT_EQ(f.key_string("a_very_long_configuration_key_name_for_hierarch"), quoted);
  EXPECT_EQ(f.key_string("padding"), "4");
  EXPECT_EQ(f.key_string("empty_value"), "");
  // Status names, units, descriptions, unsigned flags.
  const char* const statuses[] = {"ok", "max_iterations", "bad_pixels", "no_data",
                                  "model_failure", "solver_failure", "psf_failure"};
  for (int s = 0; s < 7; ++s) {
    EXPECT_EQ(f.key_string("STATUS" + std::to_string(s)), statuses[s]);
  }
  EXPECT_EQ(f.key_string("EXTNAME"), "RESULTS");
  const auto names = catalog_columns(PositionColumns::kGrid);
  for (std::size_t c = 0; c < names.size(); ++c) {
    EXPECT_FALSE(f.key_string("TCOMM" + std::to_string(c + 1)).empty()) << names[c];
  }
  EXPECT_EQ(f.key_string("TUNIT4"), "pixel");   // x0
  EXPECT_EQ(f.key_string("TUNIT24"), "us");     // time_us
  EXPECT_EQ(f.key_string("TFORM23"), "1J");     // flags, unsigned through TZERO
  EXPECT_EQ(f.key_long("TZERO23"), 2147483648LL);
}

TEST_F(CatalogWriterTest, CatalogueColumnsWithoutTextFile) {
  CatalogWriterOptions o = options();
  o.positions = PositionColumns::kCatalogue;
  o.text_path.clear();
  const auto records = make_records(40, PositionColumns::kCatalogue);
  auto w = CatalogWriter::create(o);
  append_batches(*w, records, 0, {1, 39});
  w->finish();
  expect_table(o.path, records, PositionColumns::kCatalogue);  // ids beyond 2^53 exact
  EXPECT_EQ(std::distance(fs::directory_iterator(scratch_.dir()), fs::directory_iterator()), 1)
      << "only out.fits should be left";
}

TEST_F(CatalogWriterTest, EmptyAppendAndEmptyRun) {
  CatalogWriterOptions o = options();
  auto w = CatalogWriter::create(o);
  w->append({});
  EXPECT_EQ(w->rows(), 0);
  w->finish();
  expect_table(o.path, {}, PositionColumns::kGrid);
  expect_text(o.text_path, {}, PositionColumns::kGrid);
}

TEST_F(CatalogWriterTest, ResumeCutsUncommittedRowsAndMatchesUninterruptedRun) {
  const auto records = make_records(300, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  CatalogWriterOptions o = options("run");
  {
    auto w = CatalogWriter::create(o);
    append_batches(*w, records, 0, {120, 80});
  }  // destroyed without finish: a crash after the second commit
  EXPECT_FALSE(fs::exists(o.path));
  ASSERT_TRUE(fs::exists(o.path + ".partial"));
  ASSERT_TRUE(fs::exists(o.path + ".checkpoint"));

  // What a crash in the middle of the third batch can leave: rows past the checkpoint, in the
  // table (NAXIS2 already counting them) and as raw bytes past the table's end; a torn text line.
  {
    fitsfile* f = nullptr;
    int status = 0;
    fits_open_diskfile(&f, (o.path + ".partial").c_str(), READWRITE, &status);
    fits_movnam_hdu(f, BINARY_TBL, const_cast<char*>("RESULTS"), 0, &status);
    std::vector<LONGLONG> ids(10, 777);
    std::vector<double> junk(10, 1.25);
    fits_write_col(f, TLONGLONG, 1, 201, 1, 10, ids.data(), &status);
    fits_write_col(f, TDOUBLE, 4, 201, 1, 10, junk.data(), &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
    ASSERT_EQ(read_table(o.path + ".partial").rows.size(), 210u);
  }
  append_bytes(o.path + ".partial", std::string(5000, '\xab'));
  append_bytes(o.text_path + ".partial", "200 13 11 19.5 19.5 0.1\n201 14 11 19.25 1");

  long long committed = -1;
  auto w = CatalogWriter::resume(o);
  committed = w->units();
  EXPECT_EQ(committed, 200);
  EXPECT_EQ(w->rows(), 200);
  append_batches(*w, records, committed, {60, 40});
  w->finish();
  EXPECT_FALSE(fs::exists(o.path + ".checkpoint"));

  expect_table(o.path, records, PositionColumns::kGrid);
  expect_text(o.text_path, records, PositionColumns::kGrid);
  EXPECT_TRUE(read_bytes(o.path) == ref_fits) << "FITS differs from the uninterrupted run";
  EXPECT_EQ(read_bytes(o.text_path), ref_text);
}

TEST_F(CatalogWriterTest, ResumeThenFinishKeepsOnlyCommittedRows) {
  // More uncommitted rows than are appended after resuming (here none): the appends cannot hide
  // leftovers by overwriting them.
  const auto records = make_records(20, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  CatalogWriterOptions o = options("run");
  {
    auto w = CatalogWriter::create(o);
    w->append(records);
  }
  {
    fitsfile* f = nullptr;
    int status = 0;
    fits_open_diskfile(&f, (o.path + ".partial").c_str(), READWRITE, &status);
    fits_movnam_hdu(f, BINARY_TBL, const_cast<char*>("RESULTS"), 0, &status);
    std::vector<LONGLONG> ids(30, 777);
    fits_write_col(f, TLONGLONG, 1, 21, 1, 30, ids.data(), &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
  }
  append_bytes(o.text_path + ".partial", "20 3 1 nan nan\n");
  long long committed = -1;
  {
    auto w = CatalogWriter::resume(o);
    committed = w->units();
    w->finish();
  }
  EXPECT_EQ(committed, 20);
  expect_table(o.path, records, PositionColumns::kGrid);
  EXPECT_TRUE(read_bytes(o.path) == ref_fits) << "FITS differs from the uninterrupted run";
  EXPECT_EQ(read_bytes(o.text_path), ref_text);
}

TEST_F(CatalogWriterTest, ResumeZeroesRowsThatReachedDiskBeyondNaxis2) {
  // CFITSIO may evict buffers holding new rows before it rewrites NAXIS2: the bytes sit in the
  // last block's fill and beyond, while NAXIS2 still equals the committed count.
  const auto records = make_records(50, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  CatalogWriterOptions o = options("run");
  {
    auto w = CatalogWriter::create(o);
    append_batches(*w, records, 0, {7});
  }
  const std::string partial = o.path + ".partial";
  const auto size = static_cast<long long>(fs::file_size(partial));
  {
    const int fd = ::open(partial.c_str(), O_WRONLY);
    ASSERT_GE(fd, 0);
    const std::string junk(6000, '\x5a');
    // The table's 7 rows of 188 bytes start one block before the end; scribble after them.
    ASSERT_EQ(::pwrite(fd, junk.data(), junk.size(), size - 2880 + 7 * 188),
              static_cast<ssize_t>(junk.size()));
    ::close(fd);
  }
  long long committed = -1;
  auto w = CatalogWriter::resume(o);
  committed = w->units();
  EXPECT_EQ(committed, 7);
  append_batches(*w, records, committed, {43});
  w->finish();
  expect_table(o.path, records, PositionColumns::kGrid);
  EXPECT_TRUE(read_bytes(o.path) == ref_fits) << "FITS differs from the uninterrupted run";
  EXPECT_EQ(read_bytes(o.text_path), ref_text);
}

TEST_F(CatalogWriterTest, ResumeRightAfterCreateAndTwice) {
  const auto records = make_records(30, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  CatalogWriterOptions o = options("run");
  CatalogWriter::create(o).reset();
  long long committed = -1;
  committed = CatalogWriter::resume(o)->units();
  EXPECT_EQ(committed, 0);
  {
    auto w = CatalogWriter::resume(o);
    committed = w->units();
    append_batches(*w, records, 0, {10});
  }
  auto w = CatalogWriter::resume(o);
  committed = w->units();
  EXPECT_EQ(committed, 10);
  append_batches(*w, records, committed, {20});
  w->finish();
  EXPECT_TRUE(read_bytes(o.path) == ref_fits);
  EXPECT_EQ(read_bytes(o.text_path), ref_text);
}

TEST_F(CatalogWriterTest, CreateStartsOverAndDropsAStaleRun) {
  const auto records = make_records(20, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  CatalogWriterOptions o = options("run");
  {
    auto w = CatalogWriter::create(o);
    w->append(make_records(5, PositionColumns::kCatalogue));  // other rows
  }
  auto w = CatalogWriter::create(o);
  EXPECT_EQ(w->rows(), 0);
  w->append(records);
  w->finish();
  EXPECT_TRUE(read_bytes(o.path) == ref_fits);
  EXPECT_EQ(read_bytes(o.text_path), ref_text);
}

TEST_F(CatalogWriterTest, ResumeRefusesADifferentRun) {
  const auto records = make_records(10, PositionColumns::kGrid);
  CatalogWriterOptions o = options();
  {
    auto w = CatalogWriter::create(o);
    w->append(records);
  }
  const std::string expected =
      o.path + ".checkpoint was written by a different run (input or configuration changed)";
  CatalogWriterOptions other = o;
  other.fingerprint += "x";
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::resume(other); }), expected));
  other = o;
  other.positions = PositionColumns::kCatalogue;
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::resume(other); }), expected));
  other = o;
  other.text_path.clear();
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::resume(other); }), expected));
  // A refusal leaves the run resumable.
  long long committed = -1;
  committed = CatalogWriter::resume(o)->units();
  EXPECT_EQ(committed, 10);
}

// Nothing committed (no checkpoint): resume starts the table. A finished run, or a checkpoint
// whose partials are gone, has nothing to resume.
TEST_F(CatalogWriterTest, ResumeWithNothingCommittedStartsTheTable) {
  CatalogWriterOptions o = options();
  long long committed = -1;
  auto w = CatalogWriter::resume(o);
  committed = w->units();
  EXPECT_EQ(committed, 0);
  EXPECT_TRUE(fs::exists(o.path + ".partial") && fs::exists(o.path + ".checkpoint"));
  w->finish();
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::resume(o); }),
                       "nothing to resume at " + o.path));
  // Nor does a checkpoint whose partial output is gone.
  CatalogWriter::create(o).reset();
  fs::remove(o.text_path + ".partial");
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::resume(o); }),
                       "nothing to resume at " + o.path));
}

TEST_F(CatalogWriterTest, ResumeReportsCorruptFiles) {
  const auto records = make_records(10, PositionColumns::kGrid);
  CatalogWriterOptions o = options();
  auto start = [&] {
    auto w = CatalogWriter::create(o);
    w->append(records);
  };
  auto overwrite = [](const std::string& path, long long offset, const std::string& bytes) {
    const int fd = ::open(path.c_str(), O_WRONLY);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::pwrite(fd, bytes.data(), bytes.size(), offset), static_cast<ssize_t>(bytes.size()));
    ::close(fd);
  };
  std::string msg;

  start();
  overwrite(o.path + ".partial", 0, "garbage garbage garbage");
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.path + ".partial is corrupt"));

  start();
  // The last block, holding the committed rows, lost; the header intact.
  fs::resize_file(o.path + ".partial", fs::file_size(o.path + ".partial") - 2880);
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.path + ".partial is corrupt"));

  start();
  fs::resize_file(o.text_path + ".partial", 100);
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.text_path + ".partial is corrupt"));

  start();
  overwrite(o.text_path + ".partial", 0, "% not our header");
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.text_path + ".partial is corrupt"));

  start();  // the committed text must end a line
  overwrite(o.text_path + ".partial",
            static_cast<long long>(fs::file_size(o.text_path + ".partial")) - 1, "X");
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.text_path + ".partial is corrupt"));

  start();
  overwrite(o.path + ".checkpoint", 0, "stampede catalogue checkpoint 2");
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.path + ".checkpoint is corrupt"));

  // A different layout (here: another writer's positions) in the partial itself.
  start();
  CatalogWriterOptions cat = o;
  cat.path = scratch_.path("cat.fits");
  cat.text_path.clear();
  cat.positions = PositionColumns::kCatalogue;
  CatalogWriter::create(cat).reset();
  fs::copy_file(cat.path + ".partial", o.path + ".partial", fs::copy_options::overwrite_existing);
  msg = error_of<CatalogError>([&] { CatalogWriter::resume(o); });
  EXPECT_TRUE(Contains(msg, o.path + ".partial is corrupt"));
}

TEST_F(CatalogWriterTest, CreateFailsUpFrontNamingThePath) {
  CatalogWriterOptions o = options();
  o.path = "/nonexistent/dir/out.fits";
  o.text_path.clear();
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::create(o); }),
                       "/nonexistent/dir/out.fits"));
  o = options();
  o.text_path = "/nonexistent/dir/out.txt";
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::create(o); }),
                       "/nonexistent/dir/out.txt"));
  EXPECT_FALSE(fs::exists(options().path + ".partial")) << "a failed create leaves nothing";
  EXPECT_FALSE(fs::exists(options().path + ".checkpoint"));
  // Not even a stale run it was meant to replace.
  CatalogWriter::create(options()).reset();
  EXPECT_FALSE(error_of<CatalogError>([&] { CatalogWriter::create(o); }).empty());
  EXPECT_FALSE(fs::exists(options().path + ".checkpoint")) << "nothing left to resume: a resume starts anew";
  o = options();
  o.path += ".gz";
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { CatalogWriter::create(o); }), "compressed"));
}

TEST_F(CatalogWriterTest, RefusesReservedOrInvalidHeaderKeys) {
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
           {"NAXIS2", "5"}, {"ttype1", "x"}, {"STATUS3", "x"}, {"EXTNAME", "X"},
           {"bad=key", "x"}, {"", "x"}, {"plain", "caf\xc3\xa9"}, {std::string(70, 'k'), "x"}}) {
    CatalogWriterOptions o = options();
    o.header.emplace_back(key, value);
    EXPECT_FALSE(error_of<CatalogError>([&] { CatalogWriter::create(o); }).empty()) << key;
    EXPECT_FALSE(fs::exists(o.path + ".partial")) << key;
  }
}

TEST_F(CatalogWriterTest, WriterIsUnusableAfterFinish) {
  CatalogWriterOptions o = options();
  auto w = CatalogWriter::create(o);
  w->append(make_records(3, PositionColumns::kGrid));
  w->finish();
  const auto records = make_records(3, PositionColumns::kGrid);
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { w->append(records); }), "already finished"));
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { w->finish(); }), "already finished"));
  EXPECT_EQ(w->rows(), 3);
}

// A real crash: a child process is killed with SIGKILL while it writes its third batch; the
// parent resumes from whatever was committed. Repeated at several moments into the batch.
TEST_F(CatalogWriterTest, SurvivesSigkillMidBatch) {
  const long long n1 = 100, n2 = 57, n3 = 20000, n4 = 500;
  const auto records = make_records(n1 + n2 + n3 + n4, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  int interrupted_mid_batch = 0;
  const int delays_us[] = {0, 100, 500, 2000, 10000};
  for (int delay_us : delays_us) {
    SCOPED_TRACE("kill " + std::to_string(delay_us) + " us into the third batch");
    const CatalogWriterOptions o = options("kill" + std::to_string(delay_us));
    int pipe_fds[2];
    ASSERT_EQ(::pipe(pipe_fds), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      // Child: no gtest assertions here; its fate is reported through its exit status.
      ::close(pipe_fds[0]);
      try {
        auto w = CatalogWriter::create(o);
        append_batches(*w, records, 0, {n1, n2});
        const char go = 'g';
        if (::write(pipe_fds[1], &go, 1) != 1) ::_exit(3);
        append_batches(*w, records, n1 + n2, {n3});
        for (;;) ::pause();  // finished before the kill arrived: wait for it
      } catch (...) {
        ::_exit(2);
      }
    }
    ::close(pipe_fds[1]);
    char go = 0;
    ASSERT_EQ(::read(pipe_fds[0], &go, 1), 1) << "child failed before its third batch";
    ::close(pipe_fds[0]);
    if (delay_us > 0) ::usleep(static_cast<useconds_t>(delay_us));
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int wstatus = 0;
    ASSERT_EQ(::waitpid(pid, &wstatus, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGKILL) << "status " << wstatus;

    long long committed = -1;
    auto w = CatalogWriter::resume(o);
    committed = w->units();
    ASSERT_TRUE(committed == n1 + n2 || committed == n1 + n2 + n3) << committed;
    if (committed == n1 + n2) ++interrupted_mid_batch;
    const long long left = static_cast<long long>(records.size()) - committed;
    append_batches(*w, records, committed, {left / 2, left - left / 2});
    w->finish();
    EXPECT_TRUE(read_bytes(o.path) == ref_fits) << "FITS differs from the uninterrupted run";
    EXPECT_TRUE(read_bytes(o.text_path) == ref_text) << "text differs from the uninterrupted run";
  }
  expect_table(options("kill0").path, records, PositionColumns::kGrid);
  // The third batch takes milliseconds, so at least the immediate kill lands inside it.
  EXPECT_GT(interrupted_mid_batch, 0);
}

// In a child process whose file-size limit (RLIMIT_FSIZE) is `limit` bytes: creates the writer,
// appends `records` 100 at a time until an append fails, then abandon()s it. Returns the error
// message ("no failure" when none; "child ..." when the child itself went wrong).
std::string write_until_the_limit(const CatalogWriterOptions& o, const std::vector<ObjectRecord>& records, rlim_t limit) {
  return testing::in_child_with_file_size_limit(static_cast<long long>(limit), [&] {
    std::string message = "no failure";
    try {
      auto w = CatalogWriter::create(o);
      try {
        for (std::size_t first = 0; first < records.size(); first += 100)
          w->append(std::span(records).subspan(first, std::min<std::size_t>(100, records.size() - first)));
      } catch (const CatalogError& e) {
        message = e.what();
      }
      w->abandon();
    } catch (const std::exception& e) {
      message = std::string("create: ") + e.what();
    }
    return message;
  });
}

// A write that fails for want of room (here the process's file-size limit, RLIMIT_FSIZE, in a
// child) names what ran out, and the rows committed before it survive abandon(): the run resumes
// once the limit is raised and ends byte for byte as an uninterrupted run. SIGXFSZ, which would
// kill the child silently, is ignored by the writer. (Before: "cannot flush ...: CFITSIO status
// 106" and abandon() deleted the partials and the checkpoint.)
TEST_F(CatalogWriterTest, AWriteFailureNamesTheLimitAndKeepsTheCommittedRows) {
  const auto records = make_records(3000, PositionColumns::kGrid);
  const auto [ref_fits, ref_text] = reference(records);
  const CatalogWriterOptions o = options("limited");
  // 200000 bytes: some hundreds of rows of either file, not all 3000.
  const std::string message = write_until_the_limit(o, records, 200000);
  EXPECT_TRUE(Contains(message, "the file-size limit of this process (RLIMIT_FSIZE, `ulimit -f`) of 200000 bytes is reached"))
      << message;
  EXPECT_TRUE(Contains(message, "rows committed before it are kept in '" + o.path + ".partial'")) << message;
  EXPECT_TRUE(Contains(message, "resume the run")) << message;
  ASSERT_TRUE(fs::exists(o.path + ".partial") && fs::exists(o.path + ".checkpoint") && fs::exists(o.text_path + ".partial"));
  EXPECT_FALSE(fs::exists(o.path));

  long long committed = -1;
  auto w = CatalogWriter::resume(o);
  committed = w->units();
  EXPECT_GT(committed, 0);
  EXPECT_LT(committed, 3000);
  EXPECT_EQ(committed % 100, 0);
  append_batches(*w, records, committed, {3000 - committed});
  w->finish();
  EXPECT_TRUE(read_bytes(o.path) == ref_fits) << "FITS differs from the uninterrupted run";
  EXPECT_EQ(read_bytes(o.text_path), ref_text);
}

// A plain abandon() (an error elsewhere in the run) still removes everything, and so does one
// after a failed write when the caller cannot resume (keep_on_write_failure = false: a merge).
TEST_F(CatalogWriterTest, AbandonRemovesTheOutputsUnlessAWriteFailedAfterACommit) {
  const auto records = make_records(3000, PositionColumns::kGrid);
  const CatalogWriterOptions o = options("abandoned");
  auto w = CatalogWriter::create(o);
  w->append(std::span(records).subspan(0, 10));
  w->abandon();
  for (const std::string& p : {o.path + ".partial", o.path + ".checkpoint", o.text_path + ".partial"})
    EXPECT_FALSE(fs::exists(p)) << p;
  CatalogWriterOptions merge = options("merge");
  merge.keep_on_write_failure = false;
  const std::string message = write_until_the_limit(merge, records, 200000);
  EXPECT_TRUE(Contains(message, "the file-size limit of this process")) << message;
  EXPECT_FALSE(Contains(message, "kept")) << message;
  for (const std::string& p : {merge.path + ".partial", merge.path + ".checkpoint", merge.text_path + ".partial"})
    EXPECT_FALSE(fs::exists(p)) << p;
}

// What ran out, from the errno of a failed write: /dev/full fails every write with ENOSPC.
TEST(SpaceExhaustedReason, NamesTheFullFilesystemAndTheFileSizeLimit) {
  DurableFile full = DurableFile::create("/dev/full");
  const std::string e = error_of<FileError>([&] { full.write_all("x"); });
  EXPECT_TRUE(Contains(e, "cannot write '/dev/full': No space left on device (the filesystem holding '/dev' is full (")) << e;
  EXPECT_TRUE(Contains(space_exhausted_reason("/some/where/f.fits", EDQUOT), "the disk quota for '/some/where' is exceeded"));
  EXPECT_EQ(space_exhausted_reason("/nonexistent/x.fits", EIO), "");
}

}  // namespace
}  // namespace stampede::io
