// A metadetection run (`stampede metadetect`, Python `stampede.metadetect_files`): image files cut
// into cells (engine/metadetect/cell_layout), each cell measured by a CellMeasurer on the pipeline's
// parallel stage, the rows written in cell order by a MetadetectWriter. The pipeline's batch is a
// few cells; each cell yields a variable number of rows (the batch's extension carries them).
// Rows depend only on the cell (its fixnoise is keyed by its number in the run): the same for any
// thread count.
#pragma once
#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include "engine/metadetect/metadetect_options.hpp"

namespace stampede::app {

struct MetadetectRunOptions {
  std::vector<std::string> inputs;  // image files (io/cell_image_reader)
  std::string output;
  MetadetectOptions metadetect;
  int threads = 0;     // 0: all cores
  int cells_per_batch = 2;
  bool resume = false;
  bool overwrite = false;
  const std::atomic<bool>* stop = nullptr;
};

struct MetadetectProgress {
  long long cells_done = 0, cells_total = 0;
  double seconds = 0;
};

struct MetadetectRunSummary {
  long long cells = 0, cells_failed = 0, rows = 0;
  long long cells_resumed = 0;  // committed by an earlier run
  int threads = 0;
  double seconds = 0;
  bool stopped = false;
  std::vector<std::string> problems;  // "FILE cell K: why" for each failed cell (first 100)
};

// Throws stampede::Error subclasses (io::FitsError, io::CatalogError, ConfigError) naming the file,
// HDU, key or option.
MetadetectRunSummary run_metadetect(const MetadetectRunOptions& options,
                                    const std::function<void(const MetadetectProgress&)>& progress = {});

}  // namespace stampede::app
