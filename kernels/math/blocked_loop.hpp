// A rows x cols loop taken in square blocks: where one side of a copy is read or written with a
// stride (a transpose, a rotation), a block's cache lines on both sides stay in L1 while it is done.
#pragma once

#include <algorithm>

namespace stampede::kernels {

// f(r, c) for every r < rows, c < cols, block by block (rows then columns within a block).
template <int Block = 16, class F>
inline void for_each_blocked(int rows, int cols, F f) {
  for (int r0 = 0; r0 < rows; r0 += Block)
    for (int c0 = 0; c0 < cols; c0 += Block) {
      const int r1 = std::min(rows, r0 + Block), c1 = std::min(cols, c0 + Block);
      for (int r = r0; r < r1; ++r)
        for (int c = c0; c < c1; ++c) f(r, c);
    }
}

}  // namespace stampede::kernels
