// Whole files to ranks; see file_dispatch.hpp.
#include "tools/mpi/file_dispatch.hpp"

#include <mpi.h>

#include "tools/mpi/idle_wait.hpp"


namespace stampede::mpi_driver {

namespace {

constexpr int kRequestTag = 7;
constexpr int kReplyTag = 8;

}  // namespace

void serve_file_indices(int ranks, int files) {
  int next = 0, finished = 0;
  while (finished < ranks) {
    int dummy = 0;
    MPI_Request request;
    MPI_Status status;
    MPI_Irecv(&dummy, 1, MPI_INT, MPI_ANY_SOURCE, kRequestTag, MPI_COMM_WORLD, &request);
    wait_idle(&request, &status, "file request");
    int reply = next < files ? next++ : -1;
    if (reply < 0) ++finished;
    MPI_Send(&reply, 1, MPI_INT, status.MPI_SOURCE, kReplyTag, MPI_COMM_WORLD);
  }
}

int next_file_index() {
  int dummy = 0, index = -1;
  MPI_Send(&dummy, 1, MPI_INT, 0, kRequestTag, MPI_COMM_WORLD);
  MPI_Request request;
  MPI_Irecv(&index, 1, MPI_INT, 0, kReplyTag, MPI_COMM_WORLD, &request);
  wait_idle(&request, MPI_STATUS_IGNORE, "file reply");
  return index;
}

}  // namespace stampede::mpi_driver
