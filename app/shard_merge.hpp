// Joining the tables of a job array's shards into the table one process would have written: one
// merge for both kinds of run, told apart by the table's HDU. `stampede fit --shard i/N` (RESULTS:
// every column but time_us equal, rows in input order) and `stampede metadetect --shard i/N` or
// `stampede-mpi metadetect`'s ranks (METADETECT: the whole run's table byte for byte). Refuses,
// naming the shard file: a table that is not a shard, an unfinished run's partial or checkpoint, a
// missing or duplicated shard, shards of different runs (another input, configuration or shard
// count), and a shard that does not hold its whole range (an unfinished or cut table). The rows
// are copied as bytes (io/table_join), a fixed chunk at a time; the output is checked and locked
// first and written through a partial renamed when complete.
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
  bool metadetect = false;  // the shards were metadetect tables
  int shards = 0;
  long long rows = 0;
  long long units = 0;  // objects (fit) or cells (metadetect) the joined table covers
  double seconds = 0;
};

// Throws io::CatalogError (a shard problem, naming the file), io::FitsError (an unreadable table)
// or io::FileError / io::CatalogError (the output).
ShardMergeSummary merge_shards(const ShardMergeOptions& options);

}  // namespace stampede::app
