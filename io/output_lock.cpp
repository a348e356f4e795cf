// The per-output run lock; see output_lock.hpp.
#include "io/output_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <system_error>
#include <utility>

#include "engine/common/quoted_value.hpp"
#include "io/durable_file.hpp"

namespace stampede::io {
namespace {

std::string q(const std::string& path) { return quoted_value(path, kQuotedPathMaxBytes); }

[[noreturn]] void fail(const std::string& what, int e) {
  throw FileError(what + ": " + std::generic_category().message(e));
}

// What the holder wrote, or a note when it has not written it yet (it writes right after locking).
std::string holder_of(int fd) {
  char buf[256 + HOST_NAME_MAX];
  const ssize_t n = ::pread(fd, buf, sizeof buf, 0);
  std::string text = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : "";
  while (!text.empty() && text.back() == '\n') text.pop_back();
  return text.empty() ? "another process (it has not recorded its pid yet)" : quoted_value(text);
}

}  // namespace

std::string OutputLock::path_for(const std::string& output) { return output + ".lock"; }

OutputLock OutputLock::acquire(const std::string& output) {
  const std::string path = path_for(output);
  for (;;) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) fail("cannot create the lock file " + q(path), errno);
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      if (e == EWOULDBLOCK) {
        const std::string holder = holder_of(fd);
        ::close(fd);
        throw FileError(q(output) + " is in use by another run: " + q(path) + " is held by " + holder +
                        "; wait for it to finish (a lock whose holder has died is taken over)");
      }
      ::close(fd);
      fail("cannot lock " + q(path), e);
    }
    // The file we locked must still be the one the path names (see the header).
    struct stat locked {}, named {};
    if (::fstat(fd, &locked) != 0 || ::stat(path.c_str(), &named) != 0 || locked.st_dev != named.st_dev ||
        locked.st_ino != named.st_ino) {
      ::close(fd);
      continue;
    }
    char host[HOST_NAME_MAX + 1] = {};
    if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
    const std::string record = "pid " + std::to_string(::getpid()) + " on host " + (host[0] ? host : "?") + "\n";
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, record.data(), record.size(), 0) != static_cast<ssize_t>(record.size())) {
      const int e = errno;
      ::unlink(path.c_str());
      ::close(fd);
      fail("cannot write the lock file " + q(path), e);
    }
    return OutputLock(fd, path);
  }
}

OutputLock::OutputLock(OutputLock&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)) {}

OutputLock& OutputLock::operator=(OutputLock&& other) noexcept {
  if (this != &other) {
    release();
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
  }
  return *this;
}

OutputLock::~OutputLock() { release(); }

void OutputLock::release() noexcept {
  if (fd_ < 0) return;
  ::unlink(path_.c_str());  // while locked: see the header
  ::close(std::exchange(fd_, -1));
}

}  // namespace stampede::io
