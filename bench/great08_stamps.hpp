// The first stamps of the noise-free GalSim GREAT08-mini set 0 (fiducial GREAT08-like galaxies,
// 39 px), read once for the benchmarks that fit real stamps.
#pragma once

#include <string>
#include <vector>

#include "io/stamp_grid.hpp"

namespace stampede::bench {

struct Great08Stamps {
  std::vector<double> pixels;  // count stamps, each size x size, row-major
  int size = 0;
};

inline Great08Stamps read_great08_stamps(int count) {
  io::StampGridReader grid(std::string(STAMPEDE_DATA_DIR) + "/galsim-great08-mini/nf/set_0.fits");
  Great08Stamps s;
  s.size = grid.stamp_size();
  const std::size_t npix = static_cast<std::size_t>(s.size) * s.size;
  std::vector<double> row(grid.grid_nx() * npix);
  for (int iy = 0; static_cast<int>(s.pixels.size() / npix) < count; ++iy) {
    grid.read_stamp_row(iy, row);
    s.pixels.insert(s.pixels.end(), row.begin(), row.end());
  }
  s.pixels.resize(static_cast<std::size_t>(count) * npix);
  return s;
}

}  // namespace stampede::bench
