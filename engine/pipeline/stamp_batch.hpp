// A batch of objects travelling through the pipeline: the unit of reading, fitting and writing.
// Every object is its observations in the batch's arena: a grid or catalogue stamp is one, in its
// pixel grid; a MEDS object any number (its cutouts over one band or several). Batches are
// allocated once (a fixed pool) and reused, so steady state allocates nothing.
#pragma once

#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/pipeline/object_record.hpp"
#include "engine/pipeline/observation_arena.hpp"

namespace stampede {

struct StampBatch {
  long long sequence = 0;      // batch number in input order
  long long first_object = 0;  // input index of the first object
  int count = 0;               // objects in this batch
  std::vector<ObjectRecord> records;  // input identity, then fit results
  ObservationArena observations;      // every object's observations, in object order
  // Survey objects: each one's first problem (why cutouts or the object were not used), "" none;
  // the run reports them in input order.
  std::vector<std::string> problems;
  StampBatch* next = nullptr;         // intrusive link for the writer hand-off

  explicit StampBatch(int capacity) : records(capacity), problems(capacity) {}
  int capacity() const { return static_cast<int>(records.size()); }
  // Starts filling at input object `first`: no objects, no observations (the storage is kept).
  void begin(long long first) {
    first_object = first;
    count = 0;
    observations.clear();
  }

  // What a kind of run carries beyond the objects' stamps and rows, one type per run: a
  // metadetection batch's cells and the variable number of rows each yields. Made the first time
  // the batch is filled and reused after (the pool is fixed); the run's source, task and sink know
  // the type, the pipeline only carries it. Asking for another type than the batch holds is a
  // logic error, reported rather than cast.
  template <class Payload>
  Payload& payload() {
    if (!payload_) payload_ = std::make_unique<Held<Payload>>();
    return held<Payload>(payload_.get())->value;
  }
  template <class Payload>
  const Payload& payload() const {
    return held<Payload>(payload_.get())->value;
  }

 private:
  struct AnyPayload {
    virtual ~AnyPayload() = default;
  };
  template <class Payload>
  struct Held : AnyPayload {
    Payload value;
  };
  template <class Payload, class Base>
  static auto* held(Base* base) {
    using Target = std::conditional_t<std::is_const_v<Base>, const Held<Payload>, Held<Payload>>;
    auto* p = dynamic_cast<Target*>(base);
    if (p == nullptr) throw std::logic_error("StampBatch: no payload of the type asked for");
    return p;
  }
  std::unique_ptr<AnyPayload> payload_;
};

// The serial input side: fills the next batch (records' identity, the observations) and
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
