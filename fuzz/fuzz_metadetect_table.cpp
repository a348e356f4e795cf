// Fuzz target: the metadetect table reader (io/metadetect_reader) of `metrics --metadetect`, the
// report and merges: the metrics' columns and header, every row with its band columns, the bands.
// A table read must be whole: every column as long as the cell column, every shear type a metacal
// type; else abort, a finding.
#include <cstdlib>
#include <stdexcept>

#include "engine/metacal/metacal_type.hpp"
#include "fuzz/fuzz_file.hpp"
#include "io/metadetect_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    const stampede::io::MetadetectTable t = stampede::io::read_metadetect_table(input.path());
    const std::size_t n = t.cell.size();
    if (t.flags.size() != n || t.shear_type.size() != n || t.e1.size() != n || t.e2.size() != n ||
        t.snr.size() != n || t.t_ratio.size() != n)
      std::abort();
    for (int type : t.shear_type)
      if (type < 0 || type >= stampede::kNumMetacalTypes) std::abort();
    t.key("MEASURE");
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) naming the file, HDU, key or column
  }
  try {
    const auto rows = stampede::io::read_metadetect_rows(input.path());
    (void)rows;
  } catch (const std::runtime_error&) {
  }
  try {
    stampede::io::metadetect_table_bands(input.path());
  } catch (const std::runtime_error&) {
  }
  return 0;
}
