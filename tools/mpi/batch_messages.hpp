// A batch on the wire between the MPI driver's ranks: rank 0 packs a batch (its observation arena:
// each stamp's or cutout's pixels, weights, frame and PSF, and what reading found) with the rows'
// identity into one byte message; a worker unpacks it into a batch of its own, fits it, and
// returns its results (the rows and the problem texts), which rank 0 copies back. The run's recipe
// (app/worker_recipe) travels the same way. The buffers are reused, so steady state
// allocates nothing. All ranks run the same binary (a homogeneous cluster): records travel as their
// bytes.
#pragma once

#include <cstddef>
#include <vector>

#include "app/run_harness.hpp"
#include "engine/pipeline/stamp_batch.hpp"

namespace stampede::mpi_driver {

// Appends nothing: *out is resized to the message and overwritten.
void pack_batch(const StampBatch& batch, std::vector<char>* out);
// Fills `batch` (capacity as the sender's) from a message of pack_batch. Throws
// std::runtime_error for a message that is not one (a bug, not bad input: ranks run one binary).
void unpack_batch(const char* data, std::size_t size, StampBatch* batch);

// What fitting the batch gave (the records and the problems), and back into rank 0's batch.
void pack_results(const StampBatch& batch, std::vector<char>* out);
void unpack_results(const char* data, std::size_t size, StampBatch* batch);

// A run's recipe, and back.
void pack_recipe(const app::WorkerRecipe& recipe, std::vector<char>* out);
app::WorkerRecipe unpack_recipe(const char* data, std::size_t size);

}  // namespace stampede::mpi_driver
