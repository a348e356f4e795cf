// Cell image files and truth tables (io/cell_image_writer): every HDU and truth key reads back.
#include "io/cell_image_writer.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

std::vector<double> as_float(const std::vector<double>& v) {
  std::vector<double> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = static_cast<float>(v[i]);
  return out;
}

TEST(CellImageWriter, WritesImageWeightBmaskNoisePsfAndTruthKeys) {
  testing::ScratchDir dir("cell_image_writer_");
  CellSimOptions o;
  o.size = 64;
  o.buffer = 10;
  o.grid = 2;
  o.psf = CellPsfKind::kMoffat;
  o.psf_size = 33;
  o.seed = 9;
  const CellSimulator sim(o);
  auto ws = sim.make_workspace();
  const SimCell cell = sim.simulate(4, -0.02, 0.01, *ws);
  const std::string path = dir.path("cell.fits");
  write_cell_image(path, sim, cell, 0, "r", false);
  EXPECT_THROW(write_cell_image(path, sim, cell, 0, "r", false), FileError);  // no --overwrite

  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.key_long("BITPIX"), -32);
  EXPECT_EQ(f.read_image(), as_float(cell.bands[0].image));
  EXPECT_EQ(f.key_double("SCALE"), 0.25);
  EXPECT_EQ(f.key_double("G1"), -0.02);
  EXPECT_EQ(f.key_double("G2"), 0.01);
  EXPECT_EQ(f.key_string("PSFTYPE"), "moffat");
  EXPECT_DOUBLE_EQ(f.key_double("PSFFWHM"), 0.9);
  EXPECT_EQ(f.key_double("PSFBETA"), 2.5);
  const double sigma = sim.bands()[0].noise_sigma;
  EXPECT_EQ(f.key_double("NOISESIG"), sigma);
  EXPECT_EQ(f.key_long("SEED"), 9);
  EXPECT_EQ(f.key_long("CELL"), 4);
  EXPECT_EQ(f.key_long("NOBJ"), 4);
  EXPECT_EQ(f.key_string("BAND"), "r");
  f.move_to("WEIGHT");
  EXPECT_EQ(f.read_image(), std::vector<double>(64 * 64, static_cast<float>(1 / (sigma * sigma))));
  f.move_to("BMASK");
  EXPECT_EQ(f.key_long("BITPIX"), 32);
  EXPECT_EQ(f.read_image(), std::vector<double>(64 * 64, 0.0));
  f.move_to("NOISE");
  EXPECT_EQ(f.read_image(), as_float(cell.bands[0].noise));
  f.move_to("PSF");
  EXPECT_EQ(f.image_shape().nx, 33);
  EXPECT_EQ(f.key_double("PSFCEN"), 16.0);
  EXPECT_EQ(f.key_double("SCALE"), 0.25);
  EXPECT_EQ(f.read_image(), as_float(sim.bands()[0].psf));
}

TEST(CellImageWriter, TruthHasARowPerObjectWithTheShear) {
  testing::ScratchDir dir("cell_truth_writer_");
  CellSimOptions o;
  o.bands = 2;
  const CellSimulator sim(o);
  std::vector<CellTruthRow> rows;
  for (int cell = 0; cell < 2; ++cell)
    for (const CellObject& obj : sim.objects(cell, 0.02, 0.0)) rows.push_back({cell, obj});
  const std::string path = dir.path("truth.fits");
  write_cell_truth(path, sim, 0.02, 0.0, rows, {"g", "i"}, false);
  FitsFile f = FitsFile::open_read(path);
  EXPECT_EQ(f.key_double("SHEAR1"), 0.02);
  EXPECT_EQ(f.key_double("SHEAR2"), 0.0);
  EXPECT_EQ(f.key_double("NOISESIG"), sim.bands()[0].noise_sigma);
  f.move_to("TRUTH");
  ASSERT_EQ(f.table_rows(), 98);
  const std::vector<double> cell = f.read_column("cell"), x = f.read_column("x"), e1 = f.read_column("e1_int"),
                            g1 = f.read_column("g1"), flux_i = f.read_column("flux_i");
  for (std::size_t k = 0; k < rows.size(); ++k) {
    EXPECT_EQ(cell[k], rows[k].cell);
    EXPECT_EQ(x[k], rows[k].object.x);
    EXPECT_EQ(e1[k], rows[k].object.e1_int);
    EXPECT_EQ(g1[k], 0.02);
    EXPECT_EQ(flux_i[k], rows[k].object.flux * 1.5);
  }
  for (const char* name : {"id", "y", "flux", "hlr", "bulge_frac", "e2_int", "e1_obs", "e2_obs", "snr", "g2", "flux_g"})
    EXPECT_TRUE(f.has_column(name)) << name;
}

}  // namespace
}  // namespace stampede::io
