// Joining finished tables of one schema into one (the shards of a job array, app/shard_merge): the
// first table's header (its columns and every other card, in order, but the keys named to drop) and
// every table's rows in the order given, copied as bytes, through the durable table's protocol
// (a partial renamed when complete; a failed join leaves nothing). Memory is a fixed chunk of rows.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "io/table_writer.hpp"

namespace stampede::io {

struct TableJoinOptions {
  std::vector<std::string> tables;  // in the order their rows are joined
  std::string extname;              // the table HDU of each
  std::string output;
  std::vector<std::string> dropped_keys;  // the first table's keys left out (a shard's own: SHARD, ...)
  std::vector<FinalKey> final_keys;  // integer keys the joined table gains at its end (NCELLSW)
  // After each chunk: rows written so far, and in all.
  std::function<void(long long rows_done, long long rows_total)> on_progress;
};

// Whether `key` describes a binary table's structure (XTENSION ... TFIELDS, EXTNAME, TTYPEn, TFORMn,
// TUNITn, TCOMMn, TZEROn, TSCALn), not the run that wrote it.
bool is_table_structure_key(const std::string& key);

// The rows joined. Throws CatalogError naming a table whose columns differ from the first's, or
// FitsError for an unreadable one; the output's errors as the durable table's.
long long join_tables(const TableJoinOptions& options);

}  // namespace stampede::io
