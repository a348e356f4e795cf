// Progress lines of the long commands (fit, calibrate build, ring) on stderr: redrawn in place on a
// terminal; elsewhere (a log file, a pipe, a batch job) one whole line at most every 10 s, so a
// run that takes minutes is visibly alive without flooding the log.
#pragma once

#include <cstdio>
#include <string>

namespace stampede::tools {

class ProgressPrinter {
 public:
  // Seconds between lines when not on a terminal.
  static constexpr double kLogInterval = 10.0;

  ProgressPrinter(std::FILE* out, bool terminal) : out_(out), terminal_(terminal) {}

  // `line` (without a newline) describes the state `seconds` after the start. The caller throttles
  // terminal redraws itself; lines for a log are dropped until kLogInterval has passed.
  void update(double seconds, const std::string& line) {
    if (terminal_) {
      std::fprintf(out_, "\r%s", line.c_str());
      drawn_ = true;
    } else if (seconds - last_logged_ >= kLogInterval) {
      std::fprintf(out_, "%s\n", line.c_str());
      last_logged_ = seconds;
    }
    std::fflush(out_);
  }

  // Ends a line redrawn in place, before the summary is printed.
  void finish() {
    if (drawn_) std::fputc('\n', out_);
    drawn_ = false;
  }

 private:
  std::FILE* out_;
  bool terminal_;
  bool drawn_ = false;
  double last_logged_ = 0;  // the first log line comes kLogInterval after the start
};

}  // namespace stampede::tools
