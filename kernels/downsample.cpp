// Block averaging; see downsample.hpp.
#include "kernels/downsample.hpp"

#include <cstddef>

namespace stampede::kernels {

void block_average(const double* in, int in_size, int factor, int offset, int out_size, double* out) {
  const double inv = 1.0 / (factor * factor);
  for (int y = 0; y < out_size; ++y) {
    double* orow = out + static_cast<std::ptrdiff_t>(y) * out_size;
    for (int x = 0; x < out_size; ++x) orow[x] = 0.0;
    for (int b = 0; b < factor; ++b) {
      const double* irow = in + static_cast<std::ptrdiff_t>(offset + y * factor + b) * in_size + offset;
      for (int x = 0; x < out_size; ++x) {
        const double* cell = irow + x * factor;
        double s = 0.0;
        for (int a = 0; a < factor; ++a) s += cell[a];
        orow[x] += s;
      }
    }
    for (int x = 0; x < out_size; ++x) orow[x] *= inv;
  }
}

}  // namespace stampede::kernels
