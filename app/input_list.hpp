// Many inputs in one run (`stampede fit --input-list LIST -o DIR`, and `stampede-mpi` ranks taking
// whole files): the list file, and the output each input gets.
#pragma once

#include <string>
#include <vector>

namespace stampede::app {

struct ListedInput {
  std::string input;   // as written in the list
  std::string output;  // DIR/<input's file name without .fits, .fits.gz, .fit, .fz>_fit.fits
};

// Reads LIST: one input path per line; blank lines and '#' comments skipped, surrounding blanks
// trimmed. Throws io::ConfigError naming the list (and line): unreadable, empty, or two inputs
// whose outputs would be the same file.
std::vector<ListedInput> read_input_list(const std::string& list_path, const std::string& output_dir);

}  // namespace stampede::app
