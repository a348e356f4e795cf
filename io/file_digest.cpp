// XXH64 over a stream and the file digest; see file_digest.hpp.
#include "io/file_digest.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <system_error>

#include "engine/common/quoted_value.hpp"
#include "io/durable_file.hpp"

namespace stampede::io {
namespace {

constexpr std::uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full, kP3 = 0x165667B19E3779F9ull,
                        kP4 = 0x85EBCA77C2B2AE63ull, kP5 = 0x27D4EB2F165667C5ull;

// Little-endian loads, whatever the host's order: the hash of a file is the same everywhere.
std::uint64_t load64(const unsigned char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, sizeof v);
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap64(v);
  return v;
}
std::uint64_t load32(const unsigned char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, sizeof v);
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap32(v);
  return v;
}

std::uint64_t lane_round(std::uint64_t acc, std::uint64_t input) { return std::rotl(acc + input * kP2, 31) * kP1; }
std::uint64_t merge_round(std::uint64_t acc, std::uint64_t v) { return (acc ^ lane_round(0, v)) * kP1 + kP4; }

// XXH64 fed in pieces of any size: whole 32-byte stripes go through the four lanes, the rest waits
// in `tail_` for the next piece or for digest().
class Xxh64Stream {
 public:
  void update(const unsigned char* p, std::size_t n) {
    total_ += n;
    if (buffered_ > 0) {
      const std::size_t take = std::min(n, sizeof tail_ - buffered_);
      std::memcpy(tail_ + buffered_, p, take);
      buffered_ += take, p += take, n -= take;
      if (buffered_ < sizeof tail_) return;
      stripe(tail_);
      buffered_ = 0;
    }
    for (; n >= 32; p += 32, n -= 32) stripe(p);
    std::memcpy(tail_, p, n);
    buffered_ = n;
  }

  std::uint64_t digest() const {
    std::uint64_t h;
    if (total_ >= 32) {
      h = std::rotl(v_[0], 1) + std::rotl(v_[1], 7) + std::rotl(v_[2], 12) + std::rotl(v_[3], 18);
      for (std::uint64_t v : v_) h = merge_round(h, v);
    } else {
      h = kP5;
    }
    h += total_;
    const unsigned char* p = tail_;
    std::size_t n = buffered_;
    for (; n >= 8; p += 8, n -= 8) h = std::rotl(h ^ lane_round(0, load64(p)), 27) * kP1 + kP4;
    if (n >= 4) {
      h = std::rotl(h ^ (load32(p) * kP1), 23) * kP2 + kP3;
      p += 4, n -= 4;
    }
    for (; n > 0; ++p, --n) h = std::rotl(h ^ (*p * kP5), 11) * kP1;
    h ^= h >> 33;
    h *= kP2;
    h ^= h >> 29;
    h *= kP3;
    return h ^ (h >> 32);
  }

 private:
  void stripe(const unsigned char* p) {
    for (int lane = 0; lane < 4; ++lane) v_[lane] = lane_round(v_[lane], load64(p + 8 * lane));
  }
  std::uint64_t v_[4] = {kP1 + kP2, kP2, 0, 0 - kP1};  // seed 0
  std::uint64_t total_ = 0;
  unsigned char tail_[32] = {};
  std::size_t buffered_ = 0;
};

}  // namespace

std::string FileDigest::text() const {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%lld bytes, xxh64 %016llx", size, static_cast<unsigned long long>(hash));
  return buf;
}

std::uint64_t xxh64(std::string_view bytes) {
  Xxh64Stream s;
  s.update(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size());
  return s.digest();
}

FileDigest digest_file(const std::string& path) {
  auto fail = [&](int e) {
    throw FileError("cannot read " + quoted_value(path, kQuotedPathMaxBytes) +
                    " for the run fingerprint: " + std::generic_category().message(e));
  };
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail(errno);
  constexpr std::size_t kBlock = 1 << 20;
  const auto block = std::make_unique<unsigned char[]>(kBlock);
  Xxh64Stream s;
  FileDigest d;
  for (;;) {
    const ssize_t n = ::read(fd, block.get(), kBlock);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;  // EISDIR for a directory
      ::close(fd);
      fail(e);
    }
    if (n == 0) break;
    s.update(block.get(), static_cast<std::size_t>(n));
    d.size += n;
  }
  ::close(fd);
  d.hash = s.digest();
  return d;
}

}  // namespace stampede::io
