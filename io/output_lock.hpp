// OutputLock: one run at a time per output. A run holds an exclusive flock(2) on OUT.lock, beside
// its output, from before it touches OUT, OUT.partial or OUT.checkpoint until it ends; the file
// holds "pid P on host H" so that a second run can say who holds it. The kernel drops a flock
// when its holder dies (kill -9 included), so a lock file left by a dead run never blocks the next
// one: the lock is the flock, not the file's existence.
//
// Release removes the file while still holding the lock. A run that opened the file just before
// that removal then locks an unlinked inode; acquire() sees the path no longer names the file it
// locked and starts again, so two runs never both believe they hold the lock.
#pragma once

#include <string>

namespace stampede::io {

class OutputLock {
 public:
  // OUT -> OUT.lock.
  static std::string path_for(const std::string& output);

  // Locks path_for(output) without waiting. Throws FileError
  //   "OUT is in use by another run: 'OUT.lock' is held by pid P on host H"
  // when a live process holds it, or naming the lock file and the system's reason when it cannot
  // be created (e.g. the directory does not exist).
  static OutputLock acquire(const std::string& output);

  OutputLock() = default;  // holds nothing
  OutputLock(OutputLock&& other) noexcept;
  OutputLock& operator=(OutputLock&& other) noexcept;
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;
  ~OutputLock();  // release()

  bool held() const { return fd_ >= 0; }
  // Removes the lock file and unlocks. Idempotent; never throws.
  void release() noexcept;

 private:
  OutputLock(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  int fd_ = -1;
  std::string path_;
};

}  // namespace stampede::io
