// Joining shard tables; see shard_merge.hpp.
#include "app/shard_merge.hpp"

#include <algorithm>
#include <chrono>
#include <map>
#include <optional>
#include <utility>

#include "app/fit_run.hpp"
#include "engine/pipeline/range_source.hpp"
#include "io/catalog_reader.hpp"
#include "io/catalog_writer.hpp"
#include "io/output_check.hpp"
#include "io/output_lock.hpp"
#include "app/run_config.hpp"
#include "io/fits_file.hpp"
#include "io/simulation_identity.hpp"

namespace stampede::app {

namespace {

constexpr long long kChunkRows = 4096;

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

struct Shard {
  std::string path;
  int index = 0, count = 0;
  long long total = 0;  // the whole input's objects
  long long rows = 0;
  io::PositionColumns positions = io::PositionColumns::kGrid;
  bool metacal = false;
  std::vector<std::string> bands;  // a multi-band run's
  std::vector<std::pair<std::string, std::string>> header;  // run_keys() present, with their values
};

Shard read_shard(const std::string& path) {
  refuse_unfinished_table(io::fits_root_name(path), "shard");
  io::CatalogReader r = io::CatalogReader::open(path);
  Shard s;
  s.path = path;
  s.rows = r.rows();
  io::FitsFile& f = r.file();
  const auto shard = f.read_key_string(kShardKey);
  if (!shard)
    throw io::CatalogError(path + ": no " + std::string(kShardKey) +
                           " key: not the table of a `stampede fit --shard i/N` run");
  const auto parsed = parse_shard(*shard);
  if (!parsed) throw io::CatalogError(path + ": " + kShardKey + " = '" + *shard + "' is not i/N with 0 <= i < N");
  s.index = parsed->first;
  s.count = parsed->second;
  s.positions = r.positions();
  s.metacal = r.metacal();
  s.bands = r.bands();
  s.total = f.key_long(kShardTotalKey);
  for (const std::string& k : run_keys())
    if (auto v = f.read_key_string(k)) s.header.emplace_back(k, *v);
  const long long expected = shard_begin(s.total, s.index + 1, s.count) - shard_begin(s.total, s.index, s.count);
  if (s.rows != expected)
    throw io::CatalogError(path + ": shard " + *shard + " of " + std::to_string(s.total) + " objects has " +
                           std::to_string(s.rows) + " rows, not " + std::to_string(expected));
  return s;
}

// "" when b belongs to a's run; else why not, naming b.
std::string difference(const Shard& a, const Shard& b) {
  if (a.count != b.count || a.total != b.total)
    return b.path + " is shard " + std::to_string(b.index) + "/" + std::to_string(b.count) + " of " +
           std::to_string(b.total) + " objects, " + a.path + " one of " + std::to_string(a.count) + " shards of " +
           std::to_string(a.total);
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
  const std::vector<io::RunOutput> outputs = {
      {"-o", o.output, {o.output + ".partial", o.output + ".checkpoint", io::OutputLock::path_for(o.output)}}};
  io::check_outputs(outputs, inputs, o.overwrite);
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
                             std::to_string(shards[k].index) + "/" + std::to_string(shards[k].count));
    slot = k;
  }
  for (std::size_t i = 0; i < by_index.size(); ++i)
    if (!by_index[i])
      throw io::CatalogError("merge: shard " + std::to_string(i) + "/" + std::to_string(by_index.size()) +
                             " is missing (" + std::to_string(shards.size()) + " of " +
                             std::to_string(by_index.size()) + " given)");

  io::CatalogWriterOptions wo;
  wo.path = o.output;
  wo.positions = shards[*by_index[0]].positions;
  wo.metacal = shards[*by_index[0]].metacal;
  wo.bands = shards[*by_index[0]].bands;
  wo.header = shards.front().header;  // the run's keys, as a single process writes them
  for (const io::OptionInfo& info : app::run_config_options())
    if (info.type != io::HeaderValueType::kText) wo.header_types[info.name] = info.type;
  wo.header_types["metacal_gamma_fwhm"] = io::HeaderValueType::kReal;
  wo.fingerprint = "stampede merge of " + std::to_string(by_index.size()) + " shards\n";
  wo.keep_on_write_failure = false;  // a merge has no --resume: a failed one is redone whole
  auto writer = io::CatalogWriter::create(wo);
  ShardMergeSummary summary;
  summary.shards = static_cast<int>(by_index.size());
  const long long total = shards.front().total;
  try {
    for (const auto& slot : by_index) {
      io::CatalogReader r = io::CatalogReader::open(shards[*slot].path);
      if (shards[*slot].positions != wo.positions || shards[*slot].metacal != wo.metacal || shards[*slot].bands != wo.bands)
        throw io::CatalogError("merge: " + shards[*slot].path + " has other columns than the first shard");
      for (long long first = 0; first < r.rows(); first += kChunkRows) {
        const auto rows = r.records(first, std::min(kChunkRows, r.rows() - first));
        writer->append(rows);
        summary.rows += static_cast<long long>(rows.size());
        if (o.on_progress) o.on_progress(summary.rows, total);
      }
    }
    writer->finish();
  } catch (...) {
    writer->abandon();
    throw;
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace stampede::app
