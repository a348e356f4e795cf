// Reads back what io/metadetect_writer wrote: the columns `stampede metrics --metadetect` needs, the
// run's metacal step (header key MCSTEP) and its header's keys (the options, the inputs and their
// digests, what the inputs record of their scene). Throws FitsError naming the file, HDU and column.
#pragma once
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "engine/metadetect/metadetect_row.hpp"

namespace stampede::io {

struct MetadetectTable {
  std::vector<long long> cell, flags;
  std::vector<int> shear_type;  // MetacalType
  std::vector<double> e1, e2, snr, t_ratio, mfrac;
  double step = 0;
  std::string path;
  // Every keyword card of the table's HDU but its structure (TTYPEn, NAXIS2, ...), in order.
  std::vector<std::pair<std::string, std::string>> header;
  // The value of header key `key`, or nullopt.
  std::optional<std::string> key(const std::string& key) const;
};

MetadetectTable read_metadetect_table(const std::string& path);

// The band names of header key BANDS ("g,r"; empty: none).
std::vector<std::string> metadetect_table_bands(const std::string& path);

// Every row with every column (a shard's, for a merge), the bands' flux_<band> and snr_<band> too.
std::vector<MetadetectRow> read_metadetect_rows(const std::string& path);

// The same in chunks of rows, so a table of any size can be rewritten in bounded memory.
class MetadetectRowReader {
 public:
  explicit MetadetectRowReader(const std::string& path);
  ~MetadetectRowReader();
  long long rows() const;
  const std::vector<std::string>& bands() const;  // header key BANDS's
  // Rows [first, first + n) into *out (resized to n).
  void read(long long first, std::size_t n, std::vector<MetadetectRow>* out);

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace stampede::io
