// The input list; see input_list.hpp.
#include "app/input_list.hpp"

#include <filesystem>
#include <fstream>
#include <map>

#include "app/run_config.hpp"
#include "io/text_lines.hpp"

namespace stampede::app {

std::vector<ListedInput> read_input_list(const std::string& list_path, const std::string& output_dir) {
  std::ifstream in(list_path);
  if (!in) throw io::ConfigError("cannot read the input list '" + list_path + "'");
  std::vector<ListedInput> out;
  std::map<std::string, int> line_of_output;
  int line_number = 0;
  std::string line;
  for (io::TextLine read; (read = io::read_text_line(in, &line)) != io::TextLine::kEnd;) {
    ++line_number;
    if (read == io::TextLine::kTooLong)
      throw io::ConfigError(list_path + ":" + std::to_string(line_number) + ": a line longer than " +
                            std::to_string(io::kMaxTextLine) + " bytes: not a list of input paths");
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    const auto first = line.find_first_not_of(" \t\r"), last = line.find_last_not_of(" \t\r");
    if (first == std::string::npos) continue;
    const std::string input = line.substr(first, last - first + 1);
    std::string name = std::filesystem::path(input).filename().string();
    for (const char* ext : {".fits.gz", ".fits.fz", ".fits", ".fit", ".fz"})
      if (name.size() > std::string(ext).size() && name.ends_with(ext)) {
        name.resize(name.size() - std::string(ext).size());
        break;
      }
    const std::string output = (std::filesystem::path(output_dir) / (name + "_fit.fits")).string();
    if (const auto seen = line_of_output.find(output); seen != line_of_output.end())
      throw io::ConfigError(list_path + ":" + std::to_string(line_number) + ": '" + input + "' would write '" + output +
                            "', as line " + std::to_string(seen->second) + " does");
    line_of_output[output] = line_number;
    out.push_back({input, output});
  }
  if (out.empty()) throw io::ConfigError("the input list '" + list_path + "' names no input");
  return out;
}

}  // namespace stampede::app
