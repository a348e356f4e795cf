// Waiting on an MPI request without spinning: OpenMPI's blocking calls busy-poll, which on a node
// whose cores all fit would take a core from the fits for every waiting thread. A batch or a file
// takes ~0.1 s or more, so checking every 1 ms costs at most ~0.5 % of latency and no core.
#pragma once

#include <mpi.h>

#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>

namespace stampede::mpi_driver {

inline void wait_idle(MPI_Request* request, MPI_Status* status, const char* what) {
  for (int done = 0;;) {
    if (MPI_Test(request, &done, status) != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
    if (done) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

}  // namespace stampede::mpi_driver
