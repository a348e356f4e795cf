// The output lock: a second holder is refused with a message naming the first's pid and host;
// release removes the file; a lock left by a process that died (without releasing) is taken over.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <sstream>
#include <string>

#include "io/durable_file.hpp"
#include "io/output_lock.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using stampede::io::FileError;
using stampede::io::OutputLock;
using stampede::testing::Contains;
using stampede::testing::error_of;

std::string host() {
  char h[256] = {};
  gethostname(h, sizeof h - 1);
  return h;
}

std::string contents(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(OutputLock, ASecondRunIsRefusedNamingTheHolder) {
  stampede::testing::ScratchDir dir("stampede_output_lock_");
  const std::string out = dir.path("out.fits");
  OutputLock first = OutputLock::acquire(out);
  EXPECT_TRUE(first.held());
  const std::string record = "pid " + std::to_string(getpid()) + " on host " + host();
  EXPECT_EQ(contents(OutputLock::path_for(out)), record + "\n");
  // A second acquisition, even in the same process (its own open file description), is refused.
  EXPECT_TRUE(Contains(error_of<FileError>([&] { OutputLock::acquire(out); }),
                       "'" + out + "' is in use by another run: '" + out + ".lock' is held by '" + record + "'"));
  first.release();
  EXPECT_FALSE(stampede::io::file_exists(OutputLock::path_for(out)));
  EXPECT_TRUE(OutputLock::acquire(out).held());  // free again (and released by the temporary)
  EXPECT_FALSE(stampede::io::file_exists(OutputLock::path_for(out)));
}

TEST(OutputLock, ALockWhoseHolderDiedIsTakenOver) {
  stampede::testing::ScratchDir dir("stampede_output_lock_");
  const std::string out = dir.path("out.fits");
  const pid_t child = fork();
  if (child == 0) {
    OutputLock lock = OutputLock::acquire(out);
    _exit(0);  // dies holding it: no destructor, the file stays
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ASSERT_EQ(contents(OutputLock::path_for(out)), "pid " + std::to_string(child) + " on host " + host() + "\n");
  OutputLock lock = OutputLock::acquire(out);
  EXPECT_TRUE(lock.held());
  EXPECT_EQ(contents(OutputLock::path_for(out)), "pid " + std::to_string(getpid()) + " on host " + host() + "\n");
}

TEST(OutputLock, AnUncreatableLockNamesItsPath) {
  EXPECT_TRUE(Contains(error_of<FileError>([] { OutputLock::acquire("/nonexistent/dir/o.fits"); }),
                       "cannot create the lock file '/nonexistent/dir/o.fits.lock': "));
}

}  // namespace
