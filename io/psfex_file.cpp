// PSFEx model files; see psfex_file.hpp.
#include "io/psfex_file.hpp"

#include "io/fits_file.hpp"

namespace stampede::io {

PsfexModel read_psfex_model(const std::string& path) {
  FitsFile f = FitsFile::open_read(path);
  if (!f.move_to_if_present("PSF_DATA")) throw FitsError(path + ": not a PSFEx model: no HDU 'PSF_DATA'");
  auto require = [&](bool ok, const std::string& what) {
    if (!ok) throw FitsError(f.describe() + ": " + what);
  };
  // One polynomial group in the two SExtractor positions: what PSFEx writes for a per-image model.
  require(f.key_long("POLNAXIS") == 2, "POLNAXIS = " + std::to_string(f.key_long("POLNAXIS")) +
                                           ": only models in two context parameters (X_IMAGE, Y_IMAGE) are read");
  require(f.key_long("POLNGRP") == 1, "POLNGRP = " + std::to_string(f.key_long("POLNGRP")) + ": only one polynomial group is read");
  for (const char* key : {"POLNAME1", "POLNAME2"}) {
    const std::string name = f.key_string(key);
    const std::string want = key[7] == '1' ? "X_IMAGE" : "Y_IMAGE";
    require(name == want, std::string(key) + " = '" + name + "': expected '" + want + "'");
  }
  require(f.key_long("PSFNAXIS") == 3, "PSFNAXIS = " + std::to_string(f.key_long("PSFNAXIS")) + ": expected 3");
  PsfexModel m;
  const long long degree = f.key_long("POLDEG1");
  require(degree >= 0 && degree <= 20, "POLDEG1 = " + std::to_string(degree) + ": must be in [0, 20]");
  m.degree = static_cast<int>(degree);
  m.zero_x = f.key_double("POLZERO1");
  m.zero_y = f.key_double("POLZERO2");
  m.scale_x = f.key_double("POLSCAL1");
  m.scale_y = f.key_double("POLSCAL2");
  m.sampling = f.key_double("PSF_SAMP");
  const long long ax1 = f.key_long("PSFAXIS1"), ax2 = f.key_long("PSFAXIS2"), ax3 = f.key_long("PSFAXIS3");
  require(ax1 >= 1 && ax1 <= 4096 && ax2 >= 1 && ax2 <= 4096,
          "PSFAXIS1 x PSFAXIS2 = " + std::to_string(ax1) + " x " + std::to_string(ax2) + ": must be 1..4096 each");
  require(ax3 == PsfexModel::terms_for_degree(m.degree),
          "PSFAXIS3 = " + std::to_string(ax3) + " basis images, but POLDEG1 = " + std::to_string(degree) + " needs " +
              std::to_string(PsfexModel::terms_for_degree(m.degree)));
  m.nx = static_cast<int>(ax1);
  m.ny = static_cast<int>(ax2);
  require(f.table_rows() >= 1, "no rows (the model is row 1)");
  const long long values = ax1 * ax2 * ax3;
  const long long repeat = f.column_repeat("PSF_MASK");
  require(repeat == values, "column 'PSF_MASK' holds " + std::to_string(repeat) + " values per row, but PSFAXIS1 x 2 x 3 = " +
                                std::to_string(values));
  m.basis.resize(static_cast<std::size_t>(values));
  f.read_vector_rows("PSF_MASK", 0, m.basis);
  std::string why;
  require(m.IsValid(&why), why);
  return m;
}

}  // namespace stampede::io
