// The content digest of a run's input files: the size and the XXH64 hash (Collet's xxHash, 64-bit,
// seed 0) of every byte, headers and data alike, read once in 1 MiB blocks. The run fingerprint
// records it, so `--resume` after an input's content was replaced at the same path is refused.
// XXH64 (written here from its specification) hashes 32 bytes per round in four independent lanes
// of 64-bit multiply-rotate, faster than the file can be read and far below the cost of fitting
// what the file holds (docs/usage.md, "Resume"); it is not cryptographic (it detects accidents, not
// forgeries). Its value is the same on every machine.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace stampede::io {

struct FileDigest {
  long long size = 0;      // bytes read
  std::uint64_t hash = 0;  // XXH64 of those bytes, seed 0
  // "N bytes, xxh64 0123456789abcdef".
  std::string text() const;
};

// XXH64 of `bytes` (seed 0), as digest_file computes it over a file's contents.
std::uint64_t xxh64(std::string_view bytes);

// Reads the file at `path` (a path on disk, not CFITSIO syntax) to its end. Throws FileError
// "cannot read 'PATH' for the run fingerprint: <reason>" (a directory, a missing file, an I/O error).
FileDigest digest_file(const std::string& path);

}  // namespace stampede::io
