// Fuzz target: the result-table reader (io/catalog_reader) of `metrics`, `calibrate apply` and merges:
// every column of the schema, by column and as records.
#include <algorithm>
#include <stdexcept>

#include "fuzz/fuzz_file.hpp"
#include "io/catalog_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    auto reader = stampede::io::CatalogReader::open(input.path());
    const long long rows = reader.rows();
    for (int i = 0; i < stampede::io::kNumResultFields; ++i) {
      const auto field = static_cast<stampede::io::ResultField>(i);
      if (reader.has(field)) reader.column(field);
    }
    reader.records(0, std::min<long long>(rows, 64));
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) naming the file, HDU or column
  }
  return 0;
}
