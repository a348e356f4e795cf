// Writes a simulated GREAT08-like set in the file layout of shared/data/galsim-great08-mini, so
// `stampede fit`, `stampede metrics` and any GalSim-era tool read our simulations and GalSim's alike:
//   DIR/set_K.fits    float32 grid image (no shear in its header), STAMPSZ GRIDNX GRIDNY NOISESIG,
//                     the PSF keys PSFFWHM PSFBETA PSFE1 PSFE2 PSFTRUNC (Moffat) or PSFTYPE PSFLOD
//   DIR/truth_K.fits  primary header with SHEAR1 SHEAR2 and the run's settings; HDU TRUTH, a row per object
//   DIR/psf_K.fits    the pixel-integrated PSF (stamp^2, float32) and HDU PSF_NOPIX_OS (5x, no pixel)
#pragma once

#include <string>

#include "engine/sim/great08_sim.hpp"

namespace stampede::io {

// Throws FitsError naming the file on any failure; existing files are replaced only with overwrite.
void write_great08_set(const std::string& directory, const Great08Simulator& simulator, const SimSet& set,
                       const std::string& command_line, bool overwrite);

// Oversampling of the PSF_NOPIX_OS image (as in the GalSim sets).
constexpr int kPsfOversampling = 5;

}  // namespace stampede::io
