// A batch of objects travelling through the pipeline: the unit of reading, fitting and writing.
// An object is one stamp of a grid or catalogue (pixels, weights, PSFs below) or any number of
// observations (`observations`: a MEDS tile's cutouts over one band or several). Batches are
// allocated once (a fixed pool) and reused, so steady state allocates nothing.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/pipeline/observation_arena.hpp"

namespace stampede {

// What a kind of run carries in a batch beyond the objects' stamps and rows: a metadetection
// batch's cells and the variable number of rows each yields. The run's source creates it in a batch
// the first time it fills that batch and reuses it after (the pool is fixed); its fitter and its
// sink, which know the concrete type, fill and read it. The pipeline only carries it.
class BatchExtension {
 public:
  virtual ~BatchExtension() = default;
};

struct StampBatch {
  long long sequence = 0;      // batch number in input order
  long long first_object = 0;  // input index of the first object
  int count = 0;               // objects in this batch
  int stamp_size = 0;
  bool has_weights = false;
  bool weights_are_mask = false;  // has_weights and they only mask pixels (WeightKind::kMask)
  std::vector<double> pixels;   // capacity * stamp_size^2
  std::vector<double> weights;  // same layout when has_weights
  // Per-object PSFs (psf_input = moffat_catalog), any kind: assigning an analytic model allocates
  // nothing; an image model shares its immutable image.
  std::vector<PsfModel> psf;
  std::vector<ObjectRecord> records;  // input identity, then fit results
  ObservationArena observations;      // objects of several observations (stamp_size 0)
  // Survey objects: each one's first problem (why cutouts or the object were not used), "" none;
  // the run reports them in input order.
  std::vector<std::string> problems;
  std::unique_ptr<BatchExtension> extension;  // runs whose task yields other rows (metadetection)
  StampBatch* next = nullptr;         // intrusive link for the writer hand-off

  StampBatch(int capacity, int stamp, bool per_object_psf)
      : stamp_size(stamp),
        pixels(static_cast<std::size_t>(capacity) * stamp * stamp),
        weights(static_cast<std::size_t>(capacity) * stamp * stamp),
        psf(per_object_psf ? capacity : 0),
        records(capacity),
        problems(capacity) {}
  int capacity() const { return static_cast<int>(records.size()); }
  std::size_t npix() const { return static_cast<std::size_t>(stamp_size) * stamp_size; }
  double* stamp(int k) { return pixels.data() + k * npix(); }
  double* weight(int k) { return weights.data() + k * npix(); }
  const double* stamp(int k) const { return pixels.data() + k * npix(); }
  const double* weight(int k) const { return weights.data() + k * npix(); }
};

// The serial input side: fills the next batch (records' identity, pixels, weights, PSFs) and
// returns false at the end of the input. Errors (I/O) throw.
class StampSource {
 public:
  virtual ~StampSource() = default;
  virtual long long total_objects() const = 0;  // -1 if unknown
  // Positions the source so the next batch starts at object `index` (resume).
  virtual void skip_to(long long index) = 0;
  // Reads no object at or after `end` (a shard's end), so that the last batch reads nothing past it.
  virtual void set_end(long long /*end*/) {}
  virtual bool fill(StampBatch& batch) = 0;
};

// The serial output side: receives batches strictly in input order. Errors (I/O) throw.
class BatchSink {
 public:
  virtual ~BatchSink() = default;
  virtual void write(const StampBatch& batch) = 0;
};

}  // namespace stampede
