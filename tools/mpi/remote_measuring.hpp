// The MPI driver's two roles in `stampede-mpi fit` (metadetect's ranks measure shards of their
// own: tools/mpi/mpi_main.cpp). Rank 0 runs the whole command as a single process does (its
// inputs, the one output table, resume) and fits batches itself on T threads; its pipeline also
// hands batches to the other ranks, a batch at a time to whichever rank has a free slot, so that
// ranks stay busy although fit costs vary several-fold (the pipeline keeps T + (R-1) x S batches in
// flight, and restores input order before writing). Every other rank is a worker: when rank 0's run
// distributes, it receives the run's recipe (app/worker_recipe), makes the run's fitter, and fits
// the batches it is sent on S = T threads, returning their results. Same recipe, same fitter: the
// table equals a single process's, whatever R and T.
//
// Needs MPI_THREAD_MULTIPLE (several of rank 0's pipeline threads talk to workers at once).
#pragma once

#include "app/run_harness.hpp"

namespace stampede::mpi_driver {

// Rank 0: the distributor of every run (app::TableRun::distribute): sends the run's recipe to the
// workers when the run calls it, and tells them the run is over when it ends. `threads` is this
// rank's T (and every worker's S).
app::Distributor rank0_distributor(int ranks, int threads);
// Rank 0, at the end of the job (after its last run, or its failure): no more runs.
void stop_workers();

// Every other rank: serves the runs rank 0 distributes, on as many slots as rank 0 has threads,
// until it says there are no more.
void run_worker();

}  // namespace stampede::mpi_driver
