// One object of a multi-band run (`stampede fit --meds g.fits --meds r.fits ... --bands g,r,...`,
// issue 32): the same object_data row of every band's tile, its cutouts collected per band by that
// tile's MedsObjectFitter (masks, PSFs, frames, zero points as for one tile) and fitted jointly by
// MultiBandFitter: one shape, a bulge and a disc amplitude per band; bord chooses the pure bulge or
// the pure disc for all bands at once. A band whose cutouts are all unusable is left out (its
// n_epochs 0, its problem in the row's, prefixed with the band); the others are fitted. Metacal
// (MultiEpochMetacalFitter) shares one Gamma over all bands' cutouts and fits each image set
// jointly: R is the combined response. One band is its tile's own fit (MedsObjectFitter::fit,
// metacal included), so its rows are a single-tile run's.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "app/meds_object_fit.hpp"
#include "engine/fit/multi_band_fitter.hpp"

namespace stampede::app {

// Throws io::ConfigError unless every tile lists the objects of the first in the same order: the
// message names the tile, and the row and ids that differ first (or the object counts).
void check_band_tiles(std::span<io::MedsFile* const> tiles);

class MultiBandObjectFitter {
 public:
  // One tile per band, in the order of `bands` (each must outlive it). Throws std::invalid_argument
  // for options a tile cannot serve (as MedsObjectFitter).
  MultiBandObjectFitter(std::span<io::MedsFile* const> tiles, const std::vector<std::string>& bands,
                        const MedsFitOptions& options);
  ~MultiBandObjectFitter();
  // Row `row` of every tile; the result's bands are in the run's order.
  MedsObjectResult fit(long long row);
  // The PSFEx files of every tile, without repeats.
  std::vector<std::string> psfex_files() const;

 private:
  std::vector<std::string> bands_;
  std::vector<std::unique_ptr<MedsObjectFitter>> tiles_;
  MedsModel model_;
  MultiBandFitter fitter_;                        // bd; bord: the pure disc
  std::unique_ptr<MultiBandFitter> bulge_fitter_;  // bord: the pure bulge
  std::unique_ptr<MultiEpochMetacalFitter> metacal_;  // metacal runs of several bands
  std::vector<EpochData> epochs_;                  // the current object's, all bands, reused
  std::vector<MetacalEpoch> metacal_epochs_;
};

}  // namespace stampede::app
