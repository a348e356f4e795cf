// `stampede-mpi`: `mpirun -n R stampede-mpi fit|metadetect ARGS` runs the `stampede fit` or
// `stampede metadetect` command over R ranks, one mode for both (tools/mpi/remote_measuring.hpp):
// the same arguments, the same one output table as a single process writes, the same output
// checks and resume. A separate program so that the plain `stampede` needs no MPI library at run
// time.
#include <mpi.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>

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
    "Runs `stampede fit` or `stampede metadetect` (see their --help) over R MPI ranks. Rank 0 runs\n"
    "the command as a single process does: it reads the input (a grid, a catalogue, MEDS tiles, image\n"
    "files or cell tiles: each batch's stamps, cutouts, PSFs and cells' planes travel with it), checks\n"
    "and writes the one output table, and measures on T threads; every other rank measures the\n"
    "batches it is handed, a batch at a time to whichever rank is free, on T threads. The table equals\n"
    "a single process's (a fit's every column but time_us; metadetect's byte for byte); --resume after\n"
    "a killed job (any rank) finishes it, under any number of ranks, without measuring committed\n"
    "objects or cells again. With --input-list, ranks take whole files instead, one at a time to\n"
    "whichever rank is free, each a single process's run to DIR/<name>_fit.fits. T defaults to the\n"
    "node's cores divided by the ranks on the node.\n";

// Ranks sharing this node (for the default thread count).
int ranks_on_this_node() {
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int n = 1;
  MPI_Comm_size(node, &n);
  MPI_Comm_free(&node);
  return n;
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
  try {
    if (rank != 0) {
      stampede::mpi_driver::run_worker();
      return 0;
    }
    stampede::app::Distributor distribute;
    if (ranks > 1) distribute = stampede::mpi_driver::rank0_distributor(ranks, threads);
    int code = 0;
    if (command == "fit") {
      fit.run.distribute = distribute;
      code = run_fit_command_line(fit);
    } else {
      metadetect.run.distribute = distribute;
      code = run_metadetect_with_reports(metadetect);
    }
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
