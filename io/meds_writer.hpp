// MedsWriter: writes a MEDS 0.9 tile (../shared/reference/survey-formats.md) for simulations
// (`stampede sim meds`) and tests. The layout is fixed up front from the objects' box sizes and
// cutout counts: object_data, image_info and metadata are written at once, the flat cutout arrays
// created at their full length, and each cutout's pixels written into them as they are drawn, so
// memory is one cutout's whatever the tile's size. Written as PATH.partial and renamed by finish():
// a tile is either complete or absent.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "io/meds_file.hpp"

namespace stampede::io {

// What the writer needs of each object: identity, position, box size and cutouts (their file_id,
// positions and Jacobian; start_row is assigned by the writer, in object then cutout order).
struct MedsObjectLayout {
  long long id = 0, number = 0;
  double ra = 0, dec = 0;
  int box_size = 0;
  int psf_size = 0;  // > 0: each cutout has a psf_size^2 PSF image (HDU 'psf'; psf_cutout_row/col in cutouts)
  std::vector<MedsCutout> cutouts;
};

class MedsWriter {
 public:
  // Types other than kImage are written when listed in `types` (kImage always is); `primary_keys`
  // are string keywords (key, value) of the primary header, e.g. a simulation's SIMID. Throws
  // FitsError naming the path when it cannot be created.
  MedsWriter(const std::string& path, std::vector<MedsObjectLayout> objects, const std::vector<MedsImageInfo>& images,
             const std::vector<MedsCutoutType>& types,
             const std::vector<std::pair<std::string, std::string>>& primary_keys = {});
  ~MedsWriter();
  MedsWriter(const MedsWriter&) = delete;
  MedsWriter& operator=(const MedsWriter&) = delete;

  // Cutout `icut` of object `row` of one type: box_size^2 values (seg and bmask are stored as
  // integers). Any order.
  void write_cutout(long long row, int icut, MedsCutoutType type, std::span<const double> pixels);
  // Cutout `icut`'s PSF image (psf_size^2 values) of object `row`, when the layout has PSF images.
  void write_psf_cutout(long long row, int icut, std::span<const double> samples);
  // Closes the file and renames it into place.
  void finish();

 private:
  struct State;
  std::unique_ptr<State> s_;
};

// Writes a PSFEx model file with a constant PSF (degree 0): one basis image of nx x ny samples at
// the data's pitch (PSF_SAMP = 1), centred on sample (nx / 2, ny / 2), `fwhm` in pixels as PSF_FWHM.
void write_psfex_constant(const std::string& path, int nx, int ny, std::span<const double> samples, double fwhm);

}  // namespace stampede::io
