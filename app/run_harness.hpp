// What every run that writes a table shares, fit and metadetect and their MPI modes alike: the
// worker-thread rule, the shard arithmetic and its header keys, the run's identity in its table,
// and the checks of a table output made before any rank or thread starts.
#pragma once

#include <optional>
#include <string>
#include <utility>

#include "io/output_check.hpp"

namespace stampede::app {

// The header keys of a shard's table: "i/N", and (fit) the whole input's object count.
inline constexpr const char* kShardKey = "SHARD";
inline constexpr const char* kShardTotalKey = "SHARDTOT";
// The run's identity in its table's header: RUNFP, 16 hex digits of the hash of its fingerprint
// (inputs' contents, options, program version; a fit shard's range too), which a resume of a
// complete table compares.
inline constexpr const char* kRunFingerprintKey = "RUNFP";

// Worker threads, one rule for every front end (CLI --threads, Python threads=, MPI): 0 = all of
// the machine's cores, else 1 .. kMaxThreads. Throws io::ConfigError naming `what` otherwise.
inline constexpr int kMaxThreads = 4096;
void check_threads(long long threads, const std::string& what);

// "I/N" (the --shard argument and the SHARD key) as {I, N}; nullopt unless it is exactly two
// integers with 0 <= I < N <= 1000000.
std::optional<std::pair<int, int>> parse_shard(const std::string& text);
// Shard `shard` of `shards` of `total` units (objects, cells): [begin, end), the shards' sizes
// differing by at most one. Throws io::ConfigError unless 0 <= shard < shards.
struct ShardRange {
  long long begin = 0, end = 0;
};
ShardRange shard_range(long long total, int shard, int shards);
// "I/N".
std::string shard_text(int shard, int shards);

// A table output named by `option` (-o) with the files written beside it while the run is in
// progress: PATH.partial, PATH.checkpoint (and its temporary), PATH.lock.
io::RunOutput table_output(const std::string& option, const std::string& path);

// Refuses (io::CatalogError naming it) a table that a run has not finished, where `role` (a shard,
// a metrics input) needs a finished one: a run's temporary (NAME.partial, .checkpoint, its .tmp,
// .lock) or a table with a checkpoint beside it (a run is replacing it, or was stopped doing so).
void refuse_unfinished_table(const std::string& path, const std::string& role);

// For a resume: true when `path` is a complete table (no checkpoint) whose HDU `extname` records
// `runfp` as kRunFingerprintKey: the run is done and is skipped. False when there is no complete
// table there. Throws io::ConfigError naming it when it is another run's (or not a table).
bool is_this_runs_complete_table(const std::string& path, const std::string& extname, const std::string& runfp);

}  // namespace stampede::app
