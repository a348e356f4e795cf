// Runs a piece of a test in a child process whose file-size limit (RLIMIT_FSIZE, `ulimit -f`) is a
// given number of bytes, so that writes past it fail (EFBIG) as they do on a full disk or under a
// batch system's limit, and hands back the child's message.
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <functional>
#include <string>

namespace stampede::testing {

// `body`'s return value, from a child limited to `limit` bytes a file; "child ..." when the child
// itself went wrong (no fork, a crash, a message not sent).
inline std::string in_child_with_file_size_limit(long long limit, const std::function<std::string()>& body) {
  int fds[2];
  if (::pipe(fds) != 0) return "child: no pipe";
  const pid_t pid = ::fork();
  if (pid < 0) return "child: no fork";
  if (pid == 0) {
    ::close(fds[0]);
    rlimit l{};
    ::getrlimit(RLIMIT_FSIZE, &l);
    l.rlim_cur = static_cast<rlim_t>(limit);
    if (::setrlimit(RLIMIT_FSIZE, &l) != 0) ::_exit(3);
    const std::string message = body();
    const bool sent = ::write(fds[1], message.data(), message.size()) == static_cast<ssize_t>(message.size());
    ::_exit(sent ? 0 : 4);
  }
  ::close(fds[1]);
  std::string message;
  char buf[512];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) message.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return "child status " + std::to_string(status) + ": " + message;
  return message;
}

}  // namespace stampede::testing
