// Joining metadetection shards; see metadetect_merge.hpp.
#include "app/metadetect_merge.hpp"

#include <algorithm>
#include <set>
#include <utility>

#include "app/run_harness.hpp"
#include "io/catalog_writer.hpp"
#include "io/fits_file.hpp"
#include "io/metadetect_reader.hpp"
#include "io/metadetect_writer.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"

namespace stampede::app {
namespace {

// The keys the writer itself writes (the table's structure), and the two a shard adds.
bool structural(const std::string& key) {
  static const std::set<std::string> fixed = {"XTENSION", "BITPIX", "NAXIS",   "NAXIS1",  "NAXIS2",   "PCOUNT",
                                              "GCOUNT",   "TFIELDS", "EXTNAME", "LONGSTRN", "SHARD", "NCELLSW"};
  if (fixed.count(key)) return true;
  for (const char* prefix : {"TTYPE", "TFORM", "TUNIT", "TCOMM"})
    if (key.starts_with(prefix) && key.size() > 5 && key.find_first_not_of("0123456789", 5) == std::string::npos)
      return true;
  return false;
}

struct Shard {
  std::string path;
  int index = 0, count = 0;
  long long cells_total = 0, cells_written = 0;
  std::vector<std::pair<std::string, std::string>> keys;  // the run's (not structural), in order
  std::vector<io::HeaderValueType> types;
};

[[noreturn]] void refuse(const std::string& path, const std::string& why) { throw io::CatalogError(path + ": " + why); }

Shard read_shard(const std::string& path) {
  refuse_unfinished_table(io::fits_root_name(path), "shard");
  io::FitsFile f = io::FitsFile::open_read(path);
  if (!f.move_to_if_present("METADETECT")) refuse(path, "no METADETECT table (not a `stampede metadetect` table)");
  Shard s;
  s.path = path;
  const auto shard = f.read_key_string("SHARD");
  const auto parsed = shard ? parse_shard(*shard) : std::nullopt;
  if (!parsed) refuse(path, "not a shard (no header key SHARD 'i/N'): run with --shard i/N");
  s.index = parsed->first, s.count = parsed->second;
  s.cells_total = f.key_long("NCELLS");
  const auto written = f.read_key_long("NCELLSW");
  if (!written) refuse(path, "unfinished (no NCELLSW key): finish the shard's run (--resume) first");
  s.cells_written = *written;
  for (const io::FitsFile::HeaderCard& c : f.header_cards()) {
    using Type = io::FitsFile::HeaderCard::Type;
    if (c.type == Type::kCommentary || c.type == Type::kUndefined || structural(c.key)) continue;
    s.keys.emplace_back(c.key, c.value);
    s.types.push_back(c.type == Type::kInteger ? io::HeaderValueType::kInteger
                      : c.type == Type::kReal  ? io::HeaderValueType::kReal
                                               : io::HeaderValueType::kText);
  }
  return s;
}

}  // namespace

bool is_metadetect_table(const std::string& path) {
  io::FitsFile f = io::FitsFile::open_read(path);
  return f.move_to_if_present("METADETECT");
}

MetadetectMergeSummary merge_metadetect_shards(const MetadetectMergeOptions& options) {
  if (options.shards.empty()) throw io::CatalogError("no shard tables to merge");
  std::vector<Shard> shards;
  for (const std::string& p : options.shards) shards.push_back(read_shard(p));
  std::sort(shards.begin(), shards.end(), [](const Shard& a, const Shard& b) { return a.index < b.index; });
  const Shard& first = shards.front();
  for (std::size_t k = 0; k < shards.size(); ++k) {
    const Shard& s = shards[k];
    if (s.count != first.count) refuse(s.path, "a shard of " + std::to_string(s.count) + ", not " + std::to_string(first.count));
    if (s.index != static_cast<int>(k))
      refuse(s.path, k > 0 && shards[k - 1].index == s.index ? "shard " + std::to_string(s.index) + " is given twice"
                                                            : "shard " + std::to_string(k) + " is missing");
    if (s.keys != first.keys) {
      std::string key = "?";
      for (std::size_t i = 0; i < std::min(s.keys.size(), first.keys.size()); ++i)
        if (s.keys[i] != first.keys[i]) {
          key = s.keys[i].first;
          break;
        }
      refuse(s.path, "of another run than " + first.path + " (header key " + key + " differs: other inputs or options)");
    }
    const long long begin = s.cells_total * s.index / s.count, end = s.cells_total * (s.index + 1) / s.count;
    if (s.cells_written != end - begin)
      refuse(s.path, "holds " + std::to_string(s.cells_written) + " cells, its range " + std::to_string(end - begin));
  }
  if (static_cast<int>(shards.size()) != first.count)
    refuse(first.path, "shard " + std::to_string(shards.size()) + " of " + std::to_string(first.count) + " is missing");
  for (const Shard& s : shards)
    if (io::same_file(s.path, options.output)) throw io::CatalogError("the output '" + options.output + "' is a shard");
  const io::OutputLock lock = io::OutputLock::acquire(options.output);
  io::refuse_to_replace(options.output, options.overwrite);
  io::MetadetectWriterOptions wo;
  wo.path = options.output;
  wo.header = first.keys;
  for (std::size_t i = 0; i < first.keys.size(); ++i) wo.header_types[first.keys[i].first] = first.types[i];
  wo.fingerprint = "stampede metadetect merge";
  wo.bands = io::metadetect_table_bands(first.path);
  auto writer = io::MetadetectWriter::create(wo);
  MetadetectMergeSummary summary;
  try {
    for (const Shard& s : shards) {
      const std::vector<MetadetectRow> rows = io::read_metadetect_rows(s.path);
      writer->append(rows, s.cells_written);
      summary.rows += static_cast<long long>(rows.size());
      summary.cells += s.cells_written;
    }
    writer->finish();
  } catch (...) {
    writer->abandon();
    throw;
  }
  summary.shards = static_cast<int>(shards.size());
  return summary;
}

}  // namespace stampede::app
