// Crash-safe files over POSIX: an owned descriptor whose writes can be forced to the disk, the
// directory sync that makes a creation or rename durable, and the checkpoint protocol that
// replaces a small file atomically, so a process killed at any moment (kill -9, a power cut)
// leaves either the old or the new contents, never a mix.
//
// The protocol of replace_durably(PATH, bytes):
//   1. write the bytes to temporary_path(PATH) = PATH.tmp, created or emptied;
//   2. fsync it, so its contents are on disk before any name refers to them;
//   3. rename it over PATH (atomic in POSIX: a reader sees the old file or the new one);
//   4. fsync PATH's directory, so the rename itself survives a power cut.
// A crash before 3 leaves PATH as it was (and possibly a stale PATH.tmp, which the next replace
// overwrites); after 3, PATH is the new contents.
//
// An append-only progress log (the calibration build's) is DurableFile::create, then write_all
// and sync per record; resuming it is DurableFile::open(kReadWrite), truncate to the last whole
// record and seek_to_end.
//
// Every failure throws FileError naming the path and the system's reason (errno text; for a write
// that ran out of room, what ran out: space_exhausted_reason).
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <utility>

#include "engine/common/error.hpp"

namespace stampede::io {

class FileError : public Error {
 public:
  using Error::Error;
};

class DurableFile {
 public:
  enum class Mode { kRead, kReadWrite };
  // Opens an existing file. Throws "cannot open 'PATH': <reason>".
  static DurableFile open(const std::string& path, Mode mode);
  // Creates PATH, or empties an existing one, for writing. Throws "cannot create KIND 'PATH':
  // <reason>" ("cannot create 'PATH': ..." without a kind).
  static DurableFile create(const std::string& path, std::string_view kind = "");

  DurableFile() = default;  // no file: is_open() is false
  DurableFile(DurableFile&& other) noexcept;
  DurableFile& operator=(DurableFile&& other) noexcept;
  DurableFile(const DurableFile&) = delete;
  DurableFile& operator=(const DurableFile&) = delete;
  // Closes without reporting errors; call close() where a failed close must be seen.
  ~DurableFile();

  const std::string& path() const { return path_; }
  bool is_open() const { return fd_ >= 0; }

  // Writes every byte at the current offset (retrying short writes and EINTR).
  void write_all(std::string_view bytes);
  // fsync: everything written to the file so far, by any descriptor, is on disk.
  void sync();
  long long size();
  // Reads exactly out.size() bytes at `offset`.
  void read_at(long long offset, std::span<char> out);
  // Cuts (or extends with zeros) the file to `size` bytes; the offset is unchanged.
  void truncate(long long size);
  // Moves the offset to the end, for appending after a truncate.
  void seek_to_end();
  // Closes and reports a failure. Idempotent.
  void close();

 private:
  DurableFile(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  int fd_ = -1;
  std::string path_;
};

// The directory holding `path` ("." for a bare name).
std::string directory_of(const std::string& path);
// Makes creations, renames and removals in the directory of `path` durable. Filesystems that
// cannot sync a directory (EINVAL) order metadata themselves and are accepted.
void sync_directory_of(const std::string& path);
// Removes `path`; a missing file is not an error.
void remove_if_present(const std::string& path);
bool file_exists(const std::string& path);
// The temporary that replace_durably writes: PATH.tmp.
std::string temporary_path(const std::string& path);
// Replaces the contents of `path` by `bytes` with the protocol above.
void replace_durably(const std::string& path, std::string_view bytes);
// Renames `from` to `to`, replacing `to`; durable once sync_directory_of(to) returns (callers
// with several changes in one directory sync it once, after the last).
void rename_file(const std::string& from, const std::string& to);

// What ran out when a write to `path` failed with errno `error` (0 when the caller does not know
// it, e.g. behind CFITSIO's "status 106"): "the file-size limit (RLIMIT_FSIZE, `ulimit -f`) of N
// bytes is reached", "the filesystem holding 'DIR' is full (N bytes available)", "the disk quota
// of ... is exceeded". Without errno the limits themselves are checked: the file at or past the
// process's RLIMIT_FSIZE, no block available on its filesystem (statvfs). "" when none explains it.
std::string space_exhausted_reason(const std::string& path, int error);

// "" when the file at `path` holds at least `end` bytes; else "cannot write 'PATH': its last N bytes
// were not written (what ran out, or: a short write at close)". For a file CFITSIO closed: its
// close writes the last blocks and can lose a short write (a file-size limit or a full disk met
// there) without reporting it.
std::string unwritten_tail(const std::string& path, long long end);

// Makes SIGXFSZ ignored when it has its default action (which kills the process with no message
// when a write passes RLIMIT_FSIZE): the write then fails with EFBIG, which the writers report. A
// handler the program installed is left alone. Idempotent; called by every output path.
void ignore_file_size_signal();

}  // namespace stampede::io
