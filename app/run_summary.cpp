// The fit run's summary reports; see run_summary.hpp.
#include "app/run_summary.hpp"

#include <algorithm>
#include <cstdio>

namespace stampede::app {

namespace {

template <typename... T>
std::string format(const char* fmt, T... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

}  // namespace

double RunSummary::objects_per_second() const { return objects / std::max(pipeline_seconds, 1e-9); }

std::string RunSummary::BriefReport() const {
  std::string out = format("stampede fit: %lld objects (%lld resumed) in %.1f s, %.1f objects/s; status:",
                           objects + resumed, resumed, pipeline_seconds, objects_per_second());
  if (const std::string counts = StatusCounts(); !counts.empty()) out += " " + counts;
  if (interrupted) {
    out += "; interrupted";
    if (!output.empty()) out += ": " + output + ".partial kept, continue with resume";
  } else if (!output.empty()) {
    out += "; wrote " + output;
  }
  return out;
}

std::string RunSummary::StatusCounts() const {
  std::string out;
  for (int s = 0; s < kFitStatusCount; ++s)
    if (by_status[s]) out += format("%s%s=%lld", out.empty() ? "" : " ", ToString(static_cast<FitStatus>(s)), by_status[s]);
  return out;
}

std::string RunSummary::FullReport() const {
  auto path = [](const std::string& p) { return p.empty() ? std::string("-") : p; };
  std::string out = "stampede fit summary\n";
  out += "  input          " + path(input) + "\n";
  out += "  catalogue      " + path(catalog) + "\n";
  out += "  weights        " + path(weight) + "\n";
  out += "  output         " + path(output) + "\n";
  out += "  text output    " + path(text_output) + "\n";
  out += format("  threads        %d\n", threads);
  out += format("  objects        %lld (%lld fitted by this run, %lld resumed) in %lld batches\n", objects + resumed,
                objects, resumed, batches);
  out += "  status (this run)\n";
  for (int s = 0; s < kFitStatusCount; ++s)
    out += format("    %-16s %12lld\n", ToString(static_cast<FitStatus>(s)), by_status[s]);
  out += "  time (s)\n";
  out += format("    setup            %12.3f\n", setup_seconds);
  out += format("    pipeline         %12.3f\n", pipeline_seconds);
  out += format("    finish           %12.3f\n", finish_seconds);
  out += format("    total            %12.3f\n", total_seconds);
  out += format("  rate           %.1f objects/s (pipeline), %.1f objects/s (total)\n", objects_per_second(),
                objects / std::max(total_seconds, 1e-9));
  return out;
}

}  // namespace stampede::app
