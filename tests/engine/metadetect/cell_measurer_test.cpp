// Metadetection of one cell (engine/metadetect/cell_measurer): every galaxy of a grid cell is
// detected once per image at its position, the sheared images' detections respond to the shear
// (R11 ~ 0.22 for these galaxies), a shear pair's response-corrected shear is the one applied, and
// a cell that cannot be measured is one flagged row.
#include "engine/metadetect/cell_measurer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "engine/metacal/metacal_type.hpp"
#include "engine/sim/cell_sim.hpp"

namespace stampede {
namespace {

struct CellRun {
  std::vector<MetadetectRow> rows;
  bool ok = false;
  std::string problem;
};

CellRun measure_sim_cell(const CellSimOptions& so, int cell, double g1, const MetadetectOptions& mo = {}) {
  CellSimulator sim(so);
  auto ws = sim.make_workspace();
  const SimCell c = sim.simulate(cell, g1, 0.0, *ws);
  PsfImage img;
  img.nx = img.ny = so.psf_size;
  img.pixels = sim.bands()[0].psf;
  const PsfModel psf = PsfModel::Image(std::make_shared<const PsfImage>(img));
  const std::vector<double> weight(c.bands[0].image.size(), 1.0 / std::pow(sim.bands()[0].noise_sigma, 2));
  MetadetectCell in;
  in.index = cell;
  in.size = so.size;
  in.pixels = c.bands[0].image;
  in.weight = weight;
  in.pixel_scale = so.pixel_scale;
  in.psf = &psf;
  in.keep_x0 = in.keep_y0 = so.buffer;
  in.keep_x1 = in.keep_y1 = so.size - so.buffer;
  CellMeasurer m(mo);
  CellRun run;
  run.ok = m.measure(in, &run.rows, &run.problem);
  return run;
}

// Mean e1 of the usable rows of one type.
double mean_e(const std::vector<MetadetectRow>& rows, MetacalType t, int component, int* n = nullptr) {
  double s = 0;
  int k = 0;
  for (const MetadetectRow& r : rows)
    if (r.shear_type == static_cast<int>(t) && r.flags == 0) s += component == 1 ? r.e1 : r.e2, ++k;
  if (n) *n = k;
  return s / k;
}

TEST(CellMeasurer, DetectsEveryGridGalaxyOncePerImageAtItsPosition) {
  CellSimOptions so;
  so.snr = 1e4;
  const CellRun run = measure_sim_cell(so, 0, 0.02);
  ASSERT_TRUE(run.ok) << run.problem;
  CellSimulator sim(so);
  const std::vector<CellObject> truth = sim.objects(0, 0.02, 0.0);
  for (MetacalType t : kMetacalTypes) {
    int n = 0;
    mean_e(run.rows, t, 1, &n);
    EXPECT_EQ(n, 49) << metacal_type_name(t);
  }
  for (const MetadetectRow& r : run.rows) {
    if (r.shear_type != 0) continue;
    double best = 1e9;
    for (const CellObject& o : truth) best = std::min(best, std::hypot(r.x - o.x, r.y - o.y));
    EXPECT_LT(best, 0.05) << "detection " << r.id;
    EXPECT_GT(r.t_ratio, 1.0);
    EXPECT_GT(r.snr, 1000);
  }
}

TEST(CellMeasurer, ShearPairRecoversTheShear) {
  CellSimOptions so;
  so.snr = 1e4;  // nearly noise-free; with no noise at all every isophote at 0.8 sigma would merge
  const double g = 0.02;
  const MetadetectOptions mo;
  double g_plus = 0, g_minus = 0, r_sum = 0;
  for (int cell = 0; cell < 2; ++cell) {
    for (double sign : {1.0, -1.0}) {
      const CellRun run = measure_sim_cell(so, cell, g * sign, mo);
      ASSERT_TRUE(run.ok) << run.problem;
      const double r11 = (mean_e(run.rows, MetacalType::k1p, 1) - mean_e(run.rows, MetacalType::k1m, 1)) / (2 * mo.step);
      EXPECT_GT(r11, 0.15);  // wmom under a 1.2" weight: ~0.22 for these galaxies
      EXPECT_LT(r11, 0.30);
      (sign > 0 ? g_plus : g_minus) += mean_e(run.rows, MetacalType::kNoshear, 1);
      r_sum += r11;
    }
  }
  const double m = (g_plus - g_minus) / 2 / (r_sum / 2) / g - 1;
  // Measured -1.1e-3 on these two pairs (the scene's positions sheared with it; unsheared positions
  // gave +4.8e-3): docs/metadetect.md has the many-cell figure.
  EXPECT_LT(std::abs(m), 2e-3);
}

TEST(CellMeasurer, ACellWithoutNoiseIsOneFlaggedRow) {
  CellSimOptions so;
  CellSimulator sim(so);
  auto ws = sim.make_workspace();
  const SimCell c = sim.simulate(0, *ws);
  const PsfModel psf = PsfModel::Moffat({2.5, 3.6, 0.0, 0.0});
  const std::vector<double> weight(c.bands[0].image.size(), 0.0);  // every pixel masked
  MetadetectCell in;
  in.index = 3;
  in.size = so.size;
  in.pixels = c.bands[0].image;
  in.weight = weight;
  in.pixel_scale = so.pixel_scale;
  in.psf = &psf;
  in.keep_x1 = in.keep_y1 = so.size;
  CellMeasurer m(MetadetectOptions{});
  std::vector<MetadetectRow> rows;
  std::string problem;
  EXPECT_FALSE(m.measure(in, &rows, &problem));
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].cell, 3);
  EXPECT_EQ(rows[0].id, -1);
  EXPECT_EQ(rows[0].flags, kMetadetectCellFailed);
  EXPECT_NE(problem.find("noise"), std::string::npos) << problem;
}

}  // namespace
}  // namespace stampede
