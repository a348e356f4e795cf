// Output checks: a directory, an input under another name (a link, a hard link, CFITSIO syntax
// resolved by the caller), a companion (partial, checkpoint) that is an input, two outputs that
// are one file, and an existing output without overwrite are refused with messages naming them.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "io/durable_file.hpp"
#include "io/output_check.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using stampede::io::check_outputs;
using stampede::io::FileError;
using stampede::io::RunInput;
using stampede::io::RunOutput;
using stampede::testing::Contains;
using stampede::testing::error_of;

class OutputCheckTest : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return dir.path(name); }
  std::string refusal(const std::vector<RunOutput>& outputs, bool replace = false) {
    return error_of<FileError>([&] { check_outputs(outputs, inputs, replace); });
  }
  stampede::testing::ScratchDir dir{"stampede_output_check_"};
  std::vector<RunInput> inputs;
  void SetUp() override {
    std::ofstream(path("in.fits")) << "image";
    std::ofstream(path("cat.txt")) << "1 2 3\n";
    inputs = {{"input", path("in.fits")}, {"--catalog", path("cat.txt")}};
  }
};

TEST_F(OutputCheckTest, AFreshOutputPasses) {
  EXPECT_NO_THROW(check_outputs(std::vector<RunOutput>{{"-o", path("out.fits"), {path("out.fits.partial")}}}, inputs, false));
}

TEST_F(OutputCheckTest, ADirectoryIsRefused) {
  std::filesystem::create_directory(path("d"));
  EXPECT_TRUE(Contains(refusal({{"-o", path("d"), {}}}, true), "-o '" + path("d") + "' is a directory"));
}

TEST_F(OutputCheckTest, AnInputUnderAnyNameIsRefused) {
  ASSERT_EQ(::symlink(path("in.fits").c_str(), path("soft.fits").c_str()), 0);
  ASSERT_EQ(::link(path("cat.txt").c_str(), path("hard.txt").c_str()), 0);
  const std::string expect = " is the input '" + path("in.fits") + "': writing it would destroy the input";
  EXPECT_TRUE(Contains(refusal({{"-o", path("in.fits"), {}}}, true), "-o '" + path("in.fits") + "'" + expect));
  EXPECT_TRUE(Contains(refusal({{"-o", path("soft.fits"), {}}}, true), "-o '" + path("soft.fits") + "'" + expect));
  EXPECT_TRUE(Contains(refusal({{"--text", path("hard.txt"), {}}}, true),
                       "--text '" + path("hard.txt") + "' is the --catalog '" + path("cat.txt") + "'"));
  // Even with overwrite, and even where the input's name is a file the run writes beside its output.
  EXPECT_TRUE(Contains(refusal({{"-o", path("in"), {path("in.fits")}}}, true),
                       "-o '" + path("in") + "': the run writes '" + path("in.fits") + "', which is the input"));
}

TEST_F(OutputCheckTest, TwoOutputsThatAreOneFileAreRefused) {
  EXPECT_TRUE(Contains(refusal({{"-o", path("o.fits"), {}}, {"--text", path("o.fits"), {}}}),
                       "--text '" + path("o.fits") + "' is the same file as -o '" + path("o.fits") + "'"));
}

// Found while fuzzing the Python arguments: `-o /dev/null --overwrite` (as root) renamed the table
// over the device node. A device, FIFO or socket is never replaced, overwrite or not.
TEST_F(OutputCheckTest, ADeviceOrFifoIsNeverReplaced) {
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  const std::string expect = std::string("'").append(path("fifo")).append("' is not a regular file (a device, FIFO or socket)");
  for (bool overwrite : {false, true}) EXPECT_TRUE(Contains(refusal({{"-o", path("fifo"), {}}}, overwrite), expect));
  EXPECT_TRUE(Contains(refusal({{"--text", "/dev/null", {}}}, true), "'/dev/null' is not a regular file"));
  EXPECT_THROW(stampede::io::refuse_to_replace("/dev/null", true), FileError);
}

TEST_F(OutputCheckTest, AnExistingOutputNeedsOverwrite) {
  std::ofstream(path("old.fits")) << "an earlier table";
  const std::string old = path("old.fits");
  EXPECT_EQ(refusal({{"-o", old, {}}}), std::string("'").append(old).append("' exists (use --overwrite to replace it)"));
  EXPECT_NO_THROW(check_outputs(std::vector<RunOutput>{{"-o", path("old.fits"), {}}}, inputs, true));
  EXPECT_NO_THROW(stampede::io::refuse_to_replace(path("new.fits"), false));
  EXPECT_THROW(stampede::io::refuse_to_replace(path("old.fits"), false), FileError);
}

}  // namespace
