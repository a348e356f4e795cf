// The checks every command makes on its outputs before any work: an output is not a directory, is
// not one of the run's inputs (the same file by device and inode, so another name, a link or
// CFITSIO's "in.fits[1]" syntax is seen through), nor are the files the run writes beside it (its
// partial, checkpoint and lock), two outputs are not one file, and an existing output is replaced
// only when the user said so (--overwrite). Each failure throws FileError naming the option and
// the files.
#pragma once

#include <span>
#include <string>
#include <vector>

namespace stampede::io {

// A file the run reads: how the user named it (e.g. "input", "--catalog", "psf_image") and its
// path on disk.
struct RunInput {
  std::string role;
  std::string path;
};

// A file the run writes: the option that named it ("-o", "--text"), its path, and the files the
// run derives from it and writes too (OUT.partial, OUT.checkpoint, OUT.lock, ...).
struct RunOutput {
  std::string option;
  std::string path;
  std::vector<std::string> companions;
};

// Whether a and b exist and are the same file (device and inode).
bool same_file(const std::string& a, const std::string& b);

// Throws "'PATH' exists (use --overwrite to replace it)" when `path` exists and !overwrite.
void refuse_to_replace(const std::string& path, bool overwrite);

// All of the checks above; with replace_existing, an existing output is not refused (it is replaced
// at the end of the run, or belongs to the run being resumed).
void check_outputs(std::span<const RunOutput> outputs, std::span<const RunInput> inputs, bool replace_existing);

}  // namespace stampede::io
