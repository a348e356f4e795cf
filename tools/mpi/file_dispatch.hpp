// Whole files to ranks (`stampede-mpi fit --input-list LIST -o DIR`): rank 0 serves the list's
// indices, one at a time to whichever rank asks (itself included), so a rank that drew a large
// tile does not hold up the rest; every rank fits its files with the engine on its T threads and
// writes each one's own output. Needs MPI_THREAD_MULTIPLE (rank 0 serves on a thread of its own).
#pragma once

namespace stampede::mpi_driver {

// Rank 0, on a thread of its own: answers requests until every one of `ranks` has been told
// there is nothing left of `files`.
void serve_file_indices(int ranks, int files);
// Any rank: the next file index to fit, or -1 when the list is done.
int next_file_index();

}  // namespace stampede::mpi_driver
