// The --json files of `stampede metrics` (plain, metacal and --metadetect): a path as a JSON
// string, the checks made on the file before any work, and its write.
#pragma once

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "engine/common/quoted_value.hpp"
#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "io/output_check.hpp"

namespace stampede::tools {

// A path as a JSON string: quotes, backslashes and control characters escaped.
inline std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

// --json names the file to write: not a directory, nor one of the files the command reads, given
// as (option, path) (it would be truncated: another name, a link or "t.fits[1]" is seen through by
// device and inode). Throws std::invalid_argument naming both.
inline void check_json_output(const std::string& json, const std::vector<std::pair<std::string, std::string>>& inputs) {
  if (std::filesystem::is_directory(json))
    throw std::invalid_argument("--json " + quoted_value(json, kQuotedPathMaxBytes) + " is a directory; name the file to write");
  for (const auto& [option, in] : inputs)
    if (!in.empty() && (json == in || io::same_file(json, io::fits_root_name(in))))
      throw std::invalid_argument("--json " + quoted_value(json, kQuotedPathMaxBytes) + " is the " + option + " " +
                                  quoted_value(in, kQuotedPathMaxBytes) + ": writing it would destroy it");
}

// The JSON replaces a regular file whole (written beside it, then renamed), so a failed write
// leaves the previous file; a device or pipe (/dev/stdout) is written to directly.
inline void write_json(const std::string& json, const std::string& text) {
  struct stat st {};
  if (::stat(json.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    std::ofstream out(json, std::ios::binary);
    out << text;
    out.flush();
    if (!out) throw std::runtime_error("cannot write --json " + quoted_value(json, kQuotedPathMaxBytes));
    return;
  }
  io::replace_durably(json, text);
}

}  // namespace stampede::tools
