// Cutting an image into metadetection cells; see cell_layout.hpp.
#include "engine/metadetect/cell_layout.hpp"

#include <algorithm>

namespace stampede {
namespace {

struct AxisCell {
  long origin;
  long keep_lo, keep_hi;  // image pixels
};

std::vector<AxisCell> axis_cells(long length, int size, int buffer) {
  const long inner = size - 2L * buffer, lo = buffer, hi = length - buffer;
  std::vector<AxisCell> out;
  for (long start = lo; start < hi; start += inner) {
    const long end = std::min(start + inner, hi);
    out.push_back({std::min(start - buffer, length - size), start, end});
  }
  return out;
}

}  // namespace

std::vector<CellPlacement> cell_layout(long width, long height, int size, int buffer, std::string* error) {
  if (size <= 2 * buffer) {
    *error = "a cell of " + std::to_string(size) + " pixels has no inner region with a buffer of " +
             std::to_string(buffer) + " (cell_size must exceed twice cell_buffer)";
    return {};
  }
  if (width < size || height < size) {
    *error = "the image is " + std::to_string(width) + " x " + std::to_string(height) +
             " pixels, smaller than one cell (cell_size " + std::to_string(size) + ")";
    return {};
  }
  std::vector<CellPlacement> out;
  for (const AxisCell& cy : axis_cells(height, size, buffer))
    for (const AxisCell& cx : axis_cells(width, size, buffer)) {
      CellPlacement c;
      c.x0 = static_cast<int>(cx.origin), c.y0 = static_cast<int>(cy.origin);
      // Barycentres are continuous: pixel p covers [p - 0.5, p + 0.5).
      c.keep_x0 = cx.keep_lo - cx.origin - 0.5, c.keep_x1 = cx.keep_hi - cx.origin - 0.5;
      c.keep_y0 = cy.keep_lo - cy.origin - 0.5, c.keep_y1 = cy.keep_hi - cy.origin - 0.5;
      out.push_back(c);
    }
  return out;
}

PsfexPosition cell_psfex_position(const CellPlacement& place, int size) {
  const double centre = 0.5 * (size - 1);
  return {place.x0 + centre + 1, place.y0 + centre + 1};
}

}  // namespace stampede
