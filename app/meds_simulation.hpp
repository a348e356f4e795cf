// A simulated MEDS tile on disk (`stampede sim meds`): DIR/meds.fits (image, weight, seg and bmask
// cutouts; cutout 0 of each object is an empty coadd slot, so the single epochs are cutouts
// 1..epochs as in a survey tile), DIR/psfex/image_K.psf (each source image's PSF as a constant
// PSFEx model at PSF_SAMP = 1), and DIR/truth.fits (SHEAR1 SHEAR2 and a TRUTH row per object,
// `index` = the MEDS id, so `stampede metrics --fit OUT.fits --truth DIR/truth.fits` reads it).
// Objects are drawn in parallel in chunks and written in order: the files are identical for any
// thread count, and memory is one chunk's.
#pragma once

#include <functional>
#include <string>

#include "engine/sim/meds_sim.hpp"

namespace stampede::app {

// The simulation's identity, the SIMID key of its tile's and truth file's primary headers: the
// XXH64 (16 hex digits) of every option but `band`, so a multi-band simulation's tiles and truth
// files share it (they hold the same galaxies). `stampede fit` records a tile's as INSETID, and
// `metrics` and the report refuse the truth of another simulation by it.
std::string meds_simulation_id(const MedsSimOptions& options);

// Object numbers in the seg map: object i is i + 1; its neighbour is objects + i + 1.
void write_meds_simulation(const MedsSimOptions& options, const std::string& dir, bool overwrite,
                           const std::function<void(long long done, long long total)>& progress = {});

}  // namespace stampede::app
