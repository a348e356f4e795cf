// A fresh directory for one test's files (mkdtemp under the system temp directory, so parallel
// tests and runs never share one), removed with its contents when the test ends.
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace stampede::testing {

class ScratchDir {
 public:
  // prefix: the start of the directory's name, e.g. "stampede_fit_" plus the test's name.
  explicit ScratchDir(const std::string& prefix) {
    std::string name = (std::filesystem::temp_directory_path() / (prefix + "XXXXXX")).string();
    if (!::mkdtemp(name.data())) throw std::runtime_error("cannot create a temporary directory " + name);
    dir_ = name;
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& dir() const { return dir_; }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

 private:
  std::filesystem::path dir_;
};

}  // namespace stampede::testing
