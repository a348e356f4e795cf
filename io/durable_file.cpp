// POSIX durability helpers and the atomic-replace protocol; see durable_file.hpp.
#include "io/durable_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <system_error>

namespace stampede::io {
namespace {

std::string errno_text(int e) { return std::generic_category().message(e); }

[[noreturn]] void fail_errno(const std::string& what) {
  throw FileError(what + ": " + errno_text(errno));
}

}  // namespace

DurableFile DurableFile::open(const std::string& path, Mode mode) {
  const int flags = (mode == Mode::kRead ? O_RDONLY : O_RDWR) | O_CLOEXEC;
  const int fd = ::open(path.c_str(), flags);
  if (fd < 0) fail_errno("cannot open '" + path + "'");
  return DurableFile(fd, path);
}

DurableFile DurableFile::create(const std::string& path, std::string_view kind) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) {
    fail_errno("cannot create " + (kind.empty() ? std::string() : std::string(kind) + " ") + "'" +
               path + "'");
  }
  return DurableFile(fd, path);
}

DurableFile::DurableFile(DurableFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)) {}

DurableFile& DurableFile::operator=(DurableFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
  }
  return *this;
}

DurableFile::~DurableFile() {
  if (fd_ >= 0) ::close(fd_);
}

void DurableFile::write_all(std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      fail_errno("cannot write '" + path_ + "'");
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

void DurableFile::sync() {
  if (::fsync(fd_) != 0) fail_errno("cannot sync '" + path_ + "' to disk");
}

long long DurableFile::size() {
  struct stat st {};
  if (::fstat(fd_, &st) != 0) fail_errno("cannot stat '" + path_ + "'");
  return static_cast<long long>(st.st_size);
}

void DurableFile::read_at(long long offset, std::span<char> out) {
  const ssize_t n = ::pread(fd_, out.data(), out.size(), static_cast<off_t>(offset));
  if (n < 0) fail_errno("cannot read '" + path_ + "'");
  if (static_cast<std::size_t>(n) != out.size()) {
    throw FileError("cannot read '" + path_ + "': it ends before byte " +
                    std::to_string(offset + static_cast<long long>(out.size())));
  }
}

void DurableFile::truncate(long long size) {
  if (::ftruncate(fd_, static_cast<off_t>(size)) != 0) {
    fail_errno("cannot truncate '" + path_ + "'");
  }
}

void DurableFile::seek_to_end() {
  if (::lseek(fd_, 0, SEEK_END) < 0) fail_errno("cannot seek in '" + path_ + "'");
}

void DurableFile::close() {
  if (fd_ < 0) return;
  const int rc = ::close(std::exchange(fd_, -1));
  if (rc != 0) fail_errno("cannot close '" + path_ + "'");
}

std::string directory_of(const std::string& path) {
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return dir.empty() ? "." : dir;
}

void sync_directory_of(const std::string& path) {
  const std::string dir = directory_of(path);
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) fail_errno("cannot open directory '" + dir + "'");
  const int rc = ::fsync(fd);
  const int e = errno;
  ::close(fd);
  if (rc != 0 && e != EINVAL) throw FileError("cannot sync directory '" + dir + "': " + errno_text(e));
}

void remove_if_present(const std::string& path) {
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) fail_errno("cannot remove '" + path + "'");
}

bool file_exists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

std::string temporary_path(const std::string& path) { return path + ".tmp"; }

void rename_file(const std::string& from, const std::string& to) {
  if (::rename(from.c_str(), to.c_str()) != 0) {
    fail_errno("cannot rename '" + from + "' to '" + to + "'");
  }
}

void replace_durably(const std::string& path, std::string_view bytes) {
  const std::string tmp = temporary_path(path);
  DurableFile f = DurableFile::create(tmp);
  f.write_all(bytes);
  f.sync();
  f.close();
  rename_file(tmp, path);
  sync_directory_of(path);
}

}  // namespace stampede::io
