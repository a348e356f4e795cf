// How an image is cut into metadetection cells: square cells of `size` pixels that overlap by twice
// their buffer, so that the inner regions (each cell without its buffer) tile the image's interior
// (the image without a buffer-wide border) exactly, and every detection there is kept by exactly
// one cell. The last cell along an axis is moved back to end at the image's edge; its inner region
// starts where the previous one's ended.
#pragma once
#include <string>
#include <vector>

namespace stampede {

struct CellPlacement {
  int x0 = 0, y0 = 0;  // the image pixel of the cell's (0, 0)
  // The cell's part of the interior, in the cell's pixels: a detection whose barycentre lies in
  // [keep_x0, keep_x1) x [keep_y0, keep_y1) is this cell's.
  double keep_x0 = 0, keep_x1 = 0, keep_y0 = 0, keep_y1 = 0;
};

// Row by row (y slow). Empty, with *error, when the image is smaller than a cell in either axis or
// the cell has no inner region (size <= 2 buffer).
std::vector<CellPlacement> cell_layout(long width, long height, int size, int buffer, std::string* error);

// Where a PSFEx model of the image is evaluated for a cell of `size` pixels: the cell's centre,
// origin + (size - 1) / 2 in 0-based pixel centres, as SExtractor's 1-based X_IMAGE, Y_IMAGE (the
// model's polynomial variables), so + 1.
struct PsfexPosition {
  double x_image = 0, y_image = 0;
};
PsfexPosition cell_psfex_position(const CellPlacement& place, int size);

}  // namespace stampede
