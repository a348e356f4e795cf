// Runs a metadetection as `shards` job-array shards (`--shard i/N`), for the merge's tests.
#pragma once

#include <string>
#include <vector>

#include "app/metadetect_run.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::testing {

// Shard i of `shards` of the run `o` into DIR/<prefix>i.fits; their paths in shard order.
inline std::vector<std::string> run_metadetect_shards(app::MetadetectRunOptions o, int shards, const ScratchDir& dir,
                                                      const std::string& prefix) {
  std::vector<std::string> paths;
  for (int i = 0; i < shards; ++i) {
    o.shard = i, o.shards = shards;
    o.output = dir.path(prefix + std::to_string(i) + ".fits");
    app::run_metadetect(o);
    paths.push_back(o.output);
  }
  return paths;
}

}  // namespace stampede::testing
