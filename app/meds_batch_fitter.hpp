// The pipeline's per-thread fitting state for a MEDS tile (`stampede fit --meds`): its own handle
// on the tile (CFITSIO handles are not shared between threads), its MedsObjectFitter (renderers per
// box size, PSFEx models per source image, loaded on first use), and the mapping of each object's
// result onto its output row. A batch's records carry object_data row numbers (IndexSource); a
// row's fit depends on that object alone, so any thread count gives the same table.
#pragma once

#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "app/meds_object_fit.hpp"
#include "app/multi_band_object_fit.hpp"
#include "engine/pipeline/pipeline.hpp"

namespace stampede::app {

class MedsBatchFitter final : public BatchFitter {
 public:
  // Opens `path` (a FitsError names it if it cannot be). `on_problem` (may be empty) receives each
  // object's first problem text with its row, from the fitting thread.
  MedsBatchFitter(const std::string& path, const MedsFitOptions& options,
                  std::function<void(long long row, const std::string& problem)> on_problem = {});
  // A multi-band run: one tile per band, in the order of `bands` (MultiBandObjectFitter); every
  // row carries its band columns, one band included.
  MedsBatchFitter(const std::vector<std::string>& paths, const std::vector<std::string>& bands,
                  const MedsFitOptions& options,
                  std::function<void(long long row, const std::string& problem)> on_problem = {});
  ~MedsBatchFitter() override;
  void fit(StampBatch& batch) override;

 private:
  std::deque<io::MedsFile> tiles_;  // a deque: the fitters hold references into it
  std::unique_ptr<MedsObjectFitter> fitter_;            // one tile, no bands
  std::unique_ptr<MultiBandObjectFitter> band_fitter_;  // bands
  std::function<void(long long, const std::string&)> on_problem_;
};

// The output row of one object's result (survey columns; e, radius and fluxes in sky units; a
// multi-band result's bands in record.survey.bands).
void fill_survey_record(const MedsObjectResult& result, ObjectRecord* record);

}  // namespace stampede::app
