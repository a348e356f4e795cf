// Tests for io/durable_file: the atomic replace leaves the new contents and no temporary (and
// survives a stale one), the descriptor operations an append-only log needs (create, write, sync,
// reopen, truncate to the last record, append), and FileErrors that name the path.
#include "io/durable_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

std::string contents(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class DurableFileTest : public ::testing::Test {
 protected:
  stampede::testing::ScratchDir scratch_{"stampede_durable_file_"};
};

TEST_F(DurableFileTest, ReplaceDurablyWritesNewContentsAndNoTemporary) {
  const std::string path = scratch_.path("run.checkpoint");
  EXPECT_EQ(temporary_path(path), path + ".tmp");
  replace_durably(path, "rows 1\n");
  EXPECT_EQ(contents(path), "rows 1\n");
  {
    std::ofstream stale(temporary_path(path));  // left by a crash between steps 1 and 3
    stale << "garbage that is longer than the new contents";
  }
  replace_durably(path, "rows 22\n");
  EXPECT_EQ(contents(path), "rows 22\n");
  EXPECT_FALSE(file_exists(temporary_path(path)));
  replace_durably(path, "");
  EXPECT_EQ(contents(path), "");
}

TEST_F(DurableFileTest, AppendOnlyLogResumesAfterTheLastWholeRecord) {
  const std::string path = scratch_.path("progress.txt");
  {
    DurableFile log = DurableFile::create(path);
    EXPECT_TRUE(log.is_open());
    EXPECT_EQ(log.path(), path);
    log.write_all("# header\n");
    log.write_all("1 ok\n2 ha");  // the last record cut by a crash
    log.sync();
    EXPECT_EQ(log.size(), 18);
    log.close();
    EXPECT_FALSE(log.is_open());
    log.close();  // idempotent
  }
  sync_directory_of(path);
  DurableFile log = DurableFile::open(path, DurableFile::Mode::kReadWrite);
  std::string head(8, '\0');
  log.read_at(0, head);
  EXPECT_EQ(head, "# header");
  log.truncate(14);  // keep "# header\n1 ok\n"
  log.seek_to_end();
  log.write_all("2 ok\n");
  log.sync();
  log.close();
  EXPECT_EQ(contents(path), "# header\n1 ok\n2 ok\n");

  DurableFile read = DurableFile::open(path, DurableFile::Mode::kRead);
  std::string past(4, '\0');
  EXPECT_TRUE(Contains(error_of<FileError>([&] { read.read_at(17, past); }), path));
  // Moves keep one owner.
  DurableFile moved = std::move(read);
  EXPECT_TRUE(moved.is_open());
  EXPECT_EQ(moved.size(), 19);
}

TEST_F(DurableFileTest, FailuresNameThePath) {
  const std::string missing = scratch_.path("no/such/dir/file");
  EXPECT_TRUE(Contains(error_of<FileError>([&] { DurableFile::open(missing, DurableFile::Mode::kRead); }),
                       "cannot open '" + missing + "'"));
  EXPECT_TRUE(Contains(error_of<FileError>([&] { DurableFile::create(missing, "catalogue"); }),
                       "cannot create catalogue '" + missing + "': No such file or directory"));
  EXPECT_TRUE(Contains(error_of<FileError>([&] { replace_durably(missing, "x"); }), missing + ".tmp"));
  EXPECT_TRUE(Contains(error_of<FileError>([&] { rename_file(missing, scratch_.path("b")); }),
                       "cannot rename '" + missing + "'"));
  EXPECT_TRUE(Contains(error_of<FileError>([&] { sync_directory_of(missing); }),
                       scratch_.path("no/such/dir")));
  remove_if_present(missing);  // absent: not an error
  const std::string present = scratch_.path("present");
  replace_durably(present, "x");
  EXPECT_TRUE(file_exists(present));
  remove_if_present(present);
  EXPECT_FALSE(file_exists(present));
  EXPECT_EQ(directory_of("bare_name"), ".");
  EXPECT_EQ(directory_of("/a/b/c.fits"), "/a/b");
}

}  // namespace
}  // namespace stampede::io
