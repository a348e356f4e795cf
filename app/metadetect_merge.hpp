// Joining the tables of a job array's metadetection shards (`stampede metadetect --shard i/N`, or
// the ranks of `stampede-mpi metadetect`) into the table one process writes: the rows in cell
// order, the header the whole run's. Refuses, naming the file: a table that is not a shard, a
// missing or repeated shard, shards of another run (any header key but SHARD and NCELLSW
// differing: options, inputs and their digests), and an unfinished shard (fewer cells than its
// range).
#pragma once
#include <string>
#include <vector>

namespace stampede::app {

struct MetadetectMergeOptions {
  std::vector<std::string> shards;  // any order
  std::string output;
  bool overwrite = false;
};

struct MetadetectMergeSummary {
  int shards = 0;
  long long cells = 0, rows = 0;
};

// Whether `path` holds a METADETECT table (so `stampede merge` knows which merge it is).
bool is_metadetect_table(const std::string& path);

// Throws io::CatalogError (naming the shard), io::FitsError, io::FileError.
MetadetectMergeSummary merge_metadetect_shards(const MetadetectMergeOptions& options);

}  // namespace stampede::app
