// Metadetection test cells on disk (`stampede sim cells`): for each shear sign (DIR for +g, and
// DIR/minus for -g with --pair: the same galaxies and noise, the scene sheared the other way) and each band (one band:
// the sign's directory itself; several: its subdirectory named by the band):
//   cell_KKKK.fits   the cell image with WEIGHT, BMASK, NOISE and PSF (io/cell_image_writer.hpp)
//   cells_meds.fits  with `tile`: the cells as a cell tile (DES "pizza slices", a MEDS file whose
//                    object_data row k is cell k: cutout 0 the cell image, with weight, seg (zeros),
//                    bmask (zeros), noise and psf cutouts; image_info one row, zero point 30,
//                    position_offset 1; the cells laid out on a notional square tile, adjacent cells
//                    overlapping by their buffers; Jacobian diag(scale), u along columns)
// and the sign's truth.fits (a row per object of every cell; the shear; flux_<band> per band).
// Cells are drawn in parallel in chunks and written in order: every file is identical for any
// thread count, and memory is one chunk's.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "engine/sim/cell_sim.hpp"

namespace stampede::app {

struct CellOutputOptions {
  int cells = 1;
  bool pair = false;                    // also the opposite shear under DIR/minus
  bool tile = false;                    // also cells_meds.fits
  std::vector<std::string> band_names;  // empty: one band; else options.bands names (directories)
  bool overwrite = false;
};

// The files a run writes, in the order it writes them (for the up-front check and for callers).
std::vector<std::string> cell_simulation_outputs(const CellSimOptions& options, const CellOutputOptions& out,
                                                 const std::string& dir);

// Throws std::invalid_argument for bad options (naming the option), io::FileError when an output
// exists and !overwrite (before anything is drawn), FitsError on a failed write.
void write_cell_simulation(const CellSimOptions& options, const CellOutputOptions& out, const std::string& dir,
                           const std::function<void(int done, int total)>& progress = {});

}  // namespace stampede::app
