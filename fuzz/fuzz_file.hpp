// Files for the fuzz targets: the fuzz input as a file the readers open by path (an anonymous
// memfd, so nothing is left on disk when a target crashes), and fixed FITS companions built once.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <span>
#include <string>
#include <vector>

#include "io/fits_file.hpp"

namespace stampede::fuzz {

class FuzzFile {
 public:
  explicit FuzzFile(std::span<const unsigned char> bytes) : fd_(memfd_create("stampede-fuzz", 0)) {
    if (fd_ < 0) std::abort();
    for (std::size_t done = 0; done < bytes.size();) {
      const ssize_t n = write(fd_, bytes.data() + done, bytes.size() - done);
      if (n <= 0) std::abort();
      done += static_cast<std::size_t>(n);
    }
  }
  ~FuzzFile() { close(fd_); }
  FuzzFile(const FuzzFile&) = delete;
  FuzzFile& operator=(const FuzzFile&) = delete;

  // A path any open() accepts; it holds no FITS extended syntax, so CFITSIO opens it as is.
  std::string path() const { return "/proc/self/fd/" + std::to_string(fd_); }

 private:
  int fd_;
};

// The bytes of a FITS file written by `write(FitsFile&)` through the project's own writer.
template <class Write>
std::vector<unsigned char> fits_bytes(Write write) {
  const std::filesystem::path dir = std::filesystem::exists("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
  const std::string path = (dir / ("stampede-fuzz-" + std::to_string(getpid()) + ".fits")).string();
  {
    io::FitsFile f = io::FitsFile::create(path, true);
    write(f);
    f.close();
  }
  std::ifstream in(path, std::ios::binary);
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(path);
  return bytes;
}

}  // namespace stampede::fuzz
