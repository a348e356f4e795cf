// Metadetection test cells (engine/sim/cell_sim): the light drawn is the galaxies' analytic flux,
// each galaxy sits at its truth position, the noise has its stated sigma, a shear pair shares its
// galaxies and noise (its positions sheared with the scene), and bad options are refused naming the option.
#include "engine/sim/cell_sim.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "kernels/moments.hpp"
#include "kernels/sersic.hpp"

namespace stampede {
namespace {

double sum(const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0); }

double std_dev(const std::vector<double>& v) {
  const double mean = sum(v) / static_cast<double>(v.size());
  double s2 = 0;
  for (double x : v) s2 += (x - mean) * (x - mean);
  return std::sqrt(s2 / static_cast<double>(v.size() - 1));
}

CellSimOptions noise_free_grid() {
  CellSimOptions o;  // the shear test's cell: 251 px, 7 x 7 grid, exponential, Gaussian PSF
  o.noise_free = true;
  return o;
}

TEST(CellLightRadius, EnclosesAllButEpsilon) {
  // Exponential: the light outside x = r / r_s is (1 + x) e^-x.
  const double hlr = 2.0, r = cell_light_radius(1.0, hlr, 0.0, 1e-5);
  const double x = r * kernels::sersic_b(1.0) / hlr;
  EXPECT_NEAR((1 + x) * std::exp(-x), 1e-5, 1e-10);
  // An ellipse's major axis is sqrt((1 + e) / (1 - e)) times the circularised radius.
  EXPECT_NEAR(cell_light_radius(1.0, hlr, 0.6, 1e-5), r * 2.0, 1e-9 * r);
  // de Vaucouleurs: P(8, b_4 (r / r_e)^(1/4)) = 1 - epsilon.
  const double r4 = cell_light_radius(4.0, hlr, 0.0, 1e-3);
  EXPECT_NEAR(1 - kernels::regularized_gamma_p(8.0, kernels::sersic_b(4.0) * std::pow(r4 / hlr, 0.25)), 1e-3, 1e-9);
}

TEST(CellSim, NoiseFreeCellHoldsTheGalaxiesAnalyticFlux) {
  const CellSimOptions o = noise_free_grid();
  const CellSimulator sim(o);
  auto ws = sim.make_workspace();
  const SimCell cell = sim.simulate(0, *ws);
  ASSERT_EQ(cell.objects.size(), 49u);
  double analytic = 0;
  for (const CellObject& obj : cell.objects) analytic += obj.flux;
  EXPECT_DOUBLE_EQ(analytic, 49 * o.flux);
  // The noise (sigma 1e-6 of the S/N's) adds ~sigma * 251 to the sum: ~1e-7 of it.
  EXPECT_NEAR(sum(cell.bands[0].image) / analytic, 1.0, 1e-4);
  // The same for bulge + disc galaxies and a Moffat PSF (whose wings reach further): the bulge's
  // far wings beyond the stamp cap and the cell's edge are the only light missing.
  CellSimOptions bd = o;
  bd.model = CellGalaxyModel::kBulgeDisc;
  bd.psf = CellPsfKind::kMoffat;
  bd.psf_beta = 3.5;
  const CellSimulator sim_bd(bd);
  const SimCell cell_bd = sim_bd.simulate(0, *ws);
  EXPECT_NEAR(sum(cell_bd.bands[0].image) / analytic, 1.0, 2e-3);
  EXPECT_LT(sum(cell_bd.bands[0].image), analytic);
}

TEST(CellSim, GridGalaxiesSitAtTheirTruthPositions) {
  const CellSimOptions o = noise_free_grid();
  const CellSimulator sim(o);
  auto ws = sim.make_workspace();
  const SimCell cell = sim.simulate(3, *ws);
  const std::vector<double>& image = cell.bands[0].image;
  // A 21 px stamp around each galaxy (the grid's spacing is 26 px): adaptive moments' centroid.
  constexpr int kStamp = 21, kHalf = kStamp / 2;
  std::vector<double> stamp(kStamp * kStamp), mask(kStamp * kStamp, 1.0);
  double worst = 0;
  for (const CellObject& obj : cell.objects) {
    const int x0 = static_cast<int>(std::lround(obj.x)) - kHalf, y0 = static_cast<int>(std::lround(obj.y)) - kHalf;
    for (int y = 0; y < kStamp; ++y)
      for (int x = 0; x < kStamp; ++x)
        stamp[static_cast<std::size_t>(y * kStamp + x)] = image[static_cast<std::size_t>((y0 + y) * o.size + x0 + x)];
    const kernels::ImageMoments m = kernels::adaptive_moments(stamp, mask, kStamp);
    ASSERT_TRUE(m.valid) << "object " << obj.id;
    worst = std::max({worst, std::abs(m.x + x0 - obj.x), std::abs(m.y + y0 - obj.y)});
  }
  EXPECT_LT(worst, 0.05);
  // The unsheared scene's grid: 7 x 7 inside the 34 px buffer, each within 1 px of its node.
  const double step = (251.0 - 68.0) / 7;
  for (const CellObject& obj : sim.objects(3, 0.0, 0.0)) {
    const double ix = (obj.x - 33.5) / step - 0.5, iy = (obj.y - 33.5) / step - 0.5;
    EXPECT_LE(std::abs(ix - std::round(ix)) * step, 1.0);
    EXPECT_LE(std::abs(iy - std::round(iy)) * step, 1.0);
  }
}

TEST(CellSim, NoiseHasTheStatedSigma) {
  CellSimOptions o;
  o.snr = 15;
  const CellSimulator sim(o);
  auto ws = sim.make_workspace();
  const SimCell noisy = sim.simulate(1, *ws);
  const double sigma = sim.bands()[0].noise_sigma;
  EXPECT_NEAR(std_dev(noisy.bands[0].noise) / sigma, 1.0, 0.03);
  // The image's noise: the noisy image less the noise-free one (the same galaxies; the noise-free
  // run's normals are the same, scaled by 1e-6).
  o.noise_free = true;
  const CellSimulator quiet(o);
  EXPECT_NEAR(quiet.bands()[0].noise_sigma / sigma, 1e-6, 1e-15);
  const SimCell clean = quiet.simulate(1, *ws);
  std::vector<double> residual(noisy.bands[0].image.size());
  double cross = 0;
  for (std::size_t i = 0; i < residual.size(); ++i) {
    residual[i] = noisy.bands[0].image[i] - clean.bands[0].image[i];
    cross += residual[i] * noisy.bands[0].noise[i];
  }
  EXPECT_NEAR(std_dev(residual) / sigma, 1.0, 0.03);
  // The NOISE plane is another realisation: uncorrelated with the image's (|r| ~ 1 / 251).
  const double r = cross / (static_cast<double>(residual.size()) * sigma * sigma);
  EXPECT_LT(std::abs(r), 0.02);
  // The stated per-object S/N is a round galaxy's, the largest at a given flux; an elongated one's
  // is lower (|e| near 0.8: ~0.85 of it).
  for (const CellObject& obj : noisy.objects) {
    EXPECT_LE(obj.snr / o.snr, 1.001) << "object " << obj.id;
    EXPECT_GE(obj.snr / o.snr, 0.8) << "object " << obj.id;
  }
}

TEST(CellSim, ShearPairSharesGalaxiesAndNoiseAndShearsThePositions) {
  CellSimOptions o;
  o.layout = CellLayout::kRandom;  // blends included
  const CellSimulator sim(o);
  auto ws = sim.make_workspace();
  const SimCell plus = sim.simulate(2, o.g1, o.g2, *ws), minus = sim.simulate(2, -o.g1, -o.g2, *ws);
  EXPECT_EQ(plus.g1, 0.02);
  EXPECT_EQ(minus.g1, -0.02);
  EXPECT_EQ(minus.g2, -plus.g2);
  ASSERT_EQ(plus.objects.size(), minus.objects.size());
  ASSERT_GT(plus.objects.size(), 60u);  // ~109 expected at 100 per arcmin^2
  const std::vector<CellObject> unsheared = sim.objects(2, 0.0, 0.0);
  ASSERT_EQ(unsheared.size(), plus.objects.size());
  const double c = 0.5 * (o.size - 1), n = 1 / std::sqrt(1 - 0.02 * 0.02);
  for (std::size_t k = 0; k < plus.objects.size(); ++k) {
    const CellObject &p = plus.objects[k], &m = minus.objects[k], &u = unsheared[k];
    // The scene is sheared about the cell's centre: x' - c = A(g) (x - c), A = [[1 + g1, 0], [0, 1 - g1]] / sqrt(1 - g1^2).
    EXPECT_NEAR(p.x - c, n * 1.02 * (u.x - c), 1e-9);
    EXPECT_NEAR(p.y - c, n * 0.98 * (u.y - c), 1e-9);
    EXPECT_NEAR(m.x - c, n * 0.98 * (u.x - c), 1e-9);
    EXPECT_NEAR(m.y - c, n * 1.02 * (u.y - c), 1e-9);
    EXPECT_EQ(p.e1_int, m.e1_int);
    EXPECT_EQ(p.e2_int, m.e2_int);
    EXPECT_EQ(p.flux, m.flux);
    // Opposite shears of the same shape: to first order e_obs = e_int +- g.
    EXPECT_NEAR(0.5 * (p.e1_obs - m.e1_obs), 0.02, 0.02 * 0.8 * 0.8 + 1e-12);
  }
  EXPECT_EQ(plus.bands[0].noise, minus.bands[0].noise);
  // The image noise is the same: the pair's difference is that of the noise-free pair.
  CellSimOptions q = o;
  q.noise_free = true;
  const CellSimulator quiet(q);
  const SimCell qplus = quiet.simulate(2, o.g1, o.g2, *ws), qminus = quiet.simulate(2, -o.g1, -o.g2, *ws);
  double worst = 0, peak = 0;
  for (std::size_t i = 0; i < plus.bands[0].image.size(); ++i) {
    const double d = (plus.bands[0].image[i] - minus.bands[0].image[i]) - (qplus.bands[0].image[i] - qminus.bands[0].image[i]);
    worst = std::max(worst, std::abs(d));
    peak = std::max(peak, qplus.bands[0].image[i]);
  }
  EXPECT_LT(worst, 1e-10 * peak);
  EXPECT_GT(peak, 0);
}

TEST(CellSim, RandomLayoutHasThePoissonDensity) {
  CellSimOptions o;
  o.layout = CellLayout::kRandom;
  o.noise_free = true;
  const CellSimulator sim(o);
  const double area = std::pow(251 * 0.25 / 60, 2), mean = 100 * area;
  double total = 0;
  constexpr int kCells = 40;
  for (int k = 0; k < kCells; ++k) {
    const std::vector<CellObject> objs = sim.objects(k, 0.0, 0.0);  // the unsheared scene fills the cell
    total += static_cast<double>(objs.size());
    for (const CellObject& obj : objs) {
      EXPECT_GE(obj.x, -0.5);
      EXPECT_LT(obj.x, 250.5);
      EXPECT_GE(obj.y, -0.5);
      EXPECT_LT(obj.y, 250.5);
    }
  }
  // 40 cells of mean ~109.4: the total's sigma is sqrt(4377) ~ 66; 4 sigma.
  EXPECT_NEAR(total, kCells * mean, 4 * std::sqrt(kCells * mean));
}

TEST(CellSim, ReferencePositionsAreTheReferenceTestsLayouts) {
  // The grid spans the inner region edge to edge; random: int(100 x the inner area) objects uniform
  // over it; each shifted by at most the jitter.
  CellSimOptions o;
  o.reference_positions = true;
  o.noise_free = true;
  const double c = 125, h = 0.5 * (251 - 2 * 34);  // 91.5 px
  {
    const CellSimulator sim(o);
    const std::vector<CellObject> objs = sim.objects(3, 0.0, 0.0);
    ASSERT_EQ(objs.size(), 49u);
    for (int j = 0; j < 7; ++j)
      for (int i = 0; i < 7; ++i) {
        const CellObject& obj = objs[static_cast<std::size_t>(j * 7 + i)];
        EXPECT_LE(std::abs(obj.x - (c + (i - 3) / 3.0 * h)), 1.0) << i << " " << j;
        EXPECT_LE(std::abs(obj.y - (c + (j - 3) / 3.0 * h)), 1.0) << i << " " << j;
      }
  }
  o.layout = CellLayout::kRandom;
  const CellSimulator sim(o);
  double mean_x = 0;
  int n = 0;
  for (int k = 0; k < 20; ++k) {
    const std::vector<CellObject> objs = sim.objects(k, 0.0, 0.0);
    ASSERT_EQ(objs.size(), 58u);  // int(100 x ((251 - 68) x 0.25 / 60)^2)
    for (const CellObject& obj : objs) {
      EXPECT_LE(std::abs(obj.x - c), h + 1.0);
      EXPECT_LE(std::abs(obj.y - c), h + 1.0);
      mean_x += obj.x - c, ++n;
    }
  }
  // Uniform over [-h, h]: the mean's sigma is h / sqrt(3 n) ~ 1.55 px over 1,160 objects; 4 sigma.
  EXPECT_NEAR(mean_x / n, 0.0, 4 * h / std::sqrt(3.0 * n));
}

TEST(CellSim, SameCellForAnyWorkspaceAndOrder) {
  CellSimOptions o;
  o.bands = 2;
  const CellSimulator sim(o);
  auto a = sim.make_workspace(), b = sim.make_workspace();
  const SimCell first = sim.simulate(5, *a);
  sim.simulate(0, *b);  // a workspace that drew another cell first
  const SimCell again = sim.simulate(5, *b);
  for (int band = 0; band < 2; ++band) {
    EXPECT_EQ(first.bands[static_cast<std::size_t>(band)].image, again.bands[static_cast<std::size_t>(band)].image);
    EXPECT_EQ(first.bands[static_cast<std::size_t>(band)].noise, again.bands[static_cast<std::size_t>(band)].noise);
  }
  // Bands: the same galaxies, brighter and sharper towards the last band, one noise sigma.
  EXPECT_EQ(sim.bands()[0].noise_sigma, sim.bands()[1].noise_sigma);
  EXPECT_DOUBLE_EQ(sim.bands()[1].flux_scale, 1.5);
  EXPECT_NEAR(sim.bands()[1].psf_fwhm / sim.bands()[0].psf_fwhm, 0.9, 1e-12);
  EXPECT_NE(first.bands[0].noise, first.bands[1].noise);
}

TEST(CellSim, PsfImageIsCentredWithUnitSum) {
  for (CellPsfKind kind : {CellPsfKind::kGaussian, CellPsfKind::kMoffat}) {
    CellSimOptions o;
    o.psf = kind;
    o.psf_beta = 3.5;
    o.psf_size = 33;
    const CellSimulator sim(o);
    const std::vector<double>& psf = sim.bands()[0].psf;
    ASSERT_EQ(psf.size(), 33u * 33u);
    const std::vector<double> mask(psf.size(), 1.0);
    const kernels::ImageMoments m = kernels::adaptive_moments(psf, mask, 33);
    ASSERT_TRUE(m.valid);
    EXPECT_NEAR(m.x, 16.0, 1e-9);
    EXPECT_NEAR(m.y, 16.0, 1e-9);
    // FWHM 3.6 px: a Gaussian holds all its light in 33 px; a beta 3.5 Moffat loses ~1e-3.
    EXPECT_NEAR(sum(psf), 1.0, kind == CellPsfKind::kGaussian ? 1e-9 : 3e-3);
    // A Gaussian's adaptive-moment size is its own: sigma^2 = (FWHM / 2.3548)^2 plus the pixel's 1/12.
    if (kind == CellPsfKind::kGaussian) {
      const double s = 3.6 / (2 * std::sqrt(2 * std::log(2.0)));
      EXPECT_NEAR(m.xx, s * s + 1.0 / 12, 0.01);
    }
  }
}

TEST(CellSim, BadOptionsNameTheOption) {
  auto why = [](auto change) {
    CellSimOptions o;
    change(o);
    std::string w;
    EXPECT_FALSE(o.IsValid(&w));
    EXPECT_THROW(CellSimulator{o}, std::invalid_argument);
    return w;
  };
  EXPECT_NE(why([](CellSimOptions& o) { o.size = 8; }).find("size 8"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.buffer = 130; }).find("buffer 130"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.snr = 0; }).find("snr 0"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.psf_size = 32; }).find("psf_size 32: must be odd"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.g1 = 0.4; }).find("g1, g2 0.4,0"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.density = -1; }).find("density -1"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.psf_fwhm = 0.1; }).find("psf_fwhm 0.1"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.shape_noise = -0.1; }).find("shape_noise -0.1"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.hlr = 0; }).find("hlr 0"), std::string::npos);
  EXPECT_NE(why([](CellSimOptions& o) { o.psf_beta = 1; }).find("psf_beta 1"), std::string::npos);
}

}  // namespace
}  // namespace stampede

namespace stampede {
namespace {

TEST(CellSim, RotatedSceneTurnsPositionsAndNegatesShapes) {
  CellSimOptions o;
  o.layout = CellLayout::kRandom;
  CellSimOptions r = o;
  r.rotate = true;
  const std::vector<CellObject> a = CellSimulator(o).objects(4, 0.0, 0.0), b = CellSimulator(r).objects(4, 0.0, 0.0);
  ASSERT_EQ(a.size(), b.size());
  const double c = 0.5 * (o.size - 1);
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_NEAR(b[k].x - c, -(a[k].y - c), 1e-12);
    EXPECT_NEAR(b[k].y - c, a[k].x - c, 1e-12);
    EXPECT_EQ(b[k].e1_int, -a[k].e1_int);
    EXPECT_EQ(b[k].e2_int, -a[k].e2_int);
    EXPECT_EQ(b[k].flux, a[k].flux);
  }
}

}  // namespace
}  // namespace stampede
