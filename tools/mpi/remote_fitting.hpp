// The MPI driver's two roles. Rank 0 runs the whole `stampede fit` run (input, PSF, the one
// output table, resume) and fits batches itself on T threads; its pipeline also hands batches to
// the other ranks, a batch at a time to whichever rank has a free slot, so that ranks stay busy
// although fit costs vary several-fold (the pipeline keeps T + (R-1) x S batches in flight, and
// restores input order before writing). Every other rank is a worker: it receives the run's final
// configuration, prepares the same PSF, and fits the batches it is sent on S = T threads, each
// with its own fitter, returning the rows. Same options, same PSF, same fitter: the table equals a
// single process's, whatever R and T.
//
// Needs MPI_THREAD_MULTIPLE (several of rank 0's pipeline threads talk to workers at once).
#pragma once

#include "app/fit_run.hpp"

namespace stampede::mpi_driver {

// Rank 0: the distributor for FitRunOptions::distribute (broadcasts the configuration to the
// workers when the run calls it). `threads` is this rank's T (and every worker's).
app::FitDistributor rank0_distributor(int ranks, int threads);
// Rank 0, after the run (or its failure): tells every worker to stop; if the run never reached the
// distributor (nothing to fit), the workers are told so instead of a configuration.
void stop_workers(int ranks);

// Every other rank: serves batches until rank 0 says stop. `threads` is its S.
void run_worker(int threads);

}  // namespace stampede::mpi_driver
