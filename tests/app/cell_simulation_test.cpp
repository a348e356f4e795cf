// `stampede sim cells` on disk (app/cell_simulation): the cell tile reads back through MedsFile as
// the cell images, a shear pair's files share galaxies and noise, bands land in their
// directories, the files are identical for 1 and 2 threads, and existing outputs are refused.
#include "app/cell_simulation.hpp"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "io/meds_file.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::app {
namespace {

namespace fs = std::filesystem;

std::vector<double> read_hdu(const std::string& path, const std::string& hdu) {
  io::FitsFile f = io::FitsFile::open_read(path);
  if (hdu.empty()) {
    f.move_to(0);
  } else {
    f.move_to(hdu);
  }
  return f.read_image();
}

std::string bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

CellSimOptions small() {
  CellSimOptions o;
  o.size = 96;
  o.buffer = 12;
  o.grid = 3;
  o.psf_size = 33;
  return o;
}

TEST(CellSimulation, CellTileRoundTripsThroughMedsFile) {
  testing::ScratchDir dir("cell_tile_");
  CellOutputOptions out;
  out.cells = 3;
  out.tile = true;
  const CellSimOptions o = small();
  write_cell_simulation(o, out, dir.dir().string());
  io::MedsFile tile = io::MedsFile::open(dir.path("cells_meds.fits"));
  ASSERT_EQ(tile.size(), 3);
  ASSERT_TRUE(tile.has_psf_cutouts()) << tile.psf_cutouts_problem();
  for (io::MedsCutoutType t : {io::MedsCutoutType::kWeight, io::MedsCutoutType::kSeg, io::MedsCutoutType::kBmask,
                               io::MedsCutoutType::kNoise})
    EXPECT_TRUE(tile.has(t)) << io::meds_hdu_name(t);
  ASSERT_EQ(tile.images().size(), 1u);
  EXPECT_EQ(tile.images()[0].magzp, 30);
  EXPECT_EQ(tile.images()[0].position_offset, 1);
  std::vector<double> pixels(96 * 96), psf(33 * 33);
  for (long long row = 0; row < 3; ++row) {
    const io::MedsObject obj = tile.object(row);
    ASSERT_TRUE(obj.problem.empty()) << obj.problem;
    EXPECT_EQ(obj.id, row + 1);
    EXPECT_EQ(obj.box_size, 96);
    ASSERT_EQ(obj.cutouts.size(), 1u);
    const io::MedsCutout& c = obj.cutouts[0];
    EXPECT_EQ(c.cutout_row, 47.5);
    EXPECT_EQ(c.dudcol, 0.25);
    EXPECT_EQ(c.dvdrow, 0.25);
    EXPECT_EQ(c.dudrow, 0.0);
    const std::string cell = dir.path("cell_000" + std::to_string(row) + ".fits");
    const std::pair<io::MedsCutoutType, const char*> planes[] = {
        {io::MedsCutoutType::kImage, ""}, {io::MedsCutoutType::kWeight, "WEIGHT"},
        {io::MedsCutoutType::kBmask, "BMASK"}, {io::MedsCutoutType::kNoise, "NOISE"}};
    for (const auto& [type, hdu] : planes) {
      tile.read_cutout(obj, 0, type, pixels);
      EXPECT_EQ(pixels, read_hdu(cell, hdu)) << io::meds_hdu_name(type) << " of cell " << row;
    }
    ASSERT_TRUE(c.psf_problem.empty()) << c.psf_problem;
    EXPECT_EQ(c.psf_rows, 33);
    EXPECT_EQ(c.psf_cutout_row, 16);
    tile.read_psf_cutout(obj, 0, psf);
    EXPECT_EQ(psf, read_hdu(cell, "PSF"));
  }
  // Adjacent cells on the notional tile overlap by their buffers.
  EXPECT_EQ(tile.object(1).cutouts[0].orig_start_col - tile.object(0).cutouts[0].orig_start_col, 96 - 24);
}

TEST(CellSimulation, ShearPairAndBandsLayout) {
  testing::ScratchDir dir("cell_pair_");
  CellOutputOptions out;
  out.cells = 2;
  out.pair = true;
  out.tile = true;
  out.band_names = {"g", "r"};
  CellSimOptions o = small();
  o.bands = 2;
  const std::string d = dir.dir().string();
  write_cell_simulation(o, out, d);
  for (const std::string& p : cell_simulation_outputs(o, out, d)) EXPECT_TRUE(fs::exists(p)) << p;
  EXPECT_TRUE(fs::exists(d + "/minus/r/cells_meds.fits"));
  EXPECT_TRUE(fs::exists(d + "/minus/truth.fits"));
  for (const char* band : {"g", "r"}) {
    const std::string plus = d + "/" + band + "/cell_0001.fits", minus = d + "/minus/" + band + "/cell_0001.fits";
    EXPECT_EQ(read_hdu(plus, "NOISE"), read_hdu(minus, "NOISE")) << band;
    EXPECT_NE(read_hdu(plus, ""), read_hdu(minus, "")) << band;
    io::FitsFile p = io::FitsFile::open_read(plus), m = io::FitsFile::open_read(minus);
    EXPECT_EQ(p.key_double("G1"), 0.02);
    EXPECT_EQ(m.key_double("G1"), -0.02);
    EXPECT_EQ(p.key_string("BAND"), band);
  }
  io::FitsFile tp = io::FitsFile::open_read(d + "/truth.fits"), tm = io::FitsFile::open_read(d + "/minus/truth.fits");
  EXPECT_EQ(tp.key_double("SHEAR1"), -tm.key_double("SHEAR1"));
  tp.move_to("TRUTH");
  tm.move_to("TRUTH");
  EXPECT_EQ(tp.table_rows(), 18);
  for (const char* col : {"cell", "e1_int", "e2_int", "flux", "flux_r"})
    EXPECT_EQ(tp.read_column(col), tm.read_column(col)) << col;
  // The shear acts on the whole scene: shapes and positions differ between the two signs.
  EXPECT_NE(tp.read_column("e1_obs"), tm.read_column("e1_obs"));
  EXPECT_NE(tp.read_column("x"), tm.read_column("x"));
}

TEST(CellSimulation, SameFilesForOneAndTwoThreads) {
  testing::ScratchDir dir("cell_threads_");
  CellOutputOptions out;
  out.cells = 5;
  out.pair = true;
  out.tile = true;
  CellSimOptions o = small();
  o.layout = CellLayout::kRandom;
  const std::string one = dir.path("one"), two = dir.path("two");
  tbb::task_arena(1).execute([&] { write_cell_simulation(o, out, one); });
  tbb::task_arena(2).execute([&] { write_cell_simulation(o, out, two); });
  const std::vector<std::string> a = cell_simulation_outputs(o, out, one), b = cell_simulation_outputs(o, out, two);
  ASSERT_EQ(a.size(), 5u * 2 + 2 + 2);
  for (std::size_t k = 0; k < a.size(); ++k) {
    const std::string x = bytes(a[k]);
    EXPECT_FALSE(x.empty()) << a[k];
    EXPECT_TRUE(x == bytes(b[k])) << a[k] << " differs from " << b[k];
  }
}

// Overwritten with fewer cells and no tile, the directory holds this run's cells alone: an earlier
// run's extra cells (and its tile) would be measured as this simulation's.
TEST(CellSimulation, OverwriteWithFewerCellsLeavesNoEarlierCell) {
  testing::ScratchDir dir("cell_fewer_");
  CellOutputOptions out;
  out.cells = 3;
  out.tile = true;
  const CellSimOptions o = small();
  write_cell_simulation(o, out, dir.dir().string());
  std::ofstream(dir.path("cell_notes.txt")) << "kept";
  out.cells = 1;
  out.tile = false;
  out.overwrite = true;
  write_cell_simulation(o, out, dir.dir().string());
  EXPECT_TRUE(fs::exists(dir.path("cell_0000.fits")));
  EXPECT_FALSE(fs::exists(dir.path("cell_0001.fits")));
  EXPECT_FALSE(fs::exists(dir.path("cell_0002.fits")));
  EXPECT_FALSE(fs::exists(dir.path("cells_meds.fits")));
  EXPECT_TRUE(fs::exists(dir.path("cell_notes.txt")));  // not a cell: left alone
}

TEST(CellSimulation, RefusesExistingOutputsAndBadOptions) {
  testing::ScratchDir dir("cell_refuse_");
  CellOutputOptions out;
  const CellSimOptions o = small();
  write_cell_simulation(o, out, dir.dir().string());
  try {
    write_cell_simulation(o, out, dir.dir().string());
    ADD_FAILURE() << "an existing cell was replaced without overwrite";
  } catch (const io::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("use --overwrite"), std::string::npos) << e.what();
  }
  out.overwrite = true;
  EXPECT_NO_THROW(write_cell_simulation(o, out, dir.dir().string()));
  auto message = [&](CellOutputOptions bad, CellSimOptions opts) {
    try {
      write_cell_simulation(opts, bad, dir.path("bad"));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CellOutputOptions zero = out;
  zero.cells = 0;
  EXPECT_NE(message(zero, o).find("cells 0"), std::string::npos);
  CellOutputOptions twice = out;
  twice.band_names = {"r", "r"};
  CellSimOptions two = o;
  two.bands = 2;
  EXPECT_NE(message(twice, two).find("band_names: band 'r' is given twice"), std::string::npos);
  CellOutputOptions odd = out;
  odd.band_names = {"r-1"};
  EXPECT_NE(message(odd, o).find("band_names"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir.path("bad")));
}

}  // namespace
}  // namespace stampede::app
