// Fuzz target: the ini parser and validation of the run configuration (app/run_config over io/option_registry). A file
// that loads must also print back in canonical form that parses to the identical text.
#include <cstdlib>
#include <stdexcept>

#include "fuzz/fuzz_file.hpp"
#include "app/run_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile ini({data, size});
  stampede::app::RunConfig config;
  try {
    stampede::app::load_ini(config, ini.path());
  } catch (const stampede::io::ConfigError&) {
    return 0;
  }
  for (const auto& [key, value] : stampede::app::effective_options(config)) {
    stampede::app::RunConfig again;
    stampede::app::set_option(again, key, value);  // a canonical value that does not parse is a finding
    if (stampede::app::get_option(again, key) != value) std::abort();
  }
  try {
    stampede::app::validate(config);
    stampede::app::save_image_ids(config);
  } catch (const stampede::io::ConfigError&) {
  }
  return 0;
}
