// Tests for io/durable_table, the commit protocol of every table a run writes: a file-size limit
// (RLIMIT_FSIZE, in a child process) of every size up to the finished table's, met anywhere (the
// creation, a commit, the final close), never leaves a table named complete that is not whole, and
// resume then gives the uninterrupted table byte for byte, FITS and text; a resume with nothing
// committed starts the table; a finished table is not resumed.
#include "io/durable_table.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/durable_file.hpp"
#include "support/error_assertions.hpp"
#include "support/file_size_limit.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

namespace fs = std::filesystem;
using stampede::testing::Contains;
using stampede::testing::error_of;

constexpr long long kRows = 300, kRowsPerCommit = 40;

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

DurableTableOptions options(const std::string& base) {
  DurableTableOptions o;
  o.path = base + ".fits";
  o.text_path = base + ".txt";
  o.text_header = "# id value\n";
  o.extname = "TABLE";
  o.columns = {{"id", "1K", "", "row number"}, {"value", "1D", "m", "a value"}, {"name", "7A", "", ""}};
  o.describe = [](fitsfile* f, int* status) { fits_write_comment(f, "a test table", status); };
  o.header = {{"RUNKEY", "value"}, {"NUMBER", "42"}};
  o.header_types = {{"NUMBER", HeaderValueType::kInteger}};
  o.fingerprint = "test run\nseed=1\n";
  o.layout = "test table";
  o.reserved_keys = 1;
  o.units = "batches";
  return o;
}

// One commit of rows [first, first + n): a unit each.
void append(DurableTable& t, long long n) {
  t.append(n, 1, [&] {
    std::vector<LONGLONG> ids;
    std::vector<double> values;
    std::vector<std::string> names;
    std::string text;
    for (long long k = t.rows(); k < t.rows() + n; ++k) {
      ids.push_back(k);
      values.push_back(0.25 * static_cast<double>(k) - 3.0);
      names.push_back(std::to_string(k));  // (not "r" + ...: GCC 12's -Wrestrict false positive)
      text += std::to_string(k) + " " + std::to_string(values.back()) + "\n";
    }
    std::vector<char*> name_ptrs;
    for (std::string& s : names) name_ptrs.push_back(s.data());
    int status = 0;
    errno = 0;
    fits_write_col(t.fits(), TLONGLONG, 1, t.rows() + 1, 1, n, ids.data(), &status);
    fits_write_col(t.fits(), TDOUBLE, 2, t.rows() + 1, 1, n, values.data(), &status);
    fits_write_col(t.fits(), TSTRING, 3, t.rows() + 1, 1, n, name_ptrs.data(), &status);
    t.check(status, "write rows to", errno);
    t.write_text(text);
  });
}

void run_to_end(DurableTable& t) {
  while (t.rows() < kRows) append(t, std::min(kRowsPerCommit, kRows - t.rows()));
  t.finish({{"NUNITS", t.units(), "units written"}});
}

// In a child whose file-size limit is `limit` bytes: create and run to the end until something
// fails, then abandon. Returns the error ("" none; "child ..." when the child itself went wrong).
std::string run_under_limit(const DurableTableOptions& o, long long limit) {
  return testing::in_child_with_file_size_limit(limit, [&]() -> std::string {
    try {
      auto t = DurableTable::create(o);
      try {
        run_to_end(*t);
      } catch (const CatalogError& e) {
        t->abandon();
        return e.what();
      }
    } catch (const std::exception& e) {
      return std::string("create: ") + e.what();
    }
    return "";
  });
}

TEST(DurableTable, EveryFileSizeLimitResumesToTheUninterruptedTable) {
  testing::ScratchDir dir("stampede_durable_table_");
  const DurableTableOptions reference = options(dir.path("reference"));
  {
    auto t = DurableTable::create(reference);
    run_to_end(*t);
  }
  const std::string fits = bytes_of(reference.path), text = bytes_of(reference.text_path);
  const long long largest = static_cast<long long>(std::max(fits.size(), text.size()));
  ASSERT_GT(largest, 10000);
  int whole = 0, resumed = 0, started = 0;
  for (long long limit = 256; limit <= largest; limit += limit + 256 <= largest ? 256 : std::max(1LL, largest - limit)) {
    std::string name = std::to_string(limit);  // (not "limit" + ...: GCC 12's -Wrestrict false positive)
    name.append(".limit");
    const DurableTableOptions o = options(dir.path(name));
    const std::string message = run_under_limit(o, limit);
    ASSERT_FALSE(message.starts_with("child")) << message;
    if (message.empty()) {  // the run finished: its table is whole
      ++whole;
      EXPECT_EQ(bytes_of(o.path), fits) << limit;
    } else {
      EXPECT_FALSE(fs::exists(o.path)) << limit << ": a failed run names no table";
      EXPECT_TRUE(Contains(message, "file-size limit")) << limit << ": " << message;
      DurableTable::Committed c;
      auto t = DurableTable::resume(o, &c);
      (c.fresh ? started : resumed) += 1;
      if (!c.fresh) {
        EXPECT_TRUE(Contains(message, "committed")) << message;
      }
      run_to_end(*t);
      EXPECT_EQ(bytes_of(o.path), fits) << "limit " << limit << ": " << message;
    }
    EXPECT_EQ(bytes_of(o.text_path), text) << limit;
    for (const char* suffix : {".partial", ".checkpoint", ".checkpoint.tmp"})
      EXPECT_FALSE(fs::exists(o.path + suffix)) << limit << suffix;
    if (limit == largest) break;
  }
  std::printf("%d limits resumed, %d started anew, %d whole\n", resumed, started, whole);
  EXPECT_GT(resumed, 20);
  EXPECT_GT(started, 0);
  EXPECT_GT(whole, 0);
}

TEST(DurableTable, ResumeStartsWhatNothingWasCommittedOfAndRefusesAFinishedTable) {
  testing::ScratchDir dir("stampede_durable_table_");
  const DurableTableOptions o = options(dir.path("t"));
  // A partial without its checkpoint (killed while creating): nothing was committed.
  std::ofstream(o.path + ".partial") << "half a header";
  DurableTable::Committed c;
  auto t = DurableTable::resume(o, &c);
  EXPECT_TRUE(c.fresh);
  EXPECT_EQ(c.rows, 0);
  run_to_end(*t);
  const std::string fits = bytes_of(o.path);
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { DurableTable::resume(o, &c); }), "it is complete"));
  EXPECT_EQ(bytes_of(o.path), fits);
  // A run stopped between its rename and the checkpoint's removal finished: said so, not resumed.
  std::ofstream(o.path + ".checkpoint") << "left behind";
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { DurableTable::resume(o, &c); }), "that finished"));
  EXPECT_EQ(bytes_of(o.path), fits);
  fs::remove(o.path + ".checkpoint");
  // A checkpoint whose partial is gone is refused, not started over.
  const DurableTableOptions other = options(dir.path("u"));
  auto u = DurableTable::create(other);
  append(*u, 10);
  u.reset();
  fs::remove(other.path + ".partial");
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { DurableTable::resume(other, &c); }), "does not exist"));
  // Another layout is another run.
  fs::remove(other.text_path + ".partial");
  DurableTableOptions moved = options(dir.path("v"));
  auto v = DurableTable::create(moved);
  append(*v, 10);
  v.reset();
  moved.layout = "another table";
  EXPECT_TRUE(Contains(error_of<CatalogError>([&] { DurableTable::resume(moved, &c); }), "the layout 'test table'"));
}

TEST(DurableTable, FirstDifferenceNamesTheChangedOptionFirst) {
  EXPECT_EQ(first_difference("a=1\ninput x: d1\n", "input x: d2\na=2\n"), ": it records 'a=1', this run has 'a=2'");
  EXPECT_EQ(first_difference("input x: d1\n", "input x: d2\n"), ": it records 'input x: d1', this run has 'input x: d2'");
  EXPECT_EQ(first_difference("a=1\n", "a=1\nb=2\n"), ": this run has 'b=2', which it does not record");
  EXPECT_EQ(first_difference("a=1\n", "a=1\n"), "");
}

}  // namespace
}  // namespace stampede::io
