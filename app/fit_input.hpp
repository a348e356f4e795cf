// The inputs of a fit run (app/fit_run): a grid of stamps, an image with a catalogue of objects to
// cut from it, or MEDS tiles (one per band). Opening one checks the run's outputs against every
// file it reads and locks them (app/run_harness), reads what the input's header says of itself,
// sets up the PSF and the per-thread fitters, and says what the table records of the input.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "app/fit_run.hpp"
#include "app/run_fingerprint.hpp"
#include "app/run_harness.hpp"
#include "app/stamp_fitter_recipe.hpp"
#include "app/survey_object_fit.hpp"
#include "io/catalog_writer.hpp"
#include "io/output_lock.hpp"

namespace stampede::app {

// What an input gives the run path: its source (and shard), the configuration as the input made it,
// the fit stage's factory, and what the table records of the input.
struct FitInput {
  app::RunConfig config;
  std::unique_ptr<StampSource> whole;  // the input
  std::vector<io::OutputLock> locks;   // held until the writer is done
  std::function<std::unique_ptr<BatchFitter>()> make_fitter;
  std::vector<std::string> meds, bands;  // survey input: for the workers of a distributed run
  FftPlanning planning = FftPlanning::kEstimate;
  std::shared_ptr<const StampFitterRecipe> recipe;  // stamp input: its fitters' recipe (and PSF, for save_images)
  // The table: its positions' columns; keys before the fingerprint; the files fingerprinted and
  // a text the fingerprint adds; keys after it; and a last step given the files' digests.
  io::PositionColumns positions = io::PositionColumns::kGrid;
  std::vector<std::pair<std::string, std::string>> header_before, header_after;
  std::map<std::string, io::HeaderValueType> header_types;
  std::vector<FingerprintFile> files;
  std::string fingerprint_extra;
  std::function<void(const std::vector<std::string>& digests, io::CatalogWriterOptions*)> finish_header;
};

// A grid of stamps, or an image with a catalogue of objects. Throws io::ConfigError and the io/
// errors naming what is wrong, before any fit.
FitInput open_stamp_input(const FitRunOptions& run, const TableRun& table);
// MEDS tiles, one per band: each object's cutouts read in the serial stage (io/meds_object_source).
FitInput open_survey_input(const FitRunOptions& run, const TableRun& table);

// The same tile given as two bands (another spelling of its path, a link, a copy) would count its
// pixels twice: refused (io::ConfigError) where two of `digests` (the tiles', in order) are equal.
void refuse_repeated_tiles(const FitInput& in, const std::vector<std::string>& digests);

// OUT.fits -> OUT.images.fits (any other name: NAME.images.fits): where save_images writes.
std::string images_path_for(std::string output);

// The per-thread fitters' options of a survey run.
MedsFitOptions survey_fit_options(const RunConfig& config);

}  // namespace stampede::app
