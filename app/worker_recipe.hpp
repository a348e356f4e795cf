// What a worker elsewhere (the MPI driver's other ranks) needs to measure a run's batches as the
// run itself does: the run's measurer described as key = value lines (a fit's effective
// configuration with its tiles and bands; a metadetection's option keys with its band roles), and
// the measurers made back from them. Writer and reader side by side, so that they cannot drift.
#pragma once

#include <string>
#include <vector>

#include "app/run_config.hpp"
#include "app/run_harness.hpp"
#include "engine/metadetect/metadetect_options.hpp"

namespace stampede::app {

// A fit: `config` as the run resolved it (stamp size, PSF, renderer); survey input's tiles and
// band names (none for stamps).
WorkerRecipe fit_worker_recipe(const RunConfig& config, const std::vector<std::string>& meds,
                               const std::vector<std::string>& bands);
// A metadetection: its options (band roles as masks), SEP's pixel stack for its largest cell, and
// its cells per batch.
WorkerRecipe metadetect_worker_recipe(const MetadetectOptions& options, long long pixel_stack, int cells_per_batch);

// A metadetection's options (and SEP's pixel stack) read back from its recipe. Throws
// io::ConfigError for a line it does not read or options that are not valid.
MetadetectOptions metadetect_recipe_options(const WorkerRecipe& recipe, long long* pixel_stack);

// The run's per-thread measurers from its recipe (for a metadetection, SEP's pixel stack is set
// first: call before the measurers' threads start). Throws io::ConfigError for a recipe of no
// known kind or with a line its kind does not read.
MeasurerFactory worker_measurers(const WorkerRecipe& recipe);

}  // namespace stampede::app
