// Fuzz target: a PSF image (psf_input = image, app/psf_setup), read and prepared by the default renderer.
#include <stdexcept>

#include "app/psf_setup.hpp"
#include "fuzz/fuzz_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  const stampede::fuzz::FuzzFile input({data, size});
  stampede::app::RunConfig config;
  stampede::app::set_option(config, "psf_input", "image");
  stampede::app::set_option(config, "psf_image", input.path());
  stampede::FftPlanCache plans(stampede::FftPlanning::kEstimate);
  try {
    stampede::app::build_shared_psf(config, plans);
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) or std::runtime_error naming psf_input or the file
  }
  return 0;
}
