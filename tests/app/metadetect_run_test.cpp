// A metadetection run (app/metadetect_run): the table is byte-identical for one and two threads,
// a stopped run resumes to the uninterrupted table, an image larger than a cell keeps each galaxy
// once, bad input is a clear error naming the file and HDU, or a flagged cell; several bands'
// tiles give per-band columns (the same for any thread count, shards merging to the whole), bands
// that do not match are refused by name, and the input's NOISE plane is fixnoise's field. Image
// files of several bands ({band} templates) measure as the same bands' tiles, files that do not
// match are refused by name; a PSFEx model (--psfex) of the PSF HDU's PSF measures as the PSF HDU,
// a varying one gives each cell its own PSF, and a bad one is refused by name. pgauss runs give
// the same table for any thread count, one band or several, its name in the header; so do exp
// fits (one band; several are refused by name).
#include "app/metadetect_run.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "app/cell_simulation.hpp"
#include "app/shard_merge.hpp"
#include "io/celestial_wcs.hpp"
#include "io/cell_image_reader.hpp"
#include "io/config_error.hpp"
#include "engine/metadetect/metadetect_row.hpp"
#include "engine/sim/cell_sim.hpp"
#include "io/durable_file.hpp"
#include "io/fits_error.hpp"
#include "io/meds_writer.hpp"
#include "io/psfex_file.hpp"
#include "io/star_catalogue.hpp"
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

// The simulation drawn on one thread: the files are the same for any count, and the simulator's
// parallel_for hand-offs inside the uninstrumented libtbb would fill a TSan run's report; the run
// under test is the metadetection.
void simulate_on_one_thread(const CellSimOptions& so, const CellOutputOptions& out, const std::string& dir) {
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  write_cell_simulation(so, out, dir);
}

// n cells of the shear test (nearly noise-free) and their shear pairs in dir (minus/ the -g ones).
void simulate_pairs(CellSimOptions so, int n, const std::string& dir) {
  so.snr = 1e4;
  CellOutputOptions out;
  out.cells = n;
  out.pair = true;
  simulate_on_one_thread(so, out, dir);
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

// The rows of a table the estimator keeps (flags 0, S/N > 10): the grid's galaxies, without the
// noise peaks that detection at 0.8 sigma also finds between them (S/N ~ 2-6).
long long galaxy_rows(const std::string& path) {
  const io::MetadetectTable t = io::read_metadetect_table(path);
  long long n = 0;
  for (std::size_t i = 0; i < t.snr.size(); ++i) n += t.flags[i] == 0 && t.snr[i] > 10;
  return n;
}

// Runs `o` on one thread into DIR/one.fits and on two into DIR/two.fits, a cell per batch: the
// tables must be byte-identical, `cells` cells of 49 galaxies per image, none failed.
void expect_one_table_for_one_and_two_threads(MetadetectRunOptions o, const testing::ScratchDir& dir, int cells) {
  o.output = dir.path("one.fits");
  o.threads = 1;
  o.cells_per_batch = 1;
  const MetadetectRunSummary one = run_metadetect(o);
  EXPECT_EQ(one.cells, cells);
  EXPECT_EQ(one.cells_failed, 0);
  EXPECT_EQ(galaxy_rows(o.output), cells * 5 * 49);
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

TEST(MetadetectRun, DeepBlendedCellsGiveOneTableForOneAndTwoThreadsWithEitherDetector) {
  // The reference test's random cells at S/N 1e6: most galaxies one segment, deblended. Our
  // detector and SEP's each give one table for any thread count; the two tables have the same rows
  // (positions to float rounding: docs/metadetect.md, "Detection").
  testing::ScratchDir scratch("stampede_mdet_deep_");
  CellSimOptions so;
  so.layout = CellLayout::kRandom, so.reference_positions = true, so.shape_noise = 0, so.psf_size = 53;
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 3, so);
  std::vector<std::vector<MetadetectRow>> tables;
  for (DetectorKind d : {DetectorKind::kTree, DetectorKind::kSep}) {
    o.metadetect.detection.detector = d;
    const std::string name = detector_kind_name(d);
    o.output = scratch.path(name + "_one.fits");
    o.threads = 1;
    o.cells_per_batch = 1;
    EXPECT_EQ(run_metadetect(o).cells_failed, 0);
    o.output = scratch.path(name + "_two.fits");
    o.threads = 2;
    run_metadetect(o);
    EXPECT_EQ(bytes(scratch.path(name + "_one.fits")), bytes(scratch.path(name + "_two.fits"))) << name;
    tables.push_back(io::read_metadetect_rows(o.output));
  }
  const std::vector<MetadetectRow> &tree = tables[0], &sep = tables[1];
  ASSERT_EQ(tree.size(), sep.size());
  std::size_t merged = 0;
  for (std::size_t i = 0; i < tree.size(); ++i) {
    EXPECT_EQ(tree[i].cell, sep[i].cell);
    EXPECT_EQ(tree[i].shear_type, sep[i].shear_type);
    EXPECT_NEAR(tree[i].x, sep[i].x, 1e-5) << "row " << i;
    EXPECT_NEAR(tree[i].y, sep[i].y, 1e-5) << "row " << i;
    EXPECT_EQ(tree[i].flags, sep[i].flags) << "row " << i;
    if (tree[i].flags == 0) {
      EXPECT_NEAR(tree[i].e1, sep[i].e1, 1e-6) << "row " << i;
    }
    merged += tree[i].sep_flags & 1;
  }
  EXPECT_GT(merged, tree.size() / 2) << "the cells are meant to be blended";
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
  o.progress_interval = 0;
  o.on_progress = [&](const RunProgress& p) {
    if (p.done >= 1) stop = true;
  };
  const MetadetectRunSummary first = run_metadetect(o);
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
  // A complete output of this run is skipped, as fit skips one (it used to be an error); another
  // run's complete table is refused and left as it is.
  const std::string done = bytes(o.output);
  EXPECT_TRUE(run_metadetect(o).skipped);
  MetadetectRunOptions other = o;
  other.metadetect.seed += 1;
  try {
    run_metadetect(other);
    ADD_FAILURE() << "another run's complete table was not refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is complete but was written by another run"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("(MCSEED = '"), std::string::npos) << e.what();  // naming what differs
  }
  EXPECT_EQ(bytes(o.output), done);
}

TEST(MetadetectRun, TheReconvolutionRuleTheStampAndTheWeightAreRecordedAndIdentifyTheRun) {
  // The header records Gamma's rule, the stamp size and the weight's centring; a run stopped with
  // one setting does not resume with another.
  testing::ScratchDir scratch("stampede_mdet_settings_");
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 2);
  o.output = scratch.path("default.fits");
  run_metadetect(o);
  io::FitsFile d = io::FitsFile::open_read(o.output);
  d.move_to("METADETECT");
  EXPECT_EQ(d.read_key_string("MCRECONV").value_or(""), "auto");
  EXPECT_EQ(d.read_key_double("STAMPSZ").value_or(-1), 32);
  EXPECT_EQ(d.read_key_string("RECENTRE").value_or(""), "F");
  const std::vector<double> box = d.read_column("box_size");
  for (double b : box) EXPECT_EQ(b, 32);
  MetadetectRunOptions m = o;
  m.metadetect.reconvolution = ReconvolutionRule::kMoffat;
  m.metadetect.stamp.size = 0;
  m.metadetect.recentre = true;
  m.output = scratch.path("moffat.fits");
  m.threads = 1;
  m.cells_per_batch = 1;
  std::atomic<bool> stop{false};
  m.stop = &stop;
  m.progress_interval = 0;
  m.on_progress = [&](const RunProgress& p) {
    if (p.done >= 1) stop = true;
  };
  run_metadetect(m);
  io::FitsFile p = io::FitsFile::open_read(m.output + ".partial");
  p.move_to("METADETECT");
  EXPECT_EQ(p.read_key_string("MCRECONV").value_or(""), "moffat");
  EXPECT_EQ(p.read_key_double("STAMPSZ").value_or(-1), 0);
  EXPECT_EQ(p.read_key_string("RECENTRE").value_or(""), "T");
  MetadetectRunOptions r = o;
  r.output = m.output;
  r.resume = true;
  EXPECT_THROW(run_metadetect(r), Error);
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
                        double psf_scale = 0.25, double pixel = 0.0, double scale = 0.25) {
  io::FitsFile f = io::FitsFile::create(path, true);
  std::vector<double> image(static_cast<std::size_t>(size) * size, pixel);
  f.write_image(size, size, image);
  f.write_key("SCALE", scale, "arcsec per pixel");
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
  EXPECT_EQ(no_psf.find("'WEIGHT'"), std::string::npos) << no_psf;  // named at the file, not its last HDU read
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
  // The core names the field (Python's keyword), not a command-line flag.
  EXPECT_NE(buffer.find("cell_buffer = 130"), std::string::npos) << buffer;
  EXPECT_EQ(buffer.find("--cell-buffer"), std::string::npos) << buffer;
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
    // Told apart: the pixels' values, not the weights, are what is wrong in nan.fits.
    EXPECT_NE(r.problems[0].find(name == std::string("zero.fits") ? "63001 of zero weight)" : "63001 NaN or infinite)"),
              std::string::npos) << r.problems[0];
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

// An image with a PSF HDU of `psf` (nx x ny), a WEIGHT of 1 and, when `noise_rms` > 0, a NOISE
// plane of that rms (alternating signs); `weights` WEIGHT HDUs.
std::string write_planes(const std::string& path, int nx, int ny, double psf_dx, double noise_rms, int weights = 1,
                         double sky = 0) {
  io::FitsFile f = io::FitsFile::create(path, true);
  const int size = 251;
  f.write_image(size, size, std::vector<double>(static_cast<std::size_t>(size) * size, sky));
  f.write_key("SCALE", 0.25, "arcsec per pixel");
  for (int k = 0; k < weights; ++k) f.write_image(size, size, std::vector<double>(static_cast<std::size_t>(size) * size, 1.0), "WEIGHT");
  if (noise_rms > 0) {
    std::vector<double> noise(static_cast<std::size_t>(size) * size);
    for (std::size_t i = 0; i < noise.size(); ++i) noise[i] = (i % 2 ? 1 : -1) * noise_rms;
    f.write_image(size, size, noise, "NOISE");
  }
  std::vector<double> psf(static_cast<std::size_t>(nx) * ny);
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) {
      const double dx = x - 0.5 * (nx - 1) - psf_dx, dy = y - 0.5 * (ny - 1);
      psf[static_cast<std::size_t>(y) * nx + x] = std::exp(-(dx * dx + dy * dy) / 8.0);
    }
  f.write_image(nx, ny, psf, "PSF");
  f.close();
  return path;
}

// Inputs that would give plausible numbers with exit 0 are refused naming the file, HDU and rule:
// an even or off-centre PSF, a NOISE plane that is not the weights' noise, a plane given twice, the
// same image twice; a weight no cell can use, or a sky not subtracted, fails every cell with its reason (each counted, the
// cells sharing the PSF included), and a cell with almost no interior is refused.
TEST(MetadetectRun, PlausibleBadInputIsRefusedOrEveryCellCounted) {
  testing::ScratchDir scratch("stampede_mdet_plausible_");
  MetadetectRunOptions o;
  o.output = scratch.path("out.fits");
  o.threads = 1;
  auto error_of = [&](std::vector<std::string> inputs) {
    o.inputs = std::move(inputs);
    try {
      run_metadetect(o);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string even = error_of({write_planes(scratch.path("even.fits"), 24, 25, 0, 0)});
  EXPECT_NE(even.find("'PSF'"), std::string::npos) << even;
  EXPECT_NE(even.find("24 x 25 pixels: its sides must be odd"), std::string::npos) << even;
  const std::string off = error_of({write_planes(scratch.path("off.fits"), 25, 25, 1.5, 0)});
  EXPECT_NE(off.find("centroid is (1.5, 0) pixels from its middle pixel"), std::string::npos) << off;
  const std::string noise = error_of({write_planes(scratch.path("noise.fits"), 25, 25, 0, 100)});
  EXPECT_NE(noise.find("'NOISE'"), std::string::npos) << noise;
  EXPECT_NE(noise.find("rms is 100 times the noise the weights state"), std::string::npos) << noise;
  const std::string twice = error_of({write_planes(scratch.path("two_weights.fits"), 25, 25, 0, 0, 2)});
  EXPECT_NE(twice.find("a second WEIGHT HDU"), std::string::npos) << twice;
  // The same image twice: as given twice, through a link, spelt otherwise, or copied.
  const std::string good = write_planes(scratch.path("good.fits"), 25, 25, 0, 1);
  std::filesystem::create_symlink(good, scratch.path("link.fits"));
  std::filesystem::copy_file(good, scratch.path("copy.fits"));
  for (const std::string& again : {good, scratch.path("link.fits"), scratch.dir().string() + "/./good.fits", scratch.path("copy.fits")}) {
    const std::string e = error_of({good, again});
    EXPECT_NE(e.find("holds the same bytes as '" + good + "'"), std::string::npos) << again << ": " << e;
  }
  EXPECT_FALSE(std::filesystem::exists(o.output));
  // A weight narrower than half a pixel or wider than half the cell: every cell fails, saying why.
  const std::vector<std::string> cells = sim_cells(scratch.path("sims"), 3);
  for (const double fwhm : {1e-6, 1000.0}) {
    o.inputs = cells;
    o.metadetect.weight_fwhm = fwhm;
    o.overwrite = true;
    const MetadetectRunSummary r = run_metadetect(o);
    EXPECT_EQ(r.cells_failed, 3) << fwhm;
    ASSERT_EQ(r.problems.size(), 3u) << fwhm;
    for (const std::string& p : r.problems) EXPECT_NE(p.find("weight_fwhm = "), std::string::npos) << p;
  }
  o.metadetect.weight_fwhm = 0;
  // A sky not subtracted: the cell fails saying so.
  o.inputs = {write_planes(scratch.path("sky.fits"), 25, 25, 0, 0, 1, -3.5)};
  const MetadetectRunSummary sky = run_metadetect(o);
  EXPECT_EQ(sky.cells_failed, 1);
  ASSERT_EQ(sky.problems.size(), 1u);
  EXPECT_NE(sky.problems[0].find("sky at -3.50 sigma"), std::string::npos) << sky.problems[0];
  o.metadetect.cell_size = 69;  // the default buffer of 34 leaves 1 pixel
  const std::string thin = error_of(cells);
  EXPECT_NE(thin.find("cell_buffer = 34: must be >= 0 and leave an interior of at least 16 pixels"), std::string::npos) << thin;
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
                            snr_g = f.read_column("snr_g"), flags = f.read_column("flags"), snr = f.read_column("snr");
  // The bands' images share one reconvolution PSF, so a noise-free galaxy's weighted flux scales
  // with its flux: r/g = 1.5 up to how well each band's sampled PSF image deconvolves (measured:
  // within 1.4e-3 over these 3 cells' 735 rows; band r's PSF is 10 % narrower than g's).
  int usable = 0;
  for (std::size_t i = 0; i < flux_g.size(); ++i) {
    if (flags[i] != 0 || !(snr[i] > 10)) continue;  // the galaxies, not the noise peaks between them
    ++usable;
    EXPECT_NEAR(flux_r[i] / flux_g[i], 1.5, 3e-3) << "row " << i;
    EXPECT_GT(snr_g[i], 1000) << "row " << i;
  }
  EXPECT_GT(usable, 3 * 5 * 40);
  // Shards of a band run merge to its table, band columns included.
  ShardMergeOptions mo;
  mo.shards = testing::run_metadetect_shards(o, 2, scratch, "part");
  mo.output = scratch.path("merged.fits");
  merge_shards(mo);
  EXPECT_EQ(bytes(scratch.path("merged.fits")), bytes(scratch.path("one.fits")));
}

// Band roles (DES Y6's detection and shapes on r, i, z; issue 56 must-show 3): with g, r, i, z read
// and r, i, z given both roles, every row is the r, i, z-only run's bit for bit (detections,
// shapes, their fluxes), g's flux and S/N added; detection on all four with shapes from r, i, z
// finds other detections, and where one lies where the r, i, z-only run's does its shape is close;
// pgauss's pre-PSF flux per band follows the bands' true fluxes even where a band has another
// reconvolution PSF. Bad roles are refused naming the flag.
TEST(MetadetectRun, BandRolesTakeShapesFromTheShearBandsAndFluxFromEvery) {
  testing::ScratchDir scratch("stampede_mdet_roles_");
  CellSimOptions so;
  so.snr = 1e4;
  so.bands = 4;
  CellOutputOptions out;
  out.cells = 2;
  out.band_names = {"g", "r", "i", "z"};
  simulate_on_one_thread(so, out, scratch.path("sims"));
  MetadetectRunOptions o;
  o.inputs = {scratch.path("sims/{band}/cell_0000.fits"), scratch.path("sims/{band}/cell_0001.fits")};
  o.threads = 2;
  const auto run = [&](const std::string& name, std::vector<std::string> bands, std::vector<std::string> detect,
                       std::vector<std::string> shear) {
    o.output = scratch.path(name);
    o.bands = std::move(bands), o.detect_bands = std::move(detect), o.shear_bands = std::move(shear);
    EXPECT_EQ(run_metadetect(o).cells_failed, 0) << name;
    return io::read_metadetect_rows(o.output);
  };
  const std::vector<MetadetectRow> riz = run("riz.fits", {"r", "i", "z"}, {}, {});
  const std::vector<MetadetectRow> both = run("both.fits", {"g", "r", "i", "z"}, {"r", "i", "z"}, {"r", "i", "z"});
  ASSERT_EQ(both.size(), riz.size());
  ASSERT_GT(riz.size(), 2u * 5 * 40);
  for (std::size_t i = 0; i < riz.size(); ++i) {
    const MetadetectRow &a = both[i], &b = riz[i];
    ASSERT_TRUE(a.cell == b.cell && a.shear_type == b.shear_type && a.x == b.x && a.y == b.y) << "row " << i;
    EXPECT_TRUE(a.e1 == b.e1 && a.e2 == b.e2 && a.t == b.t && a.flux == b.flux && a.snr == b.snr && a.flags == b.flags)
        << "row " << i;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(a.band_flux[k + 1], b.band_flux[k]) << "row " << i;
    if (a.flags == 0) {
      EXPECT_TRUE(std::isfinite(a.band_flux[0]) && a.band_snr[0] > 0) << "row " << i;
    }
  }
  io::FitsFile f = io::FitsFile::open_read(scratch.path("both.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("DETBANDS").value_or(""), "r,i,z");
  EXPECT_EQ(f.read_key_string("SHRBANDS").value_or(""), "r,i,z");
  // Detection on g, r, i, z: where a detection lies within 1e-3 px of riz's, its shape is riz's
  // closely (measured: 172 of these 2 cells' 490 galaxy rows, |de| <= 8.3e-7).
  const std::vector<MetadetectRow> all = run("all.fits", {"g", "r", "i", "z"}, {}, {"r", "i", "z"});
  int matched = 0;
  double worst = 0;
  for (const MetadetectRow& a : all) {
    if (a.flags != 0 || !(a.snr > 10)) continue;
    for (const MetadetectRow& b : riz)
      if (b.cell == a.cell && b.shear_type == a.shear_type && b.flags == 0 && std::hypot(a.x - b.x, a.y - b.y) < 1e-3) {
        ++matched;
        worst = std::max({worst, std::abs(a.e1 - b.e1), std::abs(a.e2 - b.e2)});
      }
  }
  std::printf("detection on griz, shapes riz: %d detections within 1e-3 px of riz's, worst |de| %.2e\n", matched, worst);
  EXPECT_GT(matched, 100);
  EXPECT_LT(worst, 1e-5);
  // pgauss: each band's pre-PSF flux, whatever its Gamma, in the bands' true ratio (the simulation's
  // band b has 1 + b / 6 times band 0's flux): g (the widest PSF, the others' Gamma) against r.
  o.metadetect.measurement = MetadetectMeasurement::kPgauss;
  const std::vector<MetadetectRow> pg = run("pgauss.fits", {"g", "r", "i", "z"}, {}, {"r", "i", "z"});
  int usable = 0;
  for (const MetadetectRow& a : pg) {
    if (a.flags != 0 || !(a.snr > 100)) continue;
    ++usable;
    EXPECT_NEAR(a.band_flux[1] / a.band_flux[0], (1 + 1.0 / 6) / 1.0, 0.02) << a.cell << " " << a.x << " " << a.y;
    EXPECT_NEAR(a.band_flux[3] / a.band_flux[1], 1.5 / (1 + 1.0 / 6), 0.02) << a.cell << " " << a.x << " " << a.y;
  }
  EXPECT_GT(usable, 2 * 5 * 30);
  o.metadetect.measurement = MetadetectMeasurement::kWmom;
  // Roles that name no band of the run, twice, or without bands.
  const auto error_of = [&](std::vector<std::string> bands, std::vector<std::string> detect, std::vector<std::string> shear) {
    o.bands = std::move(bands), o.detect_bands = std::move(detect), o.shear_bands = std::move(shear);
    o.output = scratch.path("bad.fits");
    try {
      run_metadetect(o);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of({"g", "r"}, {"r", "y"}, {}).find("--detect-bands: 'y' is not one of the run's bands (g,r)"),
            std::string::npos);
  EXPECT_NE(error_of({"g", "r"}, {}, {"r", "r"}).find("--shear-bands: band 'r' is given twice"), std::string::npos);
  o.inputs = {scratch.path("sims/g/cell_0000.fits")};
  EXPECT_NE(error_of({}, {}, {"g"}).find("--shear-bands gives bands a role: it needs several bands"), std::string::npos);
}

// A simulated cell rewritten with MFRAC and ORMASK planes (and BMASK where `bmask` is given).
std::string with_mask_planes(const std::string& cell, const std::string& path, const std::vector<double>& mfrac,
                             const std::vector<double>& ormask, const std::vector<double>& bmask = {}) {
  const io::CellImage im = io::read_cell_image(cell, true);
  io::FitsFile f = io::FitsFile::create(path, true);
  f.write_image(im.width, im.height, im.pixels);
  f.write_key("SCALE", im.pixel_scale, "arcsec per pixel");
  f.write_image(im.width, im.height, im.weight, "WEIGHT");
  if (!bmask.empty()) f.write_image(im.width, im.height, bmask, "BMASK", io::FitsFile::PixelType::kInt32);
  f.write_image(im.width, im.height, ormask, "ORMASK", io::FitsFile::PixelType::kInt32);
  f.write_image(im.width, im.height, mfrac, "MFRAC");
  f.write_image(im.psf->nx, im.psf->ny, im.psf->pixels, "PSF");
  f.close();
  return path;
}

// An image's MFRAC plane is what mfrac averages (masked pixels counting 1), its ORMASK and BMASK
// bits come back at each detection's unsheared pixel, and an MFRAC value outside [0, 1] is refused
// naming the HDU and the pixel.
TEST(MetadetectRun, MfracOrmaskAndBmaskPlanesAreReportedPerDetection) {
  testing::ScratchDir scratch("stampede_mdet_planes_");
  const std::string cell = sim_cells(scratch.path("sims"), 1)[0];
  const int n = 251;
  std::vector<double> mfrac(static_cast<std::size_t>(n) * n, 0.0), ormask(mfrac.size(), 0.0), bmask(mfrac.size(), 0.0);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const auto p = static_cast<std::size_t>(y) * n + x;
      if (x >= 125) mfrac[p] = 0.3, ormask[p] = 16;
      if (x >= 60 && x < 90 && y >= 60 && y < 90) bmask[p] = 2;
    }
  MetadetectRunOptions o;
  o.inputs = {with_mask_planes(cell, scratch.path("planes.fits"), mfrac, ormask, bmask)};
  o.output = scratch.path("out.fits");
  o.threads = 2;
  run_metadetect(o);
  const std::vector<MetadetectRow> rows = io::read_metadetect_rows(o.output);
  ASSERT_GT(rows.size(), 100u);
  int left = 0, right = 0, masked = 0;
  for (const MetadetectRow& r : rows) {
    const long px = std::lround(r.x_noshear), py = std::lround(r.y_noshear);
    ASSERT_EQ(r.ormask, ormask[static_cast<std::size_t>(py) * n + px]) << r.x_noshear;
    ASSERT_EQ(r.bmask, bmask[static_cast<std::size_t>(py) * n + px]) << r.x_noshear << ", " << r.y_noshear;
    if (r.bmask != 0) {
      ++masked;
      EXPECT_TRUE(r.flags & kMetadetectMasked);
      continue;
    }
    // The 2" Gaussian (sigma 3.4 px) reaches 11 px about the detection: rows farther than that
    // from the step and from the bad region's four-fold turns see 0 or 0.3 everywhere.
    bool clear = std::abs(r.x_noshear - 125) > 13;
    for (long y = py - 13; clear && y <= py + 13; ++y)
      for (long x = px - 13; clear && x <= px + 13; ++x)
        for (int turn = 0; turn < 4; ++turn) {
          long u = x, v = y;
          for (int k = 0; k < turn; ++k) std::tie(u, v) = std::pair{n - 1 - v, u};
          if (u >= 0 && v >= 0 && u < n && v < n && bmask[static_cast<std::size_t>(v) * n + u] != 0) clear = false;
        }
    if (!clear) continue;
    const double expected = r.x_noshear < 125 ? 0.0 : 0.3;
    EXPECT_NEAR(r.mfrac, expected, 1e-12) << r.x_noshear << ", " << r.y_noshear;
    ++(expected == 0 ? left : right);
  }
  EXPECT_GT(left, 5);
  EXPECT_GT(right, 5);
  EXPECT_GT(masked, 0);
  // A fraction beyond 1 is no masked fraction.
  mfrac[static_cast<std::size_t>(7) * n + 5] = 1.5;
  o.inputs = {with_mask_planes(cell, scratch.path("bad.fits"), mfrac, ormask)};
  o.output = scratch.path("bad_out.fits");
  try {
    run_metadetect(o);
    ADD_FAILURE() << "an MFRAC value of 1.5 was accepted";
  } catch (const io::FitsError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'MFRAC'"), std::string::npos) << what;
    EXPECT_NE(what.find("masked fraction 1.5 at pixel (5, 7)"), std::string::npos) << what;
  }
  EXPECT_FALSE(std::filesystem::exists(o.output));
}

// A bright-star catalogue (--star-mask): the galaxy at each cell's centre under a star's disc is
// detected in no image; the catalogue's digest and margin are recorded; it may not be the output;
// a bad catalogue is refused naming it.
TEST(MetadetectRun, StarMaskDropsWhatLiesUnderItsDiscsAndIsRecorded) {
  testing::ScratchDir scratch("stampede_mdet_stars_");
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 2);
  o.threads = 2;
  o.output = scratch.path("plain.fits");
  run_metadetect(o);
  const std::string stars = scratch.path("stars.fits");
  {
    io::FitsFile f = io::FitsFile::create(stars, true);
    f.write_empty_image();
    f.write_table("STARS", {{"x", false, {126}}, {"y", false, {126}}, {"radius", false, {4}}});
    f.close();
  }
  o.star_mask = stars;
  o.star_margin = 2;
  o.output = scratch.path("stars_out.fits");
  const MetadetectRunSummary r = run_metadetect(o);
  EXPECT_EQ(r.cells_failed, 0);
  EXPECT_EQ(galaxy_rows(o.output), galaxy_rows(scratch.path("plain.fits")) - 2 * 5);
  for (const MetadetectRow& row : io::read_metadetect_rows(o.output))
    EXPECT_GE(std::hypot(row.x - 125, row.y - 125), 6.0) << row.x << ", " << row.y;
  io::FitsFile f = io::FitsFile::open_read(o.output);
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("STARCAT").value_or(""), stars);
  EXPECT_FALSE(f.read_key_string("STARCATD").value_or("").empty());
  EXPECT_EQ(f.read_key_double("STARMARG").value_or(-1), 2.0);
  // The catalogue as the output: refused before anything is written, the catalogue kept.
  o.output = stars;
  o.overwrite = true;
  EXPECT_THROW(run_metadetect(o), io::FileError);
  EXPECT_NO_THROW(io::read_star_catalogue(stars, 0));
  o.overwrite = false;
  o.output = scratch.path("bad.fits");
  o.star_mask = o.inputs[0];  // an image, no table
  try {
    run_metadetect(o);
    ADD_FAILURE() << "an image as the star catalogue was accepted";
  } catch (const io::FitsError& e) {
    EXPECT_NE(std::string(e.what()).find(o.inputs[0] + ": no binary table"), std::string::npos) << e.what();
  }
}

// A star catalogue of ra, dec and radius_arcsec is placed on each image by its TAN WCS: the rows
// are those of the same stars given in pixels (bit for bit: the discs agree to ~1e-9 px and no
// pixel lies that near a rim); an image without a WCS is named, and so is a WCS this reader
// cannot use.
TEST(MetadetectRun, SkyStarCatalogueIsPlacedByEachImagesWcs) {
  testing::ScratchDir scratch("stampede_mdet_sky_stars_");
  const std::vector<std::string> cells = sim_cells(scratch.path("sims"), 2);
  io::CelestialWcs wcs;
  wcs.crval1 = 150.1, wcs.crval2 = -42.3, wcs.crpix1 = 120.5, wcs.crpix2 = 131.0;
  wcs.cd = {-0.25 / 3600 * std::cos(0.3), 0.25 / 3600 * std::sin(0.3), 0.25 / 3600 * std::sin(0.3), 0.25 / 3600 * std::cos(0.3)};
  auto with_wcs = [&](const std::string& cell, const std::string& path, const std::string& ctype1) {
    const io::CellImage im = io::read_cell_image(cell, true);
    io::FitsFile f = io::FitsFile::create(path, true);
    f.write_image(im.width, im.height, im.pixels);
    f.write_key("SCALE", im.pixel_scale, "arcsec per pixel");
    f.write_key("CTYPE1", ctype1, ""), f.write_key("CTYPE2", std::string("DEC--TAN"), "");
    f.write_key("CRVAL1", wcs.crval1, ""), f.write_key("CRVAL2", wcs.crval2, "");
    f.write_key("CRPIX1", wcs.crpix1, ""), f.write_key("CRPIX2", wcs.crpix2, "");
    f.write_key("CD1_1", wcs.cd[0], ""), f.write_key("CD1_2", wcs.cd[1], "");
    f.write_key("CD2_1", wcs.cd[2], ""), f.write_key("CD2_2", wcs.cd[3], "");
    f.write_image(im.width, im.height, im.weight, "WEIGHT");
    f.write_image(im.width, im.height, im.noise, "NOISE");
    f.write_image(im.psf->nx, im.psf->ny, im.psf->pixels, "PSF");
    f.close();
    return path;
  };
  MetadetectRunOptions o;
  o.inputs = {with_wcs(cells[0], scratch.path("a.fits"), "RA---TAN"), with_wcs(cells[1], scratch.path("b.fits"), "RA---TAN")};
  o.threads = 2;
  o.star_margin = 1;
  // Stars (FITS 1-based pixels), one on the grid's middle galaxy, radii 4.5 and 6.5 px (1.125", 1.625").
  const std::vector<double> x = {126, 65}, y = {126, 187}, radius = {4.5, 6.5};
  const std::string pixel_stars = scratch.path("pixel_stars.fits"), sky_stars = scratch.path("sky_stars.fits");
  {
    io::FitsFile f = io::FitsFile::create(pixel_stars, true);
    f.write_empty_image();
    f.write_table("STARS", {{"x", false, x}, {"y", false, y}, {"radius", false, radius}});
    f.close();
    std::vector<double> ra, dec, arcsec;
    for (std::size_t k = 0; k < x.size(); ++k) {
      const std::array<double, 2> p = wcs.sky(x[k] - 1, y[k] - 1);
      const std::optional<std::array<double, 2>> back = wcs.pixel(p[0], p[1]);
      ASSERT_TRUE(back.has_value());
      EXPECT_NEAR((*back)[0], x[k] - 1, 1e-8);
      EXPECT_NEAR((*back)[1], y[k] - 1, 1e-8);
      ra.push_back(p[0]), dec.push_back(p[1]), arcsec.push_back(radius[k] * 0.25);
    }
    io::FitsFile g = io::FitsFile::create(sky_stars, true);
    g.write_empty_image();
    g.write_table("STARS", {{"ra", false, ra}, {"dec", false, dec}, {"radius_arcsec", false, arcsec}});
    g.close();
  }
  o.star_mask = pixel_stars;
  o.output = scratch.path("pixel_out.fits");
  run_metadetect(o);
  o.star_mask = sky_stars;
  o.output = scratch.path("sky_out.fits");
  run_metadetect(o);
  const std::vector<MetadetectRow> by_pixel = io::read_metadetect_rows(scratch.path("pixel_out.fits"));
  const std::vector<MetadetectRow> by_sky = io::read_metadetect_rows(o.output);
  ASSERT_EQ(by_pixel.size(), by_sky.size());
  {
    MetadetectRunOptions plain = o;
    plain.star_mask.clear();
    plain.output = scratch.path("plain.fits");
    run_metadetect(plain);
    EXPECT_LE(galaxy_rows(o.output), galaxy_rows(plain.output) - 2 * 5);  // the centre's galaxy in two cells
  }
  for (std::size_t k = 0; k < by_pixel.size(); ++k) {
    ASSERT_EQ(by_pixel[k].x, by_sky[k].x) << k;
    ASSERT_EQ(by_pixel[k].e1, by_sky[k].e1) << k;
    ASSERT_EQ(by_pixel[k].mfrac, by_sky[k].mfrac) << k;
  }
  for (const MetadetectRow& r : by_sky) EXPECT_GE(std::hypot(r.x - 125, r.y - 125), 5.5) << r.x << ", " << r.y;
  // An image without a WCS: named with the catalogue.
  o.inputs = {cells[0]};
  o.output = scratch.path("no_wcs.fits");
  try {
    run_metadetect(o);
    ADD_FAILURE() << "a sky catalogue on an image without a WCS was accepted";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(cells[0] + " has no celestial WCS"), std::string::npos) << e.what();
  }
  // A projection this reader does not know: named with its key.
  o.inputs = {with_wcs(cells[0], scratch.path("sin.fits"), "RA---SIN")};
  o.output = scratch.path("sin_out.fits");
  try {
    run_metadetect(o);
    ADD_FAILURE() << "an RA---SIN WCS was accepted";
  } catch (const io::FitsError& e) {
    EXPECT_NE(std::string(e.what()).find("'RA---SIN'"), std::string::npos) << e.what();
  }
}

// `sim cells --bad-columns`: hot columns flagged in BMASK, the same under +g and -g; metadetect
// masks them (filled), reports the bit at detections on them, and keeps no hot pixel's detection
// unflagged.
TEST(MetadetectRun, SimulatedBadColumnsAreFlaggedInBmaskAndMasked) {
  testing::ScratchDir scratch("stampede_mdet_sim_columns_");
  CellSimOptions so;
  so.bad_columns = 3;
  simulate_pairs(so, 2, scratch.path("sims"));
  const io::CellImage plus = io::read_cell_image(scratch.path("sims/cell_0000.fits"), true);
  const io::CellImage minus = io::read_cell_image(scratch.path("sims/minus/cell_0000.fits"), true);
  ASSERT_EQ(plus.bmask, minus.bmask);
  long long flagged = 0;
  for (std::size_t p = 0; p < plus.bmask.size(); ++p) {
    flagged += plus.bmask[p] == 1;
    if (plus.bmask[p]) {
      EXPECT_EQ(plus.weight[p], 0.0);  // masked on reading
    }
  }
  EXPECT_GE(flagged, 3 * 251 / 4);
  EXPECT_EQ(plus.masked_by_bmask, flagged);
  MetadetectRunOptions o;
  o.inputs = {scratch.path("sims/cell_0000.fits"), scratch.path("sims/cell_0001.fits")};
  o.threads = 2;
  o.output = scratch.path("out.fits");
  EXPECT_EQ(run_metadetect(o).cells_failed, 0);
  for (const MetadetectRow& r : io::read_metadetect_rows(o.output)) {
    if (r.id < 0 || r.cell != 0) continue;
    const std::size_t p = static_cast<std::size_t>(std::lround(r.y_noshear)) * 251 + static_cast<std::size_t>(std::lround(r.x_noshear));
    EXPECT_EQ(r.bmask, plus.bmask[p]);
    if (r.bmask) {
      EXPECT_TRUE(r.flags & kMetadetectMasked);
    }
  }
}

// `sim cells --stars`: unlensed stars, the same under +g and -g, each image with its STARS table;
// `--star-mask-hdu STARS` masks each image by its own table: no detection inside a star's disc,
// where without it the stars are detected.
TEST(MetadetectRun, SimulatedStarsAreMaskedByEachImagesOwnTable) {
  testing::ScratchDir scratch("stampede_mdet_sim_stars_");
  CellSimOptions so;
  so.stars = 3;
  simulate_pairs(so, 2, scratch.path("sims"));
  std::vector<std::string> inputs;
  for (int k = 0; k < 2; ++k) {
    const std::string plus = scratch.path("sims/cell_000" + std::to_string(k) + ".fits");
    const std::string minus = scratch.path("sims/minus/cell_000" + std::to_string(k) + ".fits");
    const std::vector<StarDisc> a = io::read_star_catalogue(plus, 0, "STARS"), b = io::read_star_catalogue(minus, 0, "STARS");
    ASSERT_EQ(a.size(), 3u);
    ASSERT_EQ(b.size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) EXPECT_TRUE(a[i].x == b[i].x && a[i].y == b[i].y && a[i].radius == b[i].radius);
    inputs.push_back(plus);
  }
  MetadetectRunOptions o;
  o.inputs = inputs;
  o.threads = 2;
  const auto inside = [&](const std::string& table) {
    int n = 0;
    for (const MetadetectRow& r : io::read_metadetect_rows(table)) {
      const std::vector<StarDisc> stars = io::read_star_catalogue(inputs[static_cast<std::size_t>(r.cell)], 0, "STARS");
      for (const StarDisc& star : stars) n += r.id >= 0 && star.holds(r.x, r.y);
    }
    return n;
  };
  o.output = scratch.path("plain.fits");
  run_metadetect(o);
  EXPECT_GT(inside(o.output), 0);  // the stars themselves, at least
  o.output = scratch.path("masked.fits");
  o.star_hdu = "STARS";
  EXPECT_EQ(run_metadetect(o).cells_failed, 0);
  EXPECT_EQ(inside(o.output), 0);
  io::FitsFile f = io::FitsFile::open_read(o.output);
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("STARHDU").value_or(""), "STARS");
  o.star_mask = scratch.path("stars.fits");
  o.output = scratch.path("both.fits");
  EXPECT_THROW(run_metadetect(o), io::ConfigError);  // one or the other
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
                            flags = f.read_column("flags"), snr = f.read_column("snr");
  // The pre-PSF flux of one galaxy in two bands of one Gamma: r/g = 1.5 as for wmom.
  int usable = 0;
  for (std::size_t i = 0; i < flux_g.size(); ++i) {
    if (flags[i] != 0 || !(snr[i] > 10)) continue;
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
  EXPECT_EQ(galaxy_rows(o.output), 3 * 5 * 9);
  o.threads = 2;
  o.output = scratch.path("two.fits");
  run_metadetect(o);
  EXPECT_EQ(bytes(scratch.path("one.fits")), bytes(scratch.path("two.fits")));
  io::FitsFile f = io::FitsFile::open_read(scratch.path("one.fits"));
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("MEASURE").value_or(""), "exp");
  const std::vector<double> flags = f.read_column("flags"), snr = f.read_column("snr");
  for (std::size_t i = 0; i < flags.size(); ++i) {
    if (!(snr[i] > 10)) continue;  // a noise peak between the galaxies (its fit may fail: NaN); galaxy_rows counts the galaxies
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

// The ConfigError a run of `o` throws ("no error" when it runs).
std::string config_error_of(const MetadetectRunOptions& o) {
  try {
    run_metadetect(o);
  } catch (const io::ConfigError& e) {
    return std::string(e.what());
  }
  return std::string("no error");
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
    return config_error_of(o);
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
  const std::string images = error_of({scratch.path("sims/g/cell_0000.fits")}, {"g", "r"}, false);
  EXPECT_NE(images.find("holds no '{band}'"), std::string::npos) << images;
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

// Two bands of image files, read through a {band} template (DIR/{band}/cell_KKKK.fits, as `sim
// cells --bands g,r` writes them), measure bit for bit as the same scenes' band tiles (x, y in the
// tile's pixels aside), the same for one and two threads.
TEST(MetadetectRun, BandImagesMeasureAsTheirBandTiles) {
  testing::ScratchDir scratch("stampede_mdet_band_images_");
  sim_band_tiles(scratch.path("sims"), 3);
  MetadetectRunOptions o;
  for (int k = 0; k < 3; ++k) o.inputs.push_back(scratch.path("sims/{band}/cell_000" + std::to_string(k) + ".fits"));
  o.bands = {"g", "r"};
  expect_one_table_for_one_and_two_threads(o, scratch, 3);
  o.inputs = {scratch.path("sims/g/cells_meds.fits"), scratch.path("sims/r/cells_meds.fits")};
  o.tile = true;
  o.output = scratch.path("tile.fits");
  EXPECT_EQ(run_metadetect(o).cells, 3);
  io::FitsFile a = io::FitsFile::open_read(scratch.path("one.fits")), b = io::FitsFile::open_read(o.output);
  a.move_to("METADETECT"), b.move_to("METADETECT");
  EXPECT_EQ(a.read_key_string("BANDS").value_or(""), "g,r");
  EXPECT_EQ(a.read_key_string("INPUT2").value_or(""), scratch.path("sims/r/cell_0000.fits"));
  const std::vector<double> flux_g = a.read_column("flux_g");
  ASSERT_GT(flux_g.size(), 3u * 5 * 40);
  // Bit for bit, a band's NaN (its moments failed on a noise peak) matching a NaN.
  for (const char* c : {"cell", "e1", "e2", "T", "T_ratio", "psf_T", "snr", "flux", "flux_g", "flux_r", "snr_g", "snr_r", "flags"}) {
    const std::vector<double> ca = a.read_column(c), cb = b.read_column(c);
    ASSERT_EQ(ca.size(), cb.size()) << c;
    for (std::size_t i = 0; i < ca.size(); ++i)
      EXPECT_TRUE(ca[i] == cb[i] || (std::isnan(ca[i]) && std::isnan(cb[i]))) << c << " row " << i;
  }
  const std::vector<double> xa = a.read_column("x"), xb = b.read_column("x"), cell = a.read_column("cell");
  for (std::size_t i = 0; i < xa.size(); ++i)
    EXPECT_NEAR(xb[i] - xa[i], (static_cast<int>(cell[i]) % 2) * (251 - 2 * 34), 1e-9);
}

TEST(MetadetectRun, BandImagesThatDoNotMatchAreRefusedByName) {
  testing::ScratchDir scratch("stampede_mdet_band_image_errors_");
  std::filesystem::create_directories(scratch.path("g")), std::filesystem::create_directories(scratch.path("r"));
  auto error_of = [&](std::vector<std::string> inputs, std::vector<std::string> bands, const std::string& psfex = "") {
    MetadetectRunOptions o;
    o.inputs = std::move(inputs);
    o.bands = std::move(bands);
    o.psfex = psfex;
    o.output = scratch.path("out.fits");
    o.overwrite = true;
    return config_error_of(o);
  };
  write_image(scratch.path("g/a.fits"), 251, {"WEIGHT", "PSF"});
  write_image(scratch.path("r/a.fits"), 260, {"WEIGHT", "PSF"});
  write_image(scratch.path("g/b.fits"), 251, {"WEIGHT", "PSF"});
  write_image(scratch.path("r/b.fits"), 251, {"WEIGHT", "PSF"}, 1.0, 0.2, 0.0, 0.2);
  write_image(scratch.path("one.fits"), 251, {"WEIGHT", "PSF"});
  const std::string size = error_of({scratch.path("{band}/a.fits")}, {"g", "r"});
  EXPECT_NE(size.find(scratch.path("r/a.fits") + " is 260 x 260 pixels, " + scratch.path("g/a.fits") + " 251 x 251"),
            std::string::npos) << size;
  const std::string scale = error_of({scratch.path("{band}/b.fits")}, {"g", "r"});
  EXPECT_NE(scale.find(scratch.path("r/b.fits") + "'s pixel scale 0.2 arcsec differs from " + scratch.path("g/b.fits") +
                       "'s 0.25"), std::string::npos) << scale;
  const std::string no_field = error_of({scratch.path("one.fits")}, {"g", "r"});
  EXPECT_NE(no_field.find("--bands names 2 bands but image path '" + scratch.path("one.fits") + "' holds no '{band}'"),
            std::string::npos) << no_field;
  const std::string no_bands = error_of({scratch.path("{band}/b.fits")}, {});
  EXPECT_NE(no_bands.find("holds '{band}' but no --bands names the bands"), std::string::npos) << no_bands;
  const std::string psfex = error_of({scratch.path("{band}/b.fits")}, {"g", "r"}, scratch.path("model.psf"));
  EXPECT_NE(psfex.find("--psfex '" + scratch.path("model.psf") + "' holds no '{band}'"), std::string::npos) << psfex;
  const std::string names = error_of({scratch.path("{band}/b.fits")}, {"g", "G"});
  EXPECT_NE(names.find("--bands: bands 'g' and 'G' differ only in case"), std::string::npos) << names;
  const std::string twice = error_of({scratch.path("{band}/../one.fits")}, {"g", "r"});
  EXPECT_NE(twice.find("is bands g and r of"), std::string::npos) << twice;
  // A model fit measures one band, from image files as from tiles: refused before any cell.
  MetadetectRunOptions fit;
  fit.inputs = {scratch.path("{band}/b.fits")};
  fit.bands = {"g", "r"};
  fit.metadetect.measurement = MetadetectMeasurement::kExp;
  fit.output = scratch.path("out.fits");
  const std::string fits_bands = config_error_of(fit);
  EXPECT_NE(fits_bands.find("--measurement exp fits one band: give --bands one band"), std::string::npos) << fits_bands;
  // One band named, no template: its columns.
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 1);
  o.bands = {"i"};
  o.output = scratch.path("named.fits");
  run_metadetect(o);
  io::FitsFile f = io::FitsFile::open_read(o.output);
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("BANDS").value_or(""), "i");
  EXPECT_EQ(f.read_column("flux_i"), f.read_column("flux"));
}

// A PSFEx model file (PSF_DATA, column PSF_MASK) of `degree` with `terms` basis images of n x n.
void write_psfex(const std::string& path, int degree, int n, const std::vector<float>& cube, double zero, double scale,
                 double sampling = 1.0) {
  fitsfile* f = nullptr;
  int status = 0;
  fits_create_file(&f, ("!" + path).c_str(), &status);
  char* ttype[] = {const_cast<char*>("PSF_MASK")};
  const std::string form = std::to_string(cube.size()) + "E";
  char* tform[] = {const_cast<char*>(form.c_str())};
  fits_create_tbl(f, BINARY_TBL, 1, 1, ttype, tform, nullptr, "PSF_DATA", &status);
  auto key_long = [&](const char* k, long v) { fits_update_key(f, TLONG, k, &v, nullptr, &status); };
  auto key_double = [&](const char* k, double v) { fits_update_key(f, TDOUBLE, k, &v, nullptr, &status); };
  auto key_string = [&](const char* k, const char* v) { fits_update_key(f, TSTRING, k, const_cast<char*>(v), nullptr, &status); };
  key_long("POLNAXIS", 2), key_long("POLNGRP", 1), key_long("POLDEG1", degree), key_long("PSFNAXIS", 3);
  key_string("POLNAME1", "X_IMAGE"), key_string("POLNAME2", "Y_IMAGE");
  key_double("POLZERO1", zero), key_double("POLZERO2", zero), key_double("POLSCAL1", scale), key_double("POLSCAL2", scale);
  key_double("PSF_SAMP", sampling);
  key_long("PSFAXIS1", n), key_long("PSFAXIS2", n), key_long("PSFAXIS3", static_cast<long>(cube.size()) / (n * n));
  fits_write_col(f, TFLOAT, 1, 1, 1, static_cast<LONGLONG>(cube.size()), const_cast<float*>(cube.data()), &status);
  fits_close_file(f, &status);
  ASSERT_EQ(status, 0) << path;
}

// A round Gaussian of `sigma` pixels on n x n samples about the middle one.
std::vector<float> gaussian(int n, double sigma) {
  std::vector<float> out(static_cast<std::size_t>(n) * n);
  const int c = n / 2;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      out[static_cast<std::size_t>(y) * n + x] =
          static_cast<float>(std::exp(-((x - c) * (x - c) + (y - c) * (y - c)) / (2 * sigma * sigma)));
  return out;
}

// An input named like a file the run writes beside its output (OUT.fits.partial, .checkpoint,
// .lock) is refused before any work and left as it was (a failed run removes those files).
TEST(MetadetectRun, AnInputNamedLikeTheOutputsPartialIsRefusedAndKept) {
  testing::ScratchDir scratch("stampede_mdet_companion_");
  const std::vector<std::string> cells = sim_cells(scratch.path("sims"), 1);
  for (const char* suffix : {".partial", ".checkpoint", ".lock"}) {
    const std::string input = scratch.path(std::string("t.fits") + suffix);
    std::filesystem::copy_file(cells[0], input, std::filesystem::copy_options::overwrite_existing);
    const auto before = std::filesystem::file_size(input);
    MetadetectRunOptions o;
    o.inputs = {input};
    o.output = scratch.path("t.fits");
    o.overwrite = true;
    try {
      run_metadetect(o);
      ADD_FAILURE() << suffix << ": accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("which is the input '" + input + "'"), std::string::npos) << e.what();
    }
    ASSERT_TRUE(std::filesystem::exists(input)) << suffix;
    EXPECT_EQ(std::filesystem::file_size(input), before) << suffix;
    EXPECT_FALSE(std::filesystem::exists(o.output)) << suffix;
  }
}

// The cells' images in single precision (the default) or in double (--double-images): the header
// says which, and the same objects are measured to float rounding (the images within ~2e-7 of
// their peak; measured: positions within 9e-7 px, e within 6e-8).
TEST(MetadetectRun, SingleAndDoublePrecisionImagesMeasureTheSameObjects) {
  testing::ScratchDir scratch("stampede_mdet_precision_");
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 2);
  o.output = scratch.path("single.fits");
  run_metadetect(o);
  o.metadetect.double_images = true;
  o.output = scratch.path("double.fits");
  run_metadetect(o);
  for (const auto& [name, want] : {std::pair{"single.fits", "single"}, {"double.fits", "double"}}) {
    io::FitsFile f = io::FitsFile::open_read(scratch.path(name));
    f.move_to("METADETECT");
    EXPECT_EQ(f.read_key_string("IMGPREC").value_or(""), want) << name;
  }
  const std::vector<MetadetectRow> single = io::read_metadetect_rows(scratch.path("single.fits")),
                                   twice = io::read_metadetect_rows(scratch.path("double.fits"));
  ASSERT_EQ(single.size(), twice.size());
  ASSERT_GT(single.size(), 400u);
  double worst_x = 0, worst_e = 0;
  for (std::size_t i = 0; i < single.size(); ++i) {
    ASSERT_EQ(single[i].shear_type, twice[i].shear_type) << i;
    EXPECT_EQ(single[i].flags, twice[i].flags) << i;
    if (single[i].id < 0) continue;
    worst_x = std::max({worst_x, std::abs(single[i].x - twice[i].x), std::abs(single[i].y - twice[i].y)});
    worst_e = std::max({worst_e, std::abs(single[i].e1 - twice[i].e1), std::abs(single[i].e2 - twice[i].e2)});
  }
  std::printf("single against double precision images: worst |dx| = %.1e px, |de| = %.1e\n", worst_x, worst_e);
  EXPECT_LT(worst_x, 1e-5);
  EXPECT_LT(worst_e, 1e-6);
}

// A constant PSFEx model of the cells' PSF HDU (`stampede sim meds` writes such models) measures as
// the PSF HDU: the same detections, e within 1e-9 (the model's samples are the HDU's float32 ones,
// normalised once more); and the PSF HDU is then not needed. In double-precision images: single
// precision's rounding (1e-7 of the images' peak) would hide the 1e-9 this compares.
TEST(MetadetectRun, APsfexModelOfThePsfHduMeasuresAsThePsfHdu) {
  testing::ScratchDir scratch("stampede_mdet_psfex_");
  MetadetectRunOptions o;
  o.metadetect.double_images = true;
  o.inputs = sim_cells(scratch.path("sims"), 2);
  o.output = scratch.path("hdu.fits");
  run_metadetect(o);
  io::FitsFile cell = io::FitsFile::open_read(o.inputs[0]);
  cell.move_to("PSF");
  const int n = static_cast<int>(cell.image_shape().nx);
  io::write_psfex_constant(scratch.path("cells.psf"), n, n, cell.read_image(), 0.9);
  o.psfex = scratch.path("cells.psf");
  o.output = scratch.path("psfex.fits");
  const MetadetectRunSummary r = run_metadetect(o);
  EXPECT_EQ(r.cells_failed, 0);
  const std::vector<MetadetectRow> hdu = io::read_metadetect_rows(scratch.path("hdu.fits")),
                                   psfex = io::read_metadetect_rows(o.output);
  ASSERT_EQ(hdu.size(), psfex.size());
  EXPECT_EQ(galaxy_rows(scratch.path("hdu.fits")), 2 * 5 * 49);
  double worst_x = 0, worst_e = 0;
  for (std::size_t i = 0; i < hdu.size(); ++i) {
    worst_x = std::max(worst_x, std::abs(hdu[i].x - psfex[i].x));
    worst_e = std::max({worst_e, std::abs(hdu[i].e1 - psfex[i].e1), std::abs(hdu[i].e2 - psfex[i].e2)});
    // SEP's barycentres are float sums of the filtered image, which the model's float rounding of
    // the PSF moves in its last bits: 1e-8 px.
    EXPECT_NEAR(hdu[i].x, psfex[i].x, 1e-7) << i;
    EXPECT_EQ(hdu[i].flags, psfex[i].flags) << i;
    EXPECT_NEAR(hdu[i].e1, psfex[i].e1, 1e-9) << i;
    EXPECT_NEAR(hdu[i].e2, psfex[i].e2, 1e-9) << i;
    EXPECT_NEAR(hdu[i].psf_t, psfex[i].psf_t, 1e-9 * hdu[i].psf_t) << i;
  }
  std::printf("PSFEx model against the PSF HDU: worst |dx| = %.1e px, |de| = %.1e\n", worst_x, worst_e);
  io::FitsFile f = io::FitsFile::open_read(o.output);
  f.move_to("METADETECT");
  EXPECT_EQ(f.read_key_string("PSFEX1").value_or(""), o.psfex);
  EXPECT_TRUE(f.read_key_string("PSFEXD1").has_value());
  // An image without a PSF HDU runs with the model.
  o.inputs = {write_image(scratch.path("nopsf.fits"), 251, {"WEIGHT"})};
  o.output = scratch.path("nopsf_out.fits");
  EXPECT_EQ(run_metadetect(o).cells, 1);
}

// A model whose width varies with X_IMAGE gives each cell the PSF at its centre: 2 x 2 cells of a
// 400 px image (centres X_IMAGE 126 and 275), the reconvolution PSF (psf_T) the same for the cells
// of one column and another in the other column, the right-hand column's that of a constant model
// of the varying one at X_IMAGE 275; the rows are the same for one and two threads.
TEST(MetadetectRun, AVaryingPsfexModelGivesEachCellItsPsf) {
  testing::ScratchDir scratch("stampede_mdet_psfex_vary_");
  CellSimOptions so;
  so.size = 400;
  so.grid = 12;
  MetadetectRunOptions o;
  o.inputs = sim_cells(scratch.path("sims"), 1, so);
  const int n = 25;
  // (1 - xs) / 2 narrow + (1 + xs) / 2 wide: positive for |xs| <= 1.
  const std::vector<float> wide = gaussian(n, 2.4), narrow = gaussian(n, 1.6);
  std::vector<float> cube;
  for (int p = 0; p < n * n; ++p) cube.push_back(0.5f * (wide[p] + narrow[p]));
  for (int p = 0; p < n * n; ++p) cube.push_back(0.5f * (wide[p] - narrow[p]));  // the x term
  cube.resize(cube.size() + static_cast<std::size_t>(n) * n, 0.0f);              // no y term
  write_psfex(scratch.path("vary.psf"), 1, n, cube, 200.5, 200);
  o.psfex = scratch.path("vary.psf");
  o.output = scratch.path("one.fits");
  o.threads = 1;
  o.cells_per_batch = 1;
  const MetadetectRunSummary r = run_metadetect(o);
  EXPECT_EQ(r.cells, 4);
  EXPECT_EQ(r.cells_failed, 0);
  o.output = scratch.path("two.fits");
  o.threads = 2;
  run_metadetect(o);
  EXPECT_EQ(bytes(scratch.path("one.fits")), bytes(scratch.path("two.fits")));
  double psf_t[4] = {NAN, NAN, NAN, NAN};
  for (const MetadetectRow& row : io::read_metadetect_rows(scratch.path("one.fits"))) {
    if (row.flags != 0) continue;
    double& t = psf_t[row.cell];
    if (std::isnan(t)) t = row.psf_t;
    EXPECT_EQ(row.psf_t, t) << "cell " << row.cell;  // one PSF a cell
  }
  EXPECT_EQ(psf_t[0], psf_t[2]);
  EXPECT_EQ(psf_t[1], psf_t[3]);
  // The reconvolution PSF follows the PSF's Fourier tail (the narrow part's), not simply its width:
  // measured 0.5 % apart.
  EXPECT_GT(std::abs(psf_t[1] / psf_t[0] - 1), 1e-3);
  std::vector<double> at_275(static_cast<std::size_t>(n) * n);
  std::string why;
  ASSERT_TRUE(io::read_psfex_model(o.psfex).evaluate(275, 126, at_275, &why)) << why;
  io::write_psfex_constant(scratch.path("at_275.psf"), n, n, at_275, 0.9);
  o.psfex = scratch.path("at_275.psf");
  o.output = scratch.path("constant.fits");
  run_metadetect(o);
  for (const MetadetectRow& row : io::read_metadetect_rows(o.output)) {
    if (row.flags != 0) continue;
    if (row.cell % 2 == 1) EXPECT_NEAR(row.psf_t, psf_t[1], 1e-6 * psf_t[1]) << "cell " << row.cell;  // float32 samples
    else EXPECT_NE(row.psf_t, psf_t[0]) << "cell " << row.cell;
  }
}

TEST(MetadetectRun, ABadPsfexModelIsRefusedByName) {
  testing::ScratchDir scratch("stampede_mdet_psfex_bad_");
  MetadetectRunOptions o;
  o.inputs = {write_image(scratch.path("cell.fits"), 251, {"WEIGHT"})};
  o.output = scratch.path("out.fits");
  auto error_of = [&](const std::string& psfex) {
    o.psfex = psfex;
    try {
      run_metadetect(o);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string missing = error_of(scratch.path("missing.psf"));
  EXPECT_NE(missing.find("--psfex"), std::string::npos) << missing;
  EXPECT_NE(missing.find(scratch.path("missing.psf")), std::string::npos) << missing;
  const std::string not_psfex = error_of(o.inputs[0]);
  EXPECT_NE(not_psfex.find(o.inputs[0] + ": not a PSFEx model"), std::string::npos) << not_psfex;
  write_psfex(scratch.path("coarse.psf"), 0, 13, gaussian(13, 1.0), 0, 1, 2.0);
  const std::string coarse = error_of(scratch.path("coarse.psf"));
  EXPECT_NE(coarse.find("--psfex " + scratch.path("coarse.psf") + ": PSF_SAMP = 2"), std::string::npos) << coarse;
  EXPECT_NE(error_of("").find("no PSF HDU"), std::string::npos);  // no model: the PSF HDU is required again
  EXPECT_FALSE(std::filesystem::exists(o.output));
}

// --keep-unlensed reads each image's recorded shear: an image without G1, G2, or a cell tile, is
// refused by name before any cell is measured.
TEST(MetadetectRun, KeepUnlensedWithoutARecordedShearIsRefusedByName) {
  testing::ScratchDir scratch("stampede_mdet_unlensed_");
  MetadetectRunOptions o;
  o.inputs = {write_image(scratch.path("plain.fits"), 251, {"WEIGHT", "PSF"})};
  o.output = scratch.path("out.fits");
  o.metadetect.keep_unlensed = true;
  const std::string message = config_error_of(o);
  EXPECT_NE(message.find(scratch.path("plain.fits") + ": --keep-unlensed needs the scene's shear, header keys G1 and G2"),
            std::string::npos)
      << message;
  EXPECT_FALSE(io::file_exists(o.output));
  // The simulation's own image files record it: accepted.
  o.inputs = sim_cells(scratch.path("sims"), 1);
  EXPECT_EQ(run_metadetect(o).cells, 1);
}

}  // namespace
}  // namespace stampede::app
