// What a worker elsewhere (the MPI driver's other ranks) needs to measure a run's batches as the
// run itself does: the run's measurer described as key = value lines (a fit's effective
// configuration with its tiles and bands), and the measurers made back from them. Writer and reader
// side by side, so that they cannot drift. (A metadetection's ranks measure shards of their own:
// tools/mpi/mpi_main.cpp, docs/run_harness.md.)
#pragma once

#include <string>
#include <vector>

#include "app/run_config.hpp"
#include "app/run_harness.hpp"

namespace stampede::app {

// A fit: `config` as the run resolved it (stamp size, PSF, renderer); survey input's tiles and
// band names (none for stamps).
WorkerRecipe fit_worker_recipe(const RunConfig& config, const std::vector<std::string>& meds,
                               const std::vector<std::string>& bands);
// The run's per-thread measurers from its recipe. Throws io::ConfigError for a recipe of no known
// kind.
MeasurerFactory worker_measurers(const WorkerRecipe& recipe);

}  // namespace stampede::app
