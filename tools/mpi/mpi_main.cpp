// `stampede-mpi`: `mpirun -n R stampede-mpi fit|metadetect ARGS` runs the `stampede fit` or
// `stampede metadetect` command over R ranks with the same arguments, giving the table a single
// process writes. A fit's batches go from rank 0 to whichever rank is free
// (tools/mpi/remote_measuring.hpp); a metadetection's ranks measure shards of the cells, each
// reading its own, and rank 0 joins their tables (rank 0 reading every cell would cap the job at
// ~5 cores' throughput: docs/run_harness.md, "MPI"). A separate program so that the plain
// `stampede` needs no MPI library at run time.
#include <mpi.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <vector>
#include <stdexcept>
#include <string>
#include <thread>

#include "app/metadetect_run.hpp"
#include "app/run_harness.hpp"
#include "app/shard_merge.hpp"
#include "io/durable_file.hpp"
#include "io/output_lock.hpp"
#include "tools/fit_command.hpp"
#include "tools/metadetect_command.hpp"
#include "tools/mpi/file_dispatch.hpp"
#include "tools/mpi/remote_measuring.hpp"

namespace {

constexpr const char* kUsage =
    "usage: mpirun -n R stampede-mpi fit INPUT.fits -o OUT.fits [--threads T] [stampede fit options]\n"
    "       mpirun -n R stampede-mpi fit --meds TILE.fits [--meds ... --bands ...] -o OUT.fits [options]\n"
    "       mpirun -n R stampede-mpi fit --input-list LIST -o DIR [--threads T] [options]\n"
    "       mpirun -n R stampede-mpi metadetect IMAGE.fits ... -o OUT.fits [stampede metadetect options]\n"
    "\n"
    "Runs `stampede fit` (see `stampede fit --help`) over R MPI ranks. Rank 0 reads the input (a grid,\n"
    "a catalogue, or MEDS tiles: each object's cutouts and PSFs travel with its batch), writes\n"
    "the one output table and fits on T threads; every other rank fits the batches it is handed, a\n"
    "batch at a time to whichever rank is free, on T threads. The table equals a single process's\n"
    "(every column but time_us); --resume after a killed job (any rank) finishes it, under any number\n"
    "of ranks, without refitting committed objects. With --input-list, ranks take whole files\n"
    "instead, one at a time to whichever rank is free, each to DIR/<name>_fit.fits. T defaults to the\n"
    "node's cores divided by the ranks on the node.\n"
    "\n"
    "metadetect: rank r measures shard r of R of the cells (`stampede metadetect --shard r/R`) into\n"
    "OUT.fits.part-r-of-R.fits, reading its own cells, then rank 0 joins them into OUT.fits (the single\n"
    "process's table) and removes them; --resume continues the parts of a killed job of as many ranks.\n";

// Ranks sharing this node (for the default thread count).
int ranks_on_this_node() {
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int n = 1;
  MPI_Comm_size(node, &n);
  MPI_Comm_free(&node);
  return n;
}

// The parts (OUT.part-r-of-N.fits, or their partial or checkpoint) of a job of other than `ranks`
// ranks found beside the output.
std::vector<std::string> parts_of_other_jobs(const std::string& output, int ranks) {
  namespace fs = std::filesystem;
  const fs::path out(output);
  const std::string prefix = out.filename().string() + ".part-";
  const std::string mine = "-of-" + std::to_string(ranks) + ".fits";
  std::vector<std::string> found;
  std::error_code error;
  for (const fs::directory_entry& e : fs::directory_iterator(out.has_parent_path() ? out.parent_path() : fs::path("."), error)) {
    std::string name = e.path().filename().string();
    if (!name.starts_with(prefix)) continue;
    for (const std::string& suffix : stampede::app::table_output("", "").companions)  // a part's own files
      if (name.ends_with(suffix)) {
        name.resize(name.size() - suffix.size());
        break;
      }
    const std::size_t of = name.rfind("-of-");
    if (of == std::string::npos || !name.ends_with(".fits") || name.substr(of) == mine) continue;
    const std::string part = (out.has_parent_path() ? (out.parent_path() / name).string() : name);
    if (std::find(found.begin(), found.end(), part) == found.end()) found.push_back(part);
  }
  std::sort(found.begin(), found.end());
  return found;
}

// A part's table and the files written beside it.
void remove_table_files(const std::string& part) {
  for (const std::string& p : stampede::app::table_output("", part).companions) stampede::io::remove_if_present(p);
  stampede::io::remove_if_present(part);
}

// `stampede-mpi metadetect ARGS -o OUT.fits`: rank r of R measures shard r/R of the cells into
// OUT.fits.part-r-of-R.fits (resumable on its own), then rank 0 joins the parts into OUT.fits as
// `stampede merge` does and removes them (one rank's part is renamed): the table equals a single
// process's. Cells cost alike, so contiguous shards keep the ranks equally busy.
int run_metadetect_over_ranks(const MetadetectCommandLine& command, int rank, int ranks) {
  if (command.run.shards > 1) {
    if (rank == 0) std::fprintf(stderr, "stampede-mpi metadetect: error: --shard: under stampede-mpi the ranks are the shards\n");
    return 1;
  }
  const stampede::app::MetadetectRunOptions& o = command.run;
  int failed = 0;
  const std::string output = o.output;
  auto part = [&](int r) { return output + ".part-" + std::to_string(r) + "-of-" + std::to_string(ranks) + ".fits"; };
  // Rank 0 makes the single process's output checks, on the output and the parts, before any rank
  // starts; a resume continues only the parts of a job of this many ranks.
  int done = 0;
  stampede::io::OutputLock output_lock;
  if (rank == 0) {
    try {
      std::vector<std::string> parts;
      for (int r = 0; r < ranks; ++r) parts.push_back(part(r));
      stampede::app::check_metadetect_outputs(o, parts);
      const std::vector<std::string> others = parts_of_other_jobs(output, ranks);
      if (o.resume && !others.empty())
        throw std::invalid_argument("--resume: '" + others.front() + "' is a part of a job of another number of ranks "
                                    "than this one's " + std::to_string(ranks) + ": resume it with as many ranks as it "
                                    "had, or run again with --overwrite");
      if (o.resume && stampede::io::file_exists(output) && !stampede::io::file_exists(output + ".checkpoint")) {
        // The job was done: as a single process, skipped if the table is this run's, else refused.
        MetadetectCommandLine whole = command;
        if (run_metadetect_with_reports(whole) != 0) failed = 1;
        done = 1;
      } else {
        // No other job may write the output or its parts while this one runs (released before the
        // merge, which takes it itself).
        output_lock = stampede::io::OutputLock::acquire(output);
        for (const std::string& stale : others) remove_table_files(stale);  // a new job: another job's leftovers
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "stampede-mpi metadetect: error: %s\n", e.what());
      failed = 1;
    }
  }
  MPI_Bcast(&failed, 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Bcast(&done, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (failed) return 1;
  if (done) return 0;
  try {
    MetadetectCommandLine mine = command;
    mine.run.shard = rank, mine.run.shards = ranks, mine.run.output = part(rank);
    mine.run.package_output.clear();  // written from the joined table below
    mine.quiet = command.quiet || rank != 0;
    // Parts are this job's own: a fresh run replaces stale ones; --resume continues a part that was
    // started and skips one that is complete.
    mine.run.overwrite = !o.resume;
    const bool complete = stampede::io::file_exists(mine.run.output) &&
                          !stampede::io::file_exists(mine.run.output + ".checkpoint");
    mine.run.resume = o.resume && stampede::io::file_exists(mine.run.output + ".checkpoint");
    if (o.resume && !mine.run.resume) mine.run.overwrite = true;
    // 3: every cell of this rank's part failed, each a flagged row; the part is complete.
    if (!(o.resume && complete))
      if (const int code = run_metadetect_with_reports(mine); code != 0 && code != 3)
        throw std::runtime_error("rank " + std::to_string(rank) + " stopped before its cells were done");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stampede-mpi metadetect: error (rank %d): %s\n", rank, e.what());
    failed = 1;
  }
  int any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (any) return 1;
  if (rank == 0) {
    output_lock.release();
    try {
      if (ranks == 1) {
        // One rank measured every cell (shard 0/1, a whole table with no SHARD key): its part is
        // the table.
        stampede::io::rename_file(part(0), output);
        stampede::io::sync_directory_of(output);
      } else {
        std::vector<std::string> parts;
        for (int r = 0; r < ranks; ++r) parts.push_back(part(r));
        stampede::app::ShardMergeOptions merge;
        merge.shards = parts, merge.output = output, merge.overwrite = o.overwrite || o.resume;
        stampede::app::merge_shards(merge);
        for (const std::string& p : parts) stampede::io::remove_if_present(p);
      }
      stampede::app::write_metadetect_package_output(o);
      if (!command.quiet) std::fprintf(stderr, "stampede-mpi metadetect: %d ranks joined into %s\n", ranks, output.c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "stampede-mpi metadetect: error: %s\n", e.what());
      return 1;
    }
  }
  return 0;
}

// `stampede-mpi fit --input-list`: each file a single process's run on the rank that takes it,
// whichever is free (tools/mpi/file_dispatch.hpp): beyond ~50 nodes one writer per run is the
// limit (docs/scaling.md), and a failure costs one file.
int run_listed_files(const FitCommandLine& command, int rank, int ranks) {
  // Outside the try: a failing rank 0 must not destroy a joinable thread (std::terminate, and the
  // error's message lost) before it reports and aborts the job.
  std::thread server;
  try {
    const auto inputs = listed_inputs(command);  // every rank reads the list (a shared file system)
    if (rank == 0)
      server = std::thread(
          [ranks, n = static_cast<int>(inputs.size())] { stampede::mpi_driver::serve_file_indices(ranks, n); });
    for (int k; (k = stampede::mpi_driver::next_file_index()) >= 0;)
      if (const int code = run_listed_input(command, inputs[static_cast<std::size_t>(k)]); code != 0)
        throw std::runtime_error("fitting '" + inputs[static_cast<std::size_t>(k)].input + "' failed");
    if (server.joinable()) server.join();
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stampede-mpi fit: error (rank %d): %s\n", rank, e.what());
    std::fflush(stderr);
    if (server.joinable()) server.detach();  // MPI_Abort ends it with the job
    MPI_Abort(MPI_COMM_WORLD, 1);
    return 1;
  }
}

int run(int argc, char** argv, int rank, int ranks) {
  const std::string command = argc >= 2 ? argv[1] : "";
  if (command != "fit" && command != "metadetect") {
    if (rank == 0) std::fputs(kUsage, command == "--help" ? stdout : stderr);
    return command == "--help" ? 0 : 2;
  }
  const std::string name = "stampede-mpi " + command;
  // Every rank parses the same arguments; rank 0 alone prints their help or errors.
  FitCommandLine fit;
  MetadetectCommandLine metadetect;
  try {
    const int code = command == "fit" ? parse_fit_arguments(argc - 1, argv + 1, &fit, rank == 0)
                                      : parse_metadetect_arguments(argc - 1, argv + 1, &metadetect, rank == 0);
    if (code >= 0) return rank == 0 ? code : 0;
  } catch (const std::exception& e) {
    if (rank == 0) std::fprintf(stderr, "%s: error: %s\n", name.c_str(), e.what());
    return 1;
  }
  int& threads = command == "fit" ? fit.run.threads : metadetect.run.threads;
  if (threads == 0) threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / ranks_on_this_node());
  // Rank 0's pipeline keeps a stage per slot in flight, most of them waiting on MPI, not computing.
  tbb::global_control parallelism(tbb::global_control::max_allowed_parallelism,
                                  static_cast<std::size_t>(ranks) * threads + 1);
  if (!fit.input_list.empty()) return run_listed_files(fit, rank, ranks);
  if (command == "metadetect") return run_metadetect_over_ranks(metadetect, rank, ranks);
  try {
    if (rank != 0) {
      stampede::mpi_driver::run_worker();
      return 0;
    }
    if (ranks > 1) fit.run.distribute = stampede::mpi_driver::rank0_distributor(ranks, threads);
    const int code = run_fit_command_line(fit);
    if (ranks > 1) stampede::mpi_driver::stop_workers();
    return code;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error (rank %d): %s\n", name.c_str(), rank, e.what());
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, 1);  // the other ranks may be waiting on this one
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_MULTIPLE, &provided);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  int code = 1;
  if (provided < MPI_THREAD_MULTIPLE) {
    if (rank == 0) std::fputs("stampede-mpi: the MPI library does not provide MPI_THREAD_MULTIPLE\n", stderr);
  } else {
    code = run(argc, argv, rank, ranks);
  }
  MPI_Finalize();
  return code;
}
