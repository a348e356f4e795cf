// The file digest: XXH64 against the reference implementation's values (libxxhash 0.8.1), the same
// hash for a file read in 1 MiB blocks as for its bytes at once, and errors naming the file.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "io/durable_file.hpp"
#include "io/file_digest.hpp"
#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

namespace {

using stampede::io::digest_file;
using stampede::testing::Contains;
using stampede::testing::error_of;
using stampede::io::xxh64;

std::string hex(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

TEST(FileDigest, Xxh64MatchesTheReference) {
  // Every path of the algorithm: < 32 bytes (no stripes), one stripe exactly, stripes plus 8-, 4-
  // and 1-byte tails.
  EXPECT_EQ(hex(xxh64("")), "ef46db3751d8e999");
  EXPECT_EQ(hex(xxh64("abc")), "44bc2cf5ad770999");
  EXPECT_EQ(hex(xxh64(std::string(31, 'a'))), "fe47067cda802916");
  EXPECT_EQ(hex(xxh64(std::string(32, 'a'))), "856e843298f99ad7");
  std::string digits;
  for (int k = 0; k < 10; ++k) digits += "0123456789";
  EXPECT_EQ(hex(xxh64(digits)), "f80e7b96315afffa");
  std::string bytes;
  for (int k = 0; k < 3; ++k)
    for (int b = 0; b < 256; ++b) bytes += static_cast<char>(b);
  EXPECT_EQ(hex(xxh64(bytes + "xyz")), "e921a1b45bd779f8");
}

TEST(FileDigest, AFileIsHashedAcrossItsBlocksAsItsBytesAtOnce) {
  stampede::testing::ScratchDir dir("stampede_file_digest_");
  // Two 1 MiB blocks and a tail that is not a whole stripe.
  std::string bytes((1 << 21) + 37, '\0');
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 131 + 7) & 255);
  const std::string path = dir.path("f.bin");
  std::ofstream(path, std::ios::binary) << bytes;
  const auto d = digest_file(path);
  EXPECT_EQ(d.size, static_cast<long long>(bytes.size()));
  EXPECT_EQ(hex(d.hash), "f6d2aa83731ebfb4");  // libxxhash's XXH64 of the same bytes
  EXPECT_EQ(d.hash, xxh64(bytes));
  EXPECT_EQ(d.text(), "2097189 bytes, xxh64 f6d2aa83731ebfb4");
  // One flipped bit anywhere changes it; the size alone does not identify the content.
  bytes[bytes.size() / 2] ^= 1;
  std::ofstream(path, std::ios::binary) << bytes;
  EXPECT_EQ(digest_file(path).size, d.size);
  EXPECT_NE(digest_file(path).hash, d.hash);
}

TEST(FileDigest, AnUnreadableFileIsAnErrorNamingIt) {
  stampede::testing::ScratchDir dir("stampede_file_digest_");
  for (const std::string& path : {dir.path("missing.fits"), dir.dir().string()})
    EXPECT_TRUE(Contains(error_of<stampede::io::FileError>([&] { digest_file(path); }),
                         "cannot read '" + path + "' for the run fingerprint: "));
}

}  // namespace
