// FFT-friendly transform sizes; see fft_size.hpp.
#include "kernels/math/fft_size.hpp"

#include <algorithm>

namespace stampede::kernels {

int fft_friendly_size(int n) {
  for (int m = std::max(n, 1);; ++m) {
    int r = m;
    for (int f : {2, 3, 5, 7})
      while (r % f == 0) r /= f;
    if (r == 1) return m;
  }
}

}  // namespace stampede::kernels
