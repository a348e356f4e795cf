// Joining shard tables; see shard_merge.hpp.
#include "app/shard_merge.hpp"

#include <algorithm>
#include <chrono>
#include <map>
#include <optional>
#include <span>
#include <utility>

#include "app/run_harness.hpp"
#include "io/catalog_error.hpp"
#include "io/config_error.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"
#include "app/run_config.hpp"
#include "io/fits_file.hpp"
#include "io/simulation_identity.hpp"
#include "io/table_join.hpp"

namespace stampede::app {

namespace {

// The header keys fit records its input files' contents under (size and digest); the keys that
// name those files as typed are compared only for tables without them (written before they were).
// A multi-band run's further tiles are MEDS1.. with MEDSDIG1.. (fit_run).
constexpr const char* kIdentityKeys[] = {"INDIGEST", "CATDIGST", "WGTDIGST", "PSFDIGST", "MEDSDIGS", "MEDSDIG1",
                                         "MEDSDIG2", "MEDSDIG3", "MEDSDIG4", "MEDSDIG5", "MEDSDIG6", "MEDSDIG7",
                                         "PSFEXDIG"};
bool names_a_file(const std::string& key) {
  for (const char* k : {"INPUT", "CATALOG", "WEIGHTS", "MEDS", "MEDS1", "MEDS2", "MEDS3", "MEDS4", "MEDS5", "MEDS6",
                        "MEDS7", "psf_image"})
    if (key == k) return true;
  return false;
}

// What identifies the run a shard belongs to: every header key a fit table records about its
// inputs and configuration, in the order the fit wrote them (absent keys are left out).
std::vector<std::string> run_keys() {
  std::vector<std::string> keys;
  for (const io::OptionInfo& o : app::run_config_options()) keys.push_back(o.name);
  keys.emplace_back("metacal_gamma_fwhm");  // a metacal run's reconvolution PSF
  for (const char* k : {"INPUT", "CATALOG", "WEIGHTS", "MEDS", "MEDS1", "MEDS2", "MEDS3", "MEDS4", "MEDS5", "MEDS6",
                        "MEDS7", io::kInputSetKey})
    keys.emplace_back(k);
  for (const char* k : kIdentityKeys) keys.emplace_back(k);
  return keys;
}

// What a shard table says of itself. Fit: `units` are its objects (a row each), `total` the whole
// input's (SHARDTOT), `header` the run keys. Metadetect: its cells (NCELLSW) of the run's NCELLS,
// `header` every key but the shard's own.
struct Shard {
  std::string path;
  bool metadetect = false;
  int index = 0, count = 0;
  long long total = 0, units = 0;
  long long rows = 0;  // metadetect: the table's
  std::vector<std::pair<std::string, std::string>> header;
};

[[noreturn]] void refuse(const std::string& path, const std::string& why) { throw io::CatalogError(path + ": " + why); }

// The keys a metadetect shard's header holds beside the table's structure, the shard's own left out.
bool metadetect_run_key(const std::string& key) {
  return !io::is_table_structure_key(key) && key != "LONGSTRN" && key != kShardKey && key != "NCELLSW" && key != "NROWSW";
}

Shard read_shard(const std::string& path) {
  refuse_unfinished_table(io::fits_root_name(path), "shard");
  io::FitsFile f = io::FitsFile::open_read(path);
  Shard s;
  s.path = path;
  s.metadetect = f.move_to_if_present("METADETECT");
  if (!s.metadetect && !f.move_to_if_present("RESULTS"))
    refuse(path, "no RESULTS or METADETECT table: not the table of `stampede fit` or `stampede metadetect`");
  const char* run = s.metadetect ? "`stampede metadetect --shard i/N`" : "`stampede fit --shard i/N`";
  const auto shard = f.read_key_string(kShardKey);
  if (!shard) refuse(path, std::string("no ") + kShardKey + " key: not the table of a " + run + " run");
  const auto parsed = parse_shard(*shard);
  if (!parsed) refuse(path, std::string(kShardKey) + " = '" + *shard + "' is not i/N with 0 <= i < N");
  s.index = parsed->first, s.count = parsed->second;
  if (s.metadetect) {
    s.total = f.key_long("NCELLS");
    const auto written = f.read_key_long("NCELLSW");
    if (!written) refuse(path, "unfinished (no NCELLSW key): finish the shard's run (--resume) first");
    s.units = *written;
    // A table that lost (or gained) rows since its run wrote it is not that run's shard.
    s.rows = f.table_rows();
    if (const auto rows = f.read_key_long("NROWSW"); rows && *rows != s.rows)
      refuse(path, "holds " + std::to_string(s.rows) + " rows, but its run wrote " + std::to_string(*rows) +
                       " (NROWSW): rows were lost or added since; run that shard again");
    for (const io::FitsFile::HeaderCard& c : f.header_cards())
      if (c.type != io::FitsFile::HeaderCard::Type::kCommentary && metadetect_run_key(c.key)) s.header.emplace_back(c.key, c.value);
  } else {
    s.total = f.key_long(kShardTotalKey);
    s.units = f.table_rows();
    for (const std::string& k : run_keys())
      if (auto v = f.read_key_string(k)) s.header.emplace_back(k, *v);
  }
  const ShardRange range = shard_range(s.total, s.index, s.count);
  const char* units = s.metadetect ? " cells" : " objects";
  if (s.units != range.end - range.begin)
    refuse(path, "shard " + *shard + " of " + std::to_string(s.total) + units + " holds " + std::to_string(s.units) +
                     (s.metadetect ? " cells" : " rows") + ", not its range's " + std::to_string(range.end - range.begin));
  return s;
}

// "" when b belongs to a's run; else why not, naming b.
std::string difference(const Shard& a, const Shard& b) {
  if (a.metadetect != b.metadetect)
    return b.path + " is a " + (b.metadetect ? "metadetect" : "fit") + " table, " + a.path + " a " +
           (a.metadetect ? "metadetect" : "fit") + " one";
  const char* units = a.metadetect ? " cells" : " objects";
  if (a.count != b.count || a.total != b.total)
    return b.path + " is shard " + std::to_string(b.index) + "/" + std::to_string(b.count) + " of " +
           std::to_string(b.total) + units + ", " + a.path + " one of " + std::to_string(a.count) + " shards of " +
           std::to_string(a.total);
  if (a.metadetect) {  // every key the run records, in its order; RUNFP (their digest) only if alone
    std::map<std::string, std::string> bv(b.header.begin(), b.header.end());
    for (const bool digest : {false, true})
      for (const auto& [k, x] : a.header) {
        if ((k == kRunFingerprintKey) != digest) continue;
        const auto y = bv.find(k);
        if (y == bv.end() || y->second != x)
          return b.path + " is from another run than " + a.path + ": " + k + " = " +
                 (y == bv.end() ? "(absent)" : "'" + y->second + "'") + " there, '" + x + "' here (other inputs or options)";
      }
    std::map<std::string, std::string> av(a.header.begin(), a.header.end());
    for (const auto& [k, y] : b.header)
      if (!av.count(k)) return b.path + " is from another run than " + a.path + ": " + k + " = '" + y + "' there, (absent) here";
    return "";
  }
  std::map<std::string, std::string> av(a.header.begin(), a.header.end()), bv(b.header.begin(), b.header.end());
  const auto identified = [](const std::map<std::string, std::string>& h) {
    return h.count("INDIGEST") > 0 || h.count("MEDSDIGS") > 0;
  };
  const bool by_content = identified(av) && identified(bv);
  for (const std::string& k : run_keys()) {
    if (by_content && names_a_file(k)) continue;
    const auto x = av.find(k), y = bv.find(k);
    const std::string xs = x == av.end() ? "(absent)" : "'" + x->second + "'";
    const std::string ys = y == bv.end() ? "(absent)" : "'" + y->second + "'";
    if (xs != ys) return b.path + " is from another run than " + a.path + ": " + k + " = " + ys + " there, " + xs + " here";
  }
  return "";
}

}  // namespace

ShardMergeSummary merge_shards(const ShardMergeOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  if (o.shards.empty()) throw io::ConfigError("merge: no shard tables given");
  if (o.output.empty()) throw io::ConfigError("merge: no output given (-o OUT.fits)");
  std::vector<io::RunInput> inputs;
  for (const std::string& p : o.shards) inputs.push_back({"shard", io::fits_root_name(p)});
  const io::RunOutput output = table_output("-o", o.output);
  io::check_outputs(std::span(&output, 1), inputs, o.overwrite);
  const io::OutputLock lock = io::OutputLock::acquire(o.output);

  std::vector<Shard> shards;
  for (const std::string& p : o.shards) shards.push_back(read_shard(p));
  std::vector<std::optional<std::size_t>> by_index(static_cast<std::size_t>(shards.front().count));
  for (std::size_t k = 0; k < shards.size(); ++k) {
    const std::string why = difference(shards.front(), shards[k]);
    if (!why.empty()) throw io::CatalogError("merge: " + why);
    auto& slot = by_index[static_cast<std::size_t>(shards[k].index)];
    if (slot)
      throw io::CatalogError("merge: " + shards[*slot].path + " and " + shards[k].path + " are both shard " +
                             shard_text(shards[k].index, shards[k].count) + " (a shard given twice)");
    slot = k;
  }
  for (std::size_t i = 0; i < by_index.size(); ++i)
    if (!by_index[i])
      throw io::CatalogError("merge: shard " + shard_text(static_cast<int>(i), static_cast<int>(by_index.size())) +
                             " is missing (" + std::to_string(shards.size()) + " of " + std::to_string(by_index.size()) +
                             " given)");
  const Shard& first = shards.front();
  io::TableJoinOptions join;
  for (const auto& slot : by_index) join.tables.push_back(shards[*slot].path);
  join.output = o.output;
  join.on_progress = o.on_progress;
  if (first.metadetect) {
    join.extname = "METADETECT";
    long long rows = 0;
    for (const Shard& shard : shards) rows += shard.rows;
    join.dropped_keys = {kShardKey, "NCELLSW", "NROWSW"};
    join.final_keys = {{"NCELLSW", first.total, "cells whose rows this table holds"},
                       {"NROWSW", rows, "rows its run wrote (a merge checks none is lost)"}};
  } else {
    join.extname = "RESULTS";  // the shards share the whole run's RUNFP
    join.dropped_keys = {kShardKey, kShardTotalKey};
  }
  ShardMergeSummary summary;
  summary.metadetect = first.metadetect;
  summary.shards = static_cast<int>(by_index.size());
  summary.rows = io::join_tables(join);
  summary.units = first.total;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace stampede::app
