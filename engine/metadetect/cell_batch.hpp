// What a metadetection batch carries beside its observations (StampBatch::payload): the cells the
// source read, a band's NOISE planes, and the rows each cell yields (a variable number) with its
// problem, which the batch's measurer writes and the run's sink reads in cell order.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/metadetect/cell_layout.hpp"
#include "engine/metadetect/metadetect_row.hpp"
#include "engine/metadetect/star_disc.hpp"

namespace stampede {

struct CellBatch {
  struct Cell {
    int file = 0;  // which of the source's inputs (for messages)
    CellPlacement place;
    double pixel_scale = 0;
    double lens_g1 = 0, lens_g2 = 0;  // keep_unlensed: the file's recorded shear
    int first_observation = 0, bands = 1;  // its bands' observations in the arena, in band order
    // Its bands' NOISE planes, consecutive in `noise` from here (none: -1).
    long long noise_offset = -1;
    // The star discs that reach it, consecutive in `stars` from here, in its pixels.
    std::size_t first_star = 0, stars = 0;
    // Its BMASK and ORMASK bits (its bands' OR'ed), consecutive in `bits` from here: bmask, then
    // ormask (none: -1).
    long long bits_offset = -1;
    // Its masked-fraction plane (the bands' mean), in `mfrac` from here (none: -1).
    long long mfrac_offset = -1;
    std::string problem;  // why it cannot be measured (its PSFEx model fails there); "" none
  };
  std::vector<Cell> cells;
  std::vector<double> noise;  // the batch's noise planes (kept between batches)
  std::vector<StarDisc> stars;  // the batch's cells' star discs
  std::vector<std::int32_t> bits;  // the batch's cells' mask bits (kept between batches)
  std::vector<double> mfrac;       // the batch's cells' masked-fraction planes (kept between batches)
  std::size_t noise_used = 0, bits_used = 0, mfrac_used = 0;
  std::vector<MetadetectRow> rows;
  std::vector<std::string> problems;  // per cell, "" none

  // Space for the next cell's `bands` noise planes of npix pixels: their first value's offset.
  std::size_t add_noise(std::size_t npix, int bands) {
    const std::size_t at = noise_used;
    noise_used += npix * static_cast<std::size_t>(bands);
    if (noise.size() < noise_used) noise.resize(noise_used);
    return at;
  }
  // Space for the next cell's masked-fraction plane of npix pixels, zeroed: its offset.
  std::size_t add_mfrac(std::size_t npix) {
    const std::size_t at = mfrac_used;
    mfrac_used += npix;
    if (mfrac.size() < mfrac_used) mfrac.resize(mfrac_used);
    std::fill(mfrac.begin() + static_cast<long>(at), mfrac.begin() + static_cast<long>(mfrac_used), 0.0);
    return at;
  }
  // Space for the next cell's bmask and ormask planes of npix pixels, zeroed: the first's offset.
  std::size_t add_bits(std::size_t npix) {
    const std::size_t at = bits_used;
    bits_used += 2 * npix;
    if (bits.size() < bits_used) bits.resize(bits_used);
    std::fill(bits.begin() + static_cast<long>(at), bits.begin() + static_cast<long>(bits_used), 0);
    return at;
  }
};

}  // namespace stampede
