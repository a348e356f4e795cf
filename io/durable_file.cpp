// POSIX durability helpers and the atomic-replace protocol; see durable_file.hpp.
#include "io/durable_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
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

// A failed write or sync of `path`: the errno text, and what ran out when something did.
[[noreturn]] void fail_write(const std::string& what, const std::string& path) {
  const int e = errno;
  const std::string reason = space_exhausted_reason(path, e);
  throw FileError(what + ": " + errno_text(e) + (reason.empty() ? "" : " (" + reason + ")"));
}

std::string bytes_text(unsigned long long n) { return std::to_string(n) + " bytes"; }

}  // namespace

std::string space_exhausted_reason(const std::string& path, int error) {
  rlimit limit{};
  const bool limited = ::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY;
  struct stat st {};
  const bool sized = ::stat(path.c_str(), &st) == 0;
  if (error == EFBIG || (error == 0 && limited && sized && static_cast<unsigned long long>(st.st_size) >= limit.rlim_cur)) {
    if (limited)
      return "the file-size limit of this process (RLIMIT_FSIZE, `ulimit -f`) of " + bytes_text(limit.rlim_cur) +
             " is reached" + (sized ? ": the file has " + bytes_text(static_cast<unsigned long long>(st.st_size)) : "");
    return "the file is larger than its filesystem allows";
  }
  const std::string dir = directory_of(path);
  struct statvfs fs {};
  const bool have_fs = ::statvfs(dir.c_str(), &fs) == 0;
  const unsigned long long available =
      have_fs ? static_cast<unsigned long long>(fs.f_bavail) * static_cast<unsigned long long>(fs.f_frsize) : 0;
  if (error == EDQUOT)
    return "the disk quota for '" + dir + "' is exceeded" + (have_fs ? " (the filesystem has " + bytes_text(available) +
                                                                           " available)" : "");
  if (error == ENOSPC || (error == 0 && have_fs && fs.f_bavail == 0))
    return "the filesystem holding '" + dir + "' is full" + (have_fs ? " (" + bytes_text(available) + " available)" : "");
  return "";
}

void ignore_file_size_signal() {
  struct sigaction current {};
  if (::sigaction(SIGXFSZ, nullptr, &current) == 0 && current.sa_handler == SIG_DFL &&
      !(current.sa_flags & SA_SIGINFO)) {
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    ::sigaction(SIGXFSZ, &ignore, nullptr);
  }
}

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
      fail_write("cannot write '" + path_ + "'", path_);
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

void DurableFile::sync() {
  if (::fsync(fd_) != 0) fail_write("cannot sync '" + path_ + "' to disk", path_);
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

std::string unwritten_tail(const std::string& path, long long end) {
  std::error_code error;
  const auto size = std::filesystem::file_size(path, error);
  const long long have = error ? 0 : static_cast<long long>(size);
  if (have >= end) return "";
  const std::string reason = space_exhausted_reason(path, 0);
  return "cannot write '" + path + "': its last " + std::to_string(end - have) + " bytes were not written (" +
         (reason.empty() ? "a short write at close" : reason) + ")";
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
