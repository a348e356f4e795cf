// A metadetection run (app/metadetect_run): the table is byte-identical for one and two threads,
// a stopped run resumes to the uninterrupted table, an image larger than a cell keeps each galaxy
// once, bad input is a clear error naming the file and HDU, or a flagged cell; several bands'
// tiles give per-band columns (the same for any thread count, shards merging to the whole), bands
// that do not match are refused by name, and the input's NOISE plane is fixnoise's field. pgauss
// runs give the same table for any thread count, one band or several, its name in the header; so
// do exp fits (one band; several are refused by name).
#include "app/metadetect_run.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/metadetect_merge.hpp"
#include "io/config_error.hpp"
#include "engine/metadetect/metadetect_row.hpp"
#include "engine/sim/cell_sim.hpp"
#include "io/durable_file.hpp"
#include "io/fits_file.hpp"
#include "io/metadetect_reader.hpp"
#include "support/metadetect_shards.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::app {
namespace {

std::string bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// n cells of the shear test (nearly noise-free) in dir; their paths.
std::vector<std::string> sim_cells(const std::string& dir, int n, CellSimOptions o = {}) {
  o.snr = 1e4;
  CellOutputOptions out;
  out.cells = n;
  // Drawn on one thread: the files are the same for any count, and the simulator's parallel_for
  // hand-offs inside the uninstrumented libtbb would fill a TSan run's report; the run under test
  // is the metadetection.
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  write_cell_simulation(o, out, dir);
  std::vector<std::string> paths;
  for (int k = 0; k < n; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "/cell_%04d.fits", k);
    paths.push_back(dir + name);
  }
  return paths;
}

// Runs `o` on one thread into DIR/one.fits and on two into DIR/two.fits, a cell per batch: the
// tables must be byte-identical, `cells` cells of 49 detections per image, none failed.
void expect_one_table_for_one_and_two_threads(MetadetectRunOptions o, const testing::ScratchDir& dir, int cells) {
  o.output = dir.path("one.fits");
  o.threads = 1;
  o.cells_per_batch = 1;
  const MetadetectRunSummary one = run_metadetect(o);
  EXPECT_EQ(one.cells, cells);
  EXPECT_EQ(one.cells_failed, 0);
  EXPECT_EQ(one.rows, cells * 5 * 49);
  o.output = dir.path("two.fits");
  o.threads = 2;
  run_metadetect(o);
  EXPECT_EQ(bytes(dir.path("one.fits")), bytes(dir.path("two.fits")));
}

TEST(MetadetectRun, TableIsTheSameForOneAndTwoThreads) {
  testing::ScratchDir scratch("stampede_mdet_threads_");
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 4);
  expect_one_table_for_one_and_two_threads(o, scratch, 4);
}

TEST(MetadetectRun, StoppedRunResumesToTheUninterruptedTable) {
  testing::ScratchDir scratch("stampede_mdet_resume_");
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 5);
  o.output = scratch.path("whole.fits");
  o.threads = 1;
  o.cells_per_batch = 1;
  run_metadetect(o);
  o.output = scratch.path("resumed.fits");
  std::atomic<bool> stop{false};
  o.stop = &stop;
  const MetadetectRunSummary first = run_metadetect(o, [&](const MetadetectProgress& p) {
    if (p.cells_done >= 1) stop = true;
  });
  ASSERT_TRUE(first.stopped);
  ASSERT_LT(first.cells, 5);
  EXPECT_TRUE(io::file_exists(o.output + ".partial"));
  EXPECT_FALSE(io::file_exists(o.output));
  stop = false;
  o.stop = nullptr;
  o.resume = true;
  const MetadetectRunSummary second = run_metadetect(o);
  EXPECT_EQ(second.cells_resumed, first.cells);
  EXPECT_EQ(second.cells_resumed + second.cells, 5);
  EXPECT_EQ(bytes(scratch.path("whole.fits")), bytes(scratch.path("resumed.fits")));
  // A complete output has nothing to resume; another run's checkpoint is refused.
  EXPECT_THROW(run_metadetect(o), Error);
}

TEST(MetadetectRun, ImageLargerThanACellKeepsEachGalaxyOnce) {
  testing::ScratchDir scratch("stampede_mdet_cells_");
  CellSimOptions so;
  so.size = 400;  // cut into 2 x 2 cells of 251 with a 34 px buffer
  so.grid = 12;
  const std::vector<std::string> in = sim_cells(scratch.path("sims"), 1, so);
  MetadetectRunOptions o;
  o.inputs = in;
  o.output = scratch.path("out.fits");
  const MetadetectRunSummary r = run_metadetect(o);
  EXPECT_EQ(r.cells, 4);
  io::FitsFile f = io::FitsFile::open_read(o.output);
  f.move_to("METADETECT");
  const std::vector<double> x = f.read_column("x"), y = f.read_column("y"), cell = f.read_column("cell");
  const io::MetadetectTable t = io::read_metadetect_table(o.output);
  const CellSimulator sim(so);
  const std::vector<CellObject> truth = sim.objects(0, so.g1, so.g2);
  for (const CellObject& obj : truth) {
    int found = 0;
    for (std::size_t i = 0; i < x.size(); ++i)
      if (t.shear_type[i] == 0 && std::hypot(x[i] - obj.x, y[i] - obj.y) < 0.5) ++found;
    EXPECT_EQ(found, 1) << "object " << obj.id << " at (" << obj.x << ", " << obj.y << ")";
  }
  EXPECT_EQ(static_cast<int>(std::count(t.shear_type.begin(), t.shear_type.end(), 0)), static_cast<int>(truth.size()));
}

TEST(MetadetectRun, CellTileMeasuresAsItsCellImages) {
  testing::ScratchDir scratch("stampede_mdet_tile_");
  CellSimOptions so;
  so.snr = 1e4;
  CellOutputOptions out;
  out.cells = 3;
  out.tile = true;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // as sim_cells'
    write_cell_simulation(so, out, scratch.path("sims"));
  }
  MetadetectRunOptions o;
  o.inputs = {scratch.path("sims/cell_0000.fits"), scratch.path("sims/cell_0001.fits"), scratch.path("sims/cell_0002.fits")};
  o.output = scratch.path("images.fits");
  run_metadetect(o);
  o.inputs = {scratch.path("sims/cells_meds.fits")};
  o.tile = true;
  o.output = scratch.path("tile.fits");
  EXPECT_EQ(run_metadetect(o).cells, 3);
  io::FitsFile a = io::FitsFile::open_read(scratch.path("images.fits")), b = io::FitsFile::open_read(o.output);
  a.move_to("METADETECT"), b.move_to("METADETECT");
  for (const char* c : {"cell", "e1", "e2", "T", "T_ratio", "snr", "flux", "flags"}) EXPECT_EQ(a.read_column(c), b.read_column(c)) << c;
  // x, y in the tile's pixels: each cell's place in it (a square of 2 x 2 places for 3 cells,
  // adjacent cells overlapping by their buffers).
  const std::vector<double> xa = a.read_column("x"), xb = b.read_column("x"), ya = a.read_column("y"),
                            yb = b.read_column("y"), cell = a.read_column("cell");
  for (std::size_t i = 0; i < xa.size(); ++i) {
    const int k = static_cast<int>(cell[i]);
    EXPECT_NEAR(xb[i] - xa[i], (k % 2) * (251 - 2 * 34), 1e-9);
    EXPECT_NEAR(yb[i] - ya[i], (k / 2) * (251 - 2 * 34), 1e-9);
  }
}

// A cell image written by hand: `extnames` of WEIGHT, BMASK, PSF to include; PSF SCALE psf_scale.
std::string write_image(const std::string& path, int size, const std::vector<std::string>& extnames, double weight = 1.0,
                        double psf_scale = 0.25, double pixel = 0.0) {
  io::FitsFile f = io::FitsFile::create(path, true);
  std::vector<double> image(static_cast<std::size_t>(size) * size, pixel);
  f.write_image(size, size, image);
  f.write_key("SCALE", 0.25, "arcsec per pixel");
  for (const std::string& e : extnames) {
    if (e == "PSF") {
      std::vector<double> psf(25 * 25);
      for (int y = 0; y < 25; ++y)
        for (int x = 0; x < 25; ++x) psf[y * 25 + x] = std::exp(-((x - 12) * (x - 12) + (y - 12) * (y - 12)) / 8.0);
      f.write_image(25, 25, psf, "PSF");
      f.write_key("SCALE", psf_scale, "arcsec per pixel");
    } else {
      f.write_image(size, size, std::vector<double>(image.size(), e == "WEIGHT" ? weight : 0.0), e);
    }
  }
  f.close();
  return path;
}

TEST(MetadetectRun, BadInputIsAClearErrorOrAFlaggedCell) {
  testing::ScratchDir scratch("stampede_mdet_bad_");
  MetadetectRunOptions o;
  o.output = scratch.path("out.fits");
  auto error_of = [&](const std::string& input) {
    o.inputs = {input};
    try {
      run_metadetect(o);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string no_psf = error_of(write_image(scratch.path("nopsf.fits"), 251, {"WEIGHT"}));
  EXPECT_NE(no_psf.find("nopsf.fits"), std::string::npos) << no_psf;
  EXPECT_NE(no_psf.find("no PSF HDU"), std::string::npos) << no_psf;
  const std::string no_weight = error_of(write_image(scratch.path("noweight.fits"), 251, {"PSF"}));
  EXPECT_NE(no_weight.find("no WEIGHT HDU"), std::string::npos) << no_weight;
  const std::string small = error_of(write_image(scratch.path("small.fits"), 60, {"WEIGHT", "PSF"}));
  EXPECT_NE(small.find("small.fits"), std::string::npos) << small;
  EXPECT_NE(small.find("smaller than one cell"), std::string::npos) << small;
  const std::string scale = error_of(write_image(scratch.path("scale.fits"), 251, {"WEIGHT", "PSF"}, 1.0, 0.2));
  EXPECT_NE(scale.find("'PSF'"), std::string::npos) << scale;
  EXPECT_NE(scale.find("pixel scale"), std::string::npos) << scale;
  o.metadetect.cell_buffer = 130;
  const std::string buffer = error_of(write_image(scratch.path("ok.fits"), 251, {"WEIGHT", "PSF"}));
  EXPECT_NE(buffer.find("--cell-buffer"), std::string::npos) << buffer;
  o.metadetect.cell_buffer = 34;
  // Every pixel masked (zero weights), or NaN: one flagged row for the cell, not an empty table.
  for (const std::string name : {"zero.fits", "nan.fits"}) {
    o.inputs = {name == std::string("zero.fits") ? write_image(scratch.path(name), 251, {"WEIGHT", "PSF"}, 0.0)
                                                 : write_image(scratch.path(name), 251, {"WEIGHT", "PSF"}, 1.0, 0.25, NAN)};
    o.overwrite = true;
    const MetadetectRunSummary r = run_metadetect(o);
    EXPECT_EQ(r.cells, 1) << name;
    EXPECT_EQ(r.cells_failed, 1) << name;
    EXPECT_EQ(r.rows, 1) << name;
    ASSERT_EQ(r.problems.size(), 1u) << name;
    EXPECT_NE(r.problems[0].find(name), std::string::npos) << r.problems[0];
    const io::MetadetectTable t = io::read_metadetect_table(o.output);
    ASSERT_EQ(t.flags.size(), 1u);
    EXPECT_EQ(t.flags[0], kMetadetectCellFailed);
  }
}

// Cell tiles of `cells` nearly noise-free cells in bands g and r (sim cells --bands g,r --tile):
// dir/g/cells_meds.fits and dir/r/cells_meds.fits. Band r's galaxies are 1.5 times as bright.
void sim_band_tiles(const std::string& dir, int cells) {
  CellSimOptions so;
  so.snr = 1e4;
  so.bands = 2;
  CellOutputOptions out;
  out.cells = cells;
  out.tile = true;
  out.band_names = {"g", "r"};
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // as sim_cells'
  write_cell_simulation(so, out, dir);
}

TEST(MetadetectRun, BandTilesGiveBandColumnsTheSameForAnyThreadsAndShards) {
  testing::ScratchDir scratch("stampede_mdet_bands_");
  sim_band_tiles(scratch.path("sims"), 3);
  MetadetectRunOptions o;
  o.inputs = {scratch.path("sims/g/cells_meds.fits"), scratch.path("sims/r/cells_meds.fits")};
  o.tile = true;
  o.bands = {"g", "r"};
  expect_one_table_for_one_and_two_threads(o, scratch, 3);
  io::FitsFile f = io::FitsFile::open_read(scratch.path("one.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("BANDS").value_or(""), "g,r");
  const std::vector<double> flux_g = f.read_column("flux_g"), flux_r = f.read_column("flux_r"),
                            snr_g = f.read_column("snr_g"), flags = f.read_column("flags");
  // The bands' images share one reconvolution PSF, so a noise-free galaxy's weighted flux scales
  // with its flux: r/g = 1.5 up to how well each band's sampled PSF image deconvolves (measured:
  // within 1.4e-3 over these 3 cells' 735 rows; band r's PSF is 10 % narrower than g's).
  int usable = 0;
  for (std::size_t i = 0; i < flux_g.size(); ++i) {
    if (flags[i] != 0) continue;
    ++usable;
    EXPECT_NEAR(flux_r[i] / flux_g[i], 1.5, 3e-3) << "row " << i;
    EXPECT_GT(snr_g[i], 1000) << "row " << i;
  }
  EXPECT_GT(usable, 3 * 5 * 40);
  // Shards of a band run merge to its table, band columns included.
  MetadetectMergeOptions mo;
  mo.shards = testing::run_metadetect_shards(o, 2, scratch, "part");
  mo.output = scratch.path("merged.fits");
  merge_metadetect_shards(mo);
  EXPECT_EQ(bytes(scratch.path("merged.fits")), bytes(scratch.path("one.fits")));
}

TEST(MetadetectRun, PgaussTableIsTheSameForOneAndTwoThreadsAndNamesItsMeasurement) {
  testing::ScratchDir scratch("stampede_mdet_pgauss_");
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 2);
  o.metadetect.measurement = MetadetectMeasurement::kPgauss;
  expect_one_table_for_one_and_two_threads(o, scratch, 2);
  io::FitsFile f = io::FitsFile::open_read(scratch.path("one.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("MEASURE").value_or(""), "pgauss");
  EXPECT_EQ(f.read_key_double("WFWHM").value_or(0), 2.0);  // pgauss's default weight
  const std::vector<double> t_ratio = f.read_column("T_ratio"), flags = f.read_column("flags");
  int usable = 0;
  for (std::size_t i = 0; i < flags.size(); ++i) usable += flags[i] == 0 && t_ratio[i] > 0.5;
  EXPECT_GT(usable, 2 * 5 * 45);
}

TEST(MetadetectRun, PgaussBandTilesAreTheSameForOneAndTwoThreads) {
  testing::ScratchDir scratch("stampede_mdet_pgauss_bands_");
  sim_band_tiles(scratch.path("sims"), 2);
  MetadetectRunOptions o;
  o.inputs = {scratch.path("sims/g/cells_meds.fits"), scratch.path("sims/r/cells_meds.fits")};
  o.tile = true;
  o.bands = {"g", "r"};
  o.metadetect.measurement = MetadetectMeasurement::kPgauss;
  expect_one_table_for_one_and_two_threads(o, scratch, 2);
  io::FitsFile f = io::FitsFile::open_read(scratch.path("one.fits"));
  f.move_to("METADETECT");
  const std::vector<double> flux_g = f.read_column("flux_g"), flux_r = f.read_column("flux_r"),
                            flags = f.read_column("flags");
  // The pre-PSF flux of one galaxy in two bands of one Gamma: r/g = 1.5 as for wmom.
  int usable = 0;
  for (std::size_t i = 0; i < flux_g.size(); ++i) {
    if (flags[i] != 0) continue;
    ++usable;
    EXPECT_NEAR(flux_r[i] / flux_g[i], 1.5, 3e-3) << "row " << i;
  }
  EXPECT_GT(usable, 2 * 5 * 40);
}

TEST(MetadetectRun, ExpFitTableIsTheSameForOneAndTwoThreadsAndRefusesBands) {
  testing::ScratchDir scratch("stampede_mdet_exp_");
  CellSimOptions so;
  so.grid = 3;  // 9 galaxies a cell: the fits are the run's cost
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 3, so);
  o.metadetect.measurement = MetadetectMeasurement::kExp;
  o.cells_per_batch = 1;
  o.threads = 1;
  o.output = scratch.path("one.fits");
  const MetadetectRunSummary one = run_metadetect(o);
  EXPECT_EQ(one.cells, 3);
  EXPECT_EQ(one.cells_failed, 0);
  EXPECT_EQ(one.rows, 3 * 5 * 9);
  o.threads = 2;
  o.output = scratch.path("two.fits");
  run_metadetect(o);
  EXPECT_EQ(bytes(scratch.path("one.fits")), bytes(scratch.path("two.fits")));
  io::FitsFile f = io::FitsFile::open_read(scratch.path("one.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("MEASURE").value_or(""), "exp");
  const std::vector<double> flags = f.read_column("flags"), snr = f.read_column("snr");
  for (std::size_t i = 0; i < flags.size(); ++i) {
    EXPECT_EQ(flags[i], 0) << "row " << i;
    EXPECT_GT(snr[i], 1000) << "row " << i;
  }
  // Several bands: refused, naming the measurement.
  sim_band_tiles(scratch.path("bands"), 1);
  MetadetectRunOptions b = o;
  b.inputs = {scratch.path("bands/g/cells_meds.fits"), scratch.path("bands/r/cells_meds.fits")};
  b.tile = true;
  b.output = scratch.path("bands.fits");
  try {
    run_metadetect(b);
    ADD_FAILURE() << "two bands fitted";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--measurement exp fits one band"), std::string::npos) << e.what();
  }
}

TEST(MetadetectRun, BandsThatDoNotMatchTheTilesAreRefusedByName) {
  testing::ScratchDir scratch("stampede_mdet_band_errors_");
  sim_band_tiles(scratch.path("sims"), 2);
  sim_band_tiles(scratch.path("three"), 3);
  const std::string g = scratch.path("sims/g/cells_meds.fits"), r = scratch.path("sims/r/cells_meds.fits");
  auto error_of = [&](std::vector<std::string> inputs, std::vector<std::string> bands, bool tile = true) {
    MetadetectRunOptions o;
    o.inputs = std::move(inputs);
    o.bands = std::move(bands);
    o.tile = tile;
    o.output = scratch.path("out.fits");
    o.overwrite = true;
    try {
      run_metadetect(o);
    } catch (const io::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string count = error_of({g, r}, {"g"});
  EXPECT_NE(count.find("--bands names 1 band but 2 --meds tiles"), std::string::npos) << count;
  const std::string more = error_of({g}, {"g", "r"});
  EXPECT_NE(more.find("--bands names 2 bands but 1 --meds tile"), std::string::npos) << more;
  const std::string cased = error_of({g, r}, {"g", "G"});
  EXPECT_NE(cased.find("bands 'g' and 'G' differ only in case"), std::string::npos) << cased;
  const std::string chars = error_of({g, r}, {"g", "r-band"});
  EXPECT_NE(chars.find("band name 'r-band' is not 1..16 letters"), std::string::npos) << chars;
  const std::string twice = error_of({g, g}, {"g", "r"});
  EXPECT_NE(twice.find("is given twice"), std::string::npos) << twice;
  const std::string images = error_of({scratch.path("sims/g/cell_0000.fits")}, {"g"}, false);
  EXPECT_NE(images.find("--bands names the bands of --meds"), std::string::npos) << images;
  const std::string cells = error_of({g, scratch.path("three/r/cells_meds.fits")}, {"g", "r"});
  EXPECT_NE(cells.find("three/r/cells_meds.fits: 3 cells"), std::string::npos) << cells;
  EXPECT_NE(cells.find("the same cells"), std::string::npos) << cells;
  EXPECT_FALSE(std::filesystem::exists(scratch.path("out.fits")));
}

TEST(MetadetectRun, TheInputsNoisePlaneIsFixnoisesFieldUnlessTurnedOff) {
  testing::ScratchDir scratch("stampede_mdet_noise_");
  const std::vector<std::string> in = sim_cells(scratch.path("sims"), 2);  // with a NOISE HDU each
  MetadetectRunOptions o;
  o.inputs = in;
  o.output = scratch.path("plane.fits");
  run_metadetect(o);
  o.metadetect.noise_plane = false;
  o.output = scratch.path("drawn.fits");
  run_metadetect(o);
  const std::vector<MetadetectRow> plane = io::read_metadetect_rows(scratch.path("plane.fits")),
                                   drawn = io::read_metadetect_rows(scratch.path("drawn.fits"));
  ASSERT_GT(plane.size(), 200u);
  int differ = plane.size() != drawn.size();
  for (std::size_t i = 0; i < std::min(plane.size(), drawn.size()); ++i)
    differ += plane[i].e1 != drawn[i].e1 || plane[i].x != drawn[i].x;
  EXPECT_GT(differ, 100);
  // The header says which: a resumed run with the other choice is another run.
  io::FitsFile f = io::FitsFile::open_read(scratch.path("drawn.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("NOISEPLN").value_or(""), "F");
}

}  // namespace
}  // namespace stampede::app
