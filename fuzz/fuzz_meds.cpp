// Fuzz target: a MEDS tile (io/meds_file): the layout checks at open, every object row, and every
// usable cutout of every present type, as `stampede fit --meds` will read them.
#include <stdexcept>
#include <vector>

#include "fuzz/fuzz_file.hpp"
#include "io/meds_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const unsigned char* data, std::size_t size) {
  using namespace stampede::io;
  const stampede::fuzz::FuzzFile input({data, size});
  try {
    MedsFile m = MedsFile::open(input.path());
    std::vector<double> pixels;
    for (long long row = 0; row < m.size() && row < 64; ++row) {
      const MedsObject o = m.object(row);
      if (!o.problem.empty()) continue;
      for (int k = 0; k < static_cast<int>(o.cutouts.size()); ++k) {
        if (!o.cutouts[static_cast<std::size_t>(k)].problem.empty()) continue;
        // Sized only for a usable cutout, whose pixels the arrays hold (as io/meds_object_source
        // does): a box size alone is a claim (harness finding H5: 2 GB for a 16384 box).
        pixels.resize(static_cast<std::size_t>(o.box_size * o.box_size));
        for (int t = 0; t < kNumMedsCutoutTypes; ++t)
          if (m.has(static_cast<MedsCutoutType>(t))) m.read_cutout(o, k, static_cast<MedsCutoutType>(t), pixels);
        const MedsCutout& c = o.cutouts[static_cast<std::size_t>(k)];
        if (m.has_psf_cutouts() && c.psf_problem.empty()) {
          pixels.resize(static_cast<std::size_t>(c.psf_rows * c.psf_cols));
          m.read_psf_cutout(o, k, pixels);
        }
      }
    }
  } catch (const std::runtime_error&) {
    // stampede::Error (FitsError) naming the file, HDU, column or object
  }
  return 0;
}
