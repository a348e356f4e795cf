// Fuzz target: the ini parser and validation of the run configuration (io/run_config). A file
// that loads must also print back in canonical form that parses to the identical text.
#include <cstdlib>
#include <stdexcept>

#include "fuzz/fuzz_file.hpp"
#include "io/run_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile ini({data, size});
  stampede::io::RunConfig config;
  try {
    stampede::io::load_ini(config, ini.path());
  } catch (const stampede::io::ConfigError&) {
    return 0;
  }
  for (const auto& [key, value] : stampede::io::effective_options(config)) {
    stampede::io::RunConfig again;
    stampede::io::set_option(again, key, value);  // a canonical value that does not parse is a finding
    if (stampede::io::get_option(again, key) != value) std::abort();
  }
  try {
    stampede::io::validate(config);
    stampede::io::save_image_ids(config);
  } catch (const stampede::io::ConfigError&) {
  }
  return 0;
}
