// The schemas' shared table handling; see table_writer.hpp.
#include "io/table_writer.hpp"

#include "io/durable_table.hpp"

namespace stampede::io {

TableWriter::TableWriter() = default;
TableWriter::~TableWriter() = default;

void TableWriter::open(const DurableTableOptions& options, bool resume) {
  if (!resume) {
    table_ = DurableTable::create(options);
    return;
  }
  DurableTable::Committed committed;
  table_ = DurableTable::resume(options, &committed);
  started_afresh_ = committed.fresh;
}

void TableWriter::finish() { table_->finish(); }
void TableWriter::abandon() noexcept { table_->abandon(); }
long long TableWriter::rows() const { return table_->rows(); }
long long TableWriter::units() const { return table_->units(); }

}  // namespace stampede::io
