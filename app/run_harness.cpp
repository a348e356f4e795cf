// The shared pieces of every table-writing run; see run_harness.hpp.
#include "app/run_harness.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdlib>
#include <map>
#include <cstdio>
#include <filesystem>

#include "engine/pipeline/range_source.hpp"
#include "io/catalog_error.hpp"
#include "io/config_error.hpp"
#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "io/output_lock.hpp"
#include "app/run_fingerprint.hpp"

namespace stampede::app {

void check_threads(long long threads, const std::string& what) {
  if (threads < 0 || threads > kMaxThreads)
    throw io::ConfigError(what + " = " + std::to_string(threads) + ": must be 0 (all cores) or 1.." +
                          std::to_string(kMaxThreads));
}

std::optional<std::pair<int, int>> parse_shard(const std::string& text) {
  const std::size_t slash = text.find('/');
  if (slash == std::string::npos) return std::nullopt;
  int i = 0, n = 0;
  const char* end = text.data() + text.size();
  const auto a = std::from_chars(text.data(), text.data() + slash, i);
  const auto b = std::from_chars(text.data() + slash + 1, end, n);
  if (a.ec != std::errc() || a.ptr != text.data() + slash || b.ec != std::errc() || b.ptr != end) return std::nullopt;
  if (n < 1 || n > 1000000 || i < 0 || i >= n) return std::nullopt;
  return std::pair{i, n};
}

ShardRange shard_range(long long total, int shard, int shards) {
  if (shards < 1 || shard < 0 || shard >= shards)
    throw io::ConfigError("--shard " + shard_text(shard, shards) + ": must be i/N with 0 <= i < N");
  return {shard_begin(total, shard, shards), shard_begin(total, shard + 1, shards)};
}

std::string shard_text(int shard, int shards) { return std::to_string(shard) + "/" + std::to_string(shards); }

io::RunOutput table_output(const std::string& option, const std::string& path) {
  const std::string checkpoint = path + ".checkpoint";
  return {option, path, {path + ".partial", checkpoint, io::temporary_path(checkpoint), io::OutputLock::path_for(path)}};
}

void refuse_unfinished_table(const std::string& path, const std::string& role) {
  for (const std::string& suffix : table_output("", "").companions)  // ".partial", ".checkpoint", ...
    if (path.ends_with(suffix))
      throw io::CatalogError(path + ": a run's unfinished " + suffix.substr(1) + " file, not a " + role +
                             ": finish that run (--resume) and give its table");
  if (std::filesystem::exists(path + ".checkpoint"))
    throw io::CatalogError(path + ": a run that replaces it is unfinished ('" + path + ".checkpoint' is beside it), so it "
                           "is not a finished " + role + ": finish that run (--resume) first");
}

namespace {

// Two header values alike: the same text, or the same number however written.
bool same_value(const std::string& a, const std::string& b) {
  if (a == b) return true;
  char *ea = nullptr, *eb = nullptr;
  const double x = std::strtod(a.c_str(), &ea), y = std::strtod(b.c_str(), &eb);
  return ea != a.c_str() && *ea == '\0' && eb != b.c_str() && *eb == '\0' && x == y;
}

// What differs between a table's header and this run's keys: " (KEY = 'a' there, 'b' in this run)"
// for the first key that does, "" when none does (the program version, which no key holds).
std::string first_key_difference(io::FitsFile& f, const std::vector<std::pair<std::string, std::string>>& header) {
  std::map<std::string, std::string> recorded;
  for (const io::FitsFile::HeaderCard& c : f.header_cards()) recorded[c.key] = c.value;
  for (const auto& [key, value] : header) {
    if (key == kRunFingerprintKey || key == kShardKey || key == kShardTotalKey) continue;
    std::string upper = key;
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const auto at = recorded.find(upper);
    if (at == recorded.end()) return " (" + key + " is not recorded there; this run has '" + value + "')";
    if (!same_value(at->second, value)) return " (" + key + " = '" + at->second + "' there, '" + value + "' in this run)";
  }
  return "";
}

}  // namespace

bool is_this_runs_complete_table(const std::string& path, const std::string& extname, const std::string& runfp,
                                 const std::vector<std::pair<std::string, std::string>>& header) {
  if (!std::filesystem::exists(path) || std::filesystem::exists(path + ".checkpoint")) return false;
  std::string recorded, differs;
  try {
    io::FitsFile f = io::FitsFile::open_read(path);
    f.move_to(extname);
    recorded = f.read_key_string(kRunFingerprintKey).value_or("");
    if (recorded != runfp) differs = first_key_difference(f, header);
  } catch (const std::exception& e) {
    throw io::ConfigError(path + " exists and is not a table --resume can check: " + e.what());
  }
  if (recorded == runfp) return true;
  throw io::ConfigError(path + " is complete but was written by another run (" +
                        (recorded.empty() ? std::string("it records no ") + kRunFingerprintKey
                                          : std::string(kRunFingerprintKey) + " = '" + recorded + "', this run's '" +
                                                runfp + "'") +
                        ": " + (differs.empty() ? "the program version differs" : "the inputs or options differ" + differs) +
                        "); remove it, or run it again with --overwrite");
}

std::string RunProgress::Line() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%lld/%lld %ss (%.1f%%), %.1f %ss/s, ETA %.0f s   ", done, total, unit,
                100.0 * done / std::max(total, 1LL), per_second, unit, eta_seconds);
  return buf;
}

std::vector<io::OutputLock> protect_outputs(const TableRun& run, const std::vector<io::RunOutput>& outputs,
                                            const std::vector<io::RunInput>& inputs) {
  io::check_outputs(outputs, inputs, run.overwrite || run.resume);
  std::vector<io::OutputLock> locks;
  for (const io::RunOutput& o : outputs)  // those whose companions name their lock
    if (std::find(o.companions.begin(), o.companions.end(), io::OutputLock::path_for(o.path)) != o.companions.end())
      locks.push_back(io::OutputLock::acquire(o.path));
  return locks;
}

void seal_identity(const TableRun& run, long long units, io::TableWriterOptions* table, const char* total_key) {
  table->header.emplace_back(kRunFingerprintKey, RunFingerprint().text(table->fingerprint).hex());
  if (run.shards <= 1) return;
  if (units < 0) throw io::ConfigError("--shard needs an input whose " + std::string(run.unit) + " count is known");
  table->header.emplace_back(kShardKey, shard_text(run.shard, run.shards));
  if (total_key) {
    table->header.emplace_back(total_key, std::to_string(units));
    table->header_types[total_key] = io::HeaderValueType::kInteger;
  }
  table->fingerprint += "shard " + shard_text(run.shard, run.shards) + " of " + std::to_string(units) + "\n";
}

std::string recorded_runfp(const io::TableWriterOptions& table) {
  for (const auto& [key, value] : table.header)
    if (key == kRunFingerprintKey) return value;
  return "";
}

std::unique_ptr<StampSource> shard_source(const TableRun& run, StampSource& whole, long long committed) {
  if (run.shards <= 1) {
    whole.skip_to(committed);
    return nullptr;
  }
  const ShardRange range = shard_range(whole.total_objects(), run.shard, run.shards);
  auto shard = std::make_unique<RangeSource>(whole, range.begin, range.end);
  shard->skip_to(committed);
  return shard;
}

PipelineSummary measure_table(const TableRun& run, StampSource& source, long long committed, BatchSink& sink,
                              io::TableWriter* table, const MeasurerFactory& make_measurer, PipelineOptions pipeline,
                              const WorkerRecipe& recipe) {
  pipeline.stop = run.stop;
  Distribution distribution{make_measurer, pipeline.threads, nullptr};
  if (run.distribute) {
    distribution = run.distribute(recipe, make_measurer);
    pipeline.threads = distribution.pipeline_threads;
  }
  const auto finish_distribution = [&] {
    if (distribution.finish) distribution.finish();
  };
  const long long total = source.total_objects();
  auto progress = [&run, total, committed, last = -1.0](const PipelineProgress& p) mutable {
    if (!run.on_progress || p.seconds - last < run.progress_interval) return;
    last = p.seconds;
    RunProgress r;
    r.done = committed + p.objects_done;
    r.total = total;
    r.seconds = p.seconds;
    r.per_second = p.objects_done / std::max(p.seconds, 1e-9);
    r.eta_seconds = (total - r.done) / std::max(r.per_second, 1e-9);
    r.unit = run.unit;
    run.on_progress(r);
  };
  try {
    const PipelineSummary summary = run_pipeline(source, sink, distribution.make_measurer, pipeline, progress);
    finish_distribution();
    if (table && !summary.stopped) table->finish();  // stopped: the partials stay, as a kill leaves them
    return summary;
  } catch (...) {
    try {
      finish_distribution();
    } catch (...) {  // the run's own error is the one to report
    }
    if (table) table->abandon();
    throw;
  }
}

}  // namespace stampede::app
