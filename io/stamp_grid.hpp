// Reads a GREAT08-layout stamp grid (an image of nx x ny square stamps) one row of stamps at a
// time, so memory stays at one strip whatever the image size.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "io/fits_file.hpp"

namespace stampede::io {

class StampGridReader {
 public:
  // stamp_size <= 0: take it from the header key STAMPSZ. Throws FitsError (naming file, HDU, key)
  // when the size is missing or does not divide the image.
  StampGridReader(const std::string& path, int stamp_size = 0);

  int stamp_size() const { return stamp_; }
  int grid_nx() const { return nx_; }
  int grid_ny() const { return ny_; }
  FitsFile& file() { return file_; }

  // Stamps of grid row iy, ix = 0..nx-1, each stamp_size^2 row-major: out[ix * stamp^2 + k].
  void read_stamp_row(int iy, std::span<double> out);

 private:
  FitsFile file_;
  int stamp_ = 0, nx_ = 0, ny_ = 0;
  std::vector<double> strip_;
};

}  // namespace stampede::io
