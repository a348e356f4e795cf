// The pixel-integrated samples of an analytic PSF; see pixelated_psf.hpp.
#include "engine/model/pixelated_psf.hpp"

#include <cstddef>

namespace stampede {

void pixelated_psf(const PsfModel& psf, int n, int sub, std::span<double> out) {
  const double c = 0.5 * (n - 1);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      double sum = 0;
      for (int j = 0; j < sub; ++j)
        for (int i = 0; i < sub; ++i)
          sum += psf.x_value(x - c - 0.5 + (i + 0.5) / sub, y - c - 0.5 + (j + 0.5) / sub);
      out[static_cast<std::size_t>(y) * n + x] = sum / (sub * sub);
    }
}

}  // namespace stampede
