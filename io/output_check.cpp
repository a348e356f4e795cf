// Output checks before a run; see output_check.hpp.
#include "io/output_check.hpp"

#include <sys/stat.h>

#include "engine/common/quoted_value.hpp"
#include "io/durable_file.hpp"

namespace stampede::io {
namespace {

std::string q(const std::string& path) { return quoted_value(path, kQuotedPathMaxBytes); }

}  // namespace

bool same_file(const std::string& a, const std::string& b) {
  struct stat sa {}, sb {};
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

void refuse_to_replace(const std::string& path, bool overwrite) {
  // Outputs are written beside and renamed over: --overwrite on `-o /dev/null` (run as root) would
  // replace the device node itself. Only regular files are replaced.
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode))
    throw FileError(q(path) + " is not a regular file (a device, FIFO or socket): the run writes a new file and renames "
                    "it into place, which would replace it; name a file to write");
  if (!overwrite && file_exists(path)) throw FileError(q(path) + " exists (use --overwrite to replace it)");
}

void check_outputs(std::span<const RunOutput> outputs, std::span<const RunInput> inputs, bool replace_existing) {
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const RunOutput& out = outputs[k];
    struct stat st {};
    if (::stat(out.path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
      throw FileError(out.option + " " + q(out.path) + " is a directory; name the file to write");
    for (const RunInput& in : inputs) {
      if (same_file(out.path, in.path) || out.path == in.path)
        throw FileError(out.option + " " + q(out.path) + " is the " + in.role + " " + q(in.path) +
                        ": writing it would destroy the " + in.role);
      for (const std::string& c : out.companions)
        if (same_file(c, in.path) || c == in.path)
          throw FileError(out.option + " " + q(out.path) + ": the run writes " + q(c) + ", which is the " + in.role +
                          " " + q(in.path));
    }
    for (std::size_t j = 0; j < k; ++j)
      if (out.path == outputs[j].path || same_file(out.path, outputs[j].path))
        throw FileError(out.option + " " + q(out.path) + " is the same file as " + outputs[j].option + " " +
                        q(outputs[j].path));
    refuse_to_replace(out.path, replace_existing);
  }
}

}  // namespace stampede::io
