// Runs the real `stampede` binary (STAMPEDE_BINARY) in a child process for end-to-end tests.
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace stampede::testing {

struct RunResult {
  int exit_code = -1;
  long max_rss_kb = 0;
  std::string err;
};

// file_size_limit >= 0: the child's RLIMIT_FSIZE (`ulimit -f`, bytes), set after its stderr and
// stdout files are opened.
pid_t spawn(const std::vector<std::string>& args, const std::string& err_path, const std::string& command = "fit",
            const std::string& out_path = "/dev/null", long long file_size_limit = -1) {
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* e = std::fopen(err_path.c_str(), "w");
    if (e) dup2(fileno(e), 2);
    FILE* o = std::fopen(out_path.c_str(), "w");
    if (o) dup2(fileno(o), 1);
    if (file_size_limit >= 0) {
      rlimit limit{};
      getrlimit(RLIMIT_FSIZE, &limit);
      limit.rlim_cur = static_cast<rlim_t>(file_size_limit);
      if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(126);
    }
    std::vector<char*> argv;
    std::string bin = STAMPEDE_BINARY;
    argv.push_back(bin.data());
    std::string sub = command;
    argv.push_back(sub.data());
    std::vector<std::string> copy = args;
    for (auto& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  return pid;
}

RunResult finish(pid_t pid, const std::string& err_path) {
  RunResult r;
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.max_rss_kb = usage.ru_maxrss;
  std::ifstream in(err_path);
  std::stringstream ss;
  ss << in.rdbuf();
  r.err = ss.str();
  return r;
}

}  // namespace stampede::testing
