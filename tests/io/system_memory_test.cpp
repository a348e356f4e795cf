// available_memory_bytes: MemAvailable of a /proc/meminfo-format file, nothing when it is absent.
#include <gtest/gtest.h>

#include <fstream>

#include "io/system_memory.hpp"
#include "support/scratch_dir.hpp"

namespace {

TEST(SystemMemory, ReadsMemAvailableInBytes) {
  stampede::testing::ScratchDir scratch("stampede_system_memory_");
  std::ofstream(scratch.path("meminfo")) << "MemTotal:       24000000 kB\nMemFree:         2000000 kB\n"
                                            "MemAvailable:   16000000 kB\nBuffers:          100000 kB\n";
  EXPECT_EQ(stampede::io::available_memory_bytes(scratch.path("meminfo")), 16000000.0 * 1024);
  std::ofstream(scratch.path("old")) << "MemTotal:       24000000 kB\nMemFree:         2000000 kB\n";
  EXPECT_EQ(stampede::io::available_memory_bytes(scratch.path("old")), std::nullopt);
  EXPECT_EQ(stampede::io::available_memory_bytes(scratch.path("missing")), std::nullopt);
  EXPECT_GT(stampede::io::available_memory_bytes().value_or(1), 0.0);  // this machine's, when it has one
}

}  // namespace
