// Joining the tables of a job array's shards (`stampede fit --shard i/N`, one job each) into the
// table one process would have written: every column but time_us equal, rows in input order.
// Refuses, naming the shard file: a table that is not a shard, a missing or duplicated shard,
// shards of different runs (another input, configuration or shard count), and a shard whose row
// count is not its range's (an unfinished or cut table). Memory is a fixed chunk of rows, whatever
// the table's size; the output is written as `stampede fit` writes its own (a partial renamed when
// complete), checked and locked first.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace stampede::app {

struct ShardMergeOptions {
  std::vector<std::string> shards;  // the shards' tables, in any order
  std::string output;               // the joined table
  bool overwrite = false;           // replace an existing output
  // After each chunk: rows written so far, and in all.
  std::function<void(long long rows_done, long long rows_total)> on_progress;
};

struct ShardMergeSummary {
  int shards = 0;
  long long rows = 0;
  double seconds = 0;
};

// Throws io::CatalogError (a shard problem, naming the file), io::FitsError (an unreadable table)
// or io::FileError / io::CatalogError (the output).
ShardMergeSummary merge_shards(const ShardMergeOptions& options);

}  // namespace stampede::app
