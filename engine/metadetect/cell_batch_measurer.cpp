// A batch's cells measured; see cell_batch_measurer.hpp.
#include "engine/metadetect/cell_batch_measurer.hpp"

#include <span>

#include "engine/metacal/metacal_type.hpp"
#include "engine/metadetect/cell_batch.hpp"

namespace stampede {

void CellBatchMeasurer::fit(StampBatch& batch) {
  CellBatch& data = batch.payload<CellBatch>();
  data.rows.clear();
  data.problems.assign(static_cast<std::size_t>(batch.count), "");
  for (int k = 0; k < batch.count; ++k) {
    const CellBatch::Cell& c = data.cells[static_cast<std::size_t>(k)];
    if (!c.problem.empty()) {  // one flagged row, as the measurer writes for a cell it cannot measure
      MetadetectRow r;
      r.cell = batch.records[k].id;
      r.shear_type = static_cast<int>(MetacalType::kNoshear);
      r.flags = kMetadetectCellFailed;
      data.rows.push_back(r);
      data.problems[static_cast<std::size_t>(k)] = c.problem;
      continue;
    }
    const ArenaObservation& o = batch.observations[c.first_observation];
    const std::size_t npix = static_cast<std::size_t>(o.box_size) * o.box_size;
    auto noise = [&](int b) {
      return c.noise_offset < 0 ? std::span<const double>()
                                : std::span<const double>(data.noise).subspan(c.noise_offset + b * npix, npix);
    };
    bands_.clear();
    for (int b = 0; b < c.bands; ++b) {
      const ArenaObservation& ob = batch.observations[c.first_observation + b];
      bands_.push_back({.image = batch.observations.observation(ob), .noise = noise(b)});
    }
    MetadetectCell cell;
    cell.index = batch.records[k].id;
    cell.bands = bands_;
    cell.origin_x = c.place.x0, cell.origin_y = c.place.y0;
    cell.pixel_scale = c.pixel_scale;
    cell.keep_x0 = c.place.keep_x0, cell.keep_x1 = c.place.keep_x1;
    cell.keep_y0 = c.place.keep_y0, cell.keep_y1 = c.place.keep_y1;
    cell.lens_g1 = c.lens_g1, cell.lens_g2 = c.lens_g2;
    cell.stars = std::span<const StarDisc>(data.stars).subspan(c.first_star, c.stars);
    if (c.mfrac_offset >= 0)
      cell.mfrac = std::span<const double>(data.mfrac).subspan(static_cast<std::size_t>(c.mfrac_offset), npix);
    if (c.bits_offset >= 0) {
      cell.bmask = std::span<const std::int32_t>(data.bits).subspan(static_cast<std::size_t>(c.bits_offset), npix);
      cell.ormask = std::span<const std::int32_t>(data.bits).subspan(static_cast<std::size_t>(c.bits_offset) + npix, npix);
    }
    measurer_.measure(cell, &data.rows, &data.problems[static_cast<std::size_t>(k)]);
  }
}

}  // namespace stampede
