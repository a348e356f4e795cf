// Whole files to ranks; see file_dispatch.hpp.
#include "tools/mpi/file_dispatch.hpp"

#include <mpi.h>

#include <chrono>
#include <stdexcept>
#include <thread>

namespace stampede::mpi_driver {

namespace {

constexpr int kRequestTag = 7;
constexpr int kReplyTag = 8;

// As remote_fitting's: OpenMPI's blocking calls spin, and the node's cores are fitting.
void wait_idle(MPI_Request* request, MPI_Status* status) {
  for (int done = 0;;) {
    if (MPI_Test(request, &done, status) != MPI_SUCCESS) throw std::runtime_error("MPI: file request failed");
    if (done) return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

}  // namespace

void serve_file_indices(int ranks, int files) {
  int next = 0, finished = 0;
  while (finished < ranks) {
    int dummy = 0;
    MPI_Request request;
    MPI_Status status;
    MPI_Irecv(&dummy, 1, MPI_INT, MPI_ANY_SOURCE, kRequestTag, MPI_COMM_WORLD, &request);
    wait_idle(&request, &status);
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
  wait_idle(&request, MPI_STATUS_IGNORE);
  return index;
}

}  // namespace stampede::mpi_driver
