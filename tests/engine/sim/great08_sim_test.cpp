// The GREAT08-like simulator: against the GalSim sets (same truth -> same pixels, same PSF images,
// same size calibration), and its own promises (S/N, noise level, ring pairs, determinism).
#include "engine/sim/great08_sim.hpp"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <vector>

#include "io/fits_file.hpp"
#include "kernels/psf_profile.hpp"
#include "tests/support/reference_data.hpp"

namespace stampede {
namespace {

using testing::data_path;

const Great08Simulator& mini_simulator() {
  static const Great08Simulator sim{Great08SimOptions{}};  // the GREAT08-mini settings
  return sim;
}

// Every noise-free GalSim stamp of set 0, drawn by our renderer from its truth row.
TEST(Great08Sim, RendersTheGalSimSetFromItsTruth) {
  io::FitsFile truth = io::FitsFile::open_read(data_path("galsim-great08-mini/nf/truth_0.fits"));
  truth.move_to("TRUTH");
  auto col = [&](const char* name) { return truth.read_column(name); };
  const auto xc = col("x_centre"), yc = col("y_centre"), e1 = col("e1_obs"), e2 = col("e2_obs"), hlr = col("hlr"),
             bflux = col("bulge_flux"), dflux = col("disc_flux"), ix = col("ix"), iy = col("iy");
  io::FitsFile set = io::FitsFile::open_read(data_path("galsim-great08-mini/nf/set_0.fits"));
  const auto image = set.read_image();
  const int s = 39, width = 780;
  SimWorkspace ws;
  std::vector<double> ours(s * s), theirs(s * s);
  double worst = 0;
  for (std::size_t i = 0; i < xc.size(); i += 7) {  // every 7th object keeps the test quick
    std::vector<SimComponent> comps = {{4.0, bflux[i], hlr[i], e1[i], e2[i], xc[i], yc[i]},
                                       {1.0, dflux[i], hlr[i], e1[i], e2[i], xc[i], yc[i]}};
    mini_simulator().renderer().render(comps, s, ours, ws);
    double peak = 0, diff = 0;
    for (int y = 0; y < s; ++y)
      for (int x = 0; x < s; ++x) {
        const double v = image[(static_cast<std::size_t>(iy[i]) * s + y) * width + static_cast<std::size_t>(ix[i]) * s + x];
        peak = std::max(peak, v);
        diff = std::max(diff, std::abs(v - ours[static_cast<std::size_t>(y) * s + x]));
      }
    worst = std::max(worst, diff / peak);
  }
  std::printf("worst |ours - GalSim| / peak over the sampled stamps: %.2e\n", worst);
  // The README quotes the GalSim sets as accurate to ~5e-5 of the peak (and stored as float32).
  EXPECT_LT(worst, 1e-4);
}


// GalSim's PSF files: the pixel-integrated image and the 5x oversampled one without the pixel.
TEST(Great08Sim, PsfImagesMatchGalSim) {
  io::FitsFile f = io::FitsFile::open_read(data_path("galsim-great08-mini/nf/psf_0.fits"));
  const auto theirs = f.read_image();
  f.move_to("PSF_NOPIX_OS");
  const auto theirs_os = f.read_image();
  const auto ours = mini_simulator().psf_image();
  const auto ours_os = mini_simulator().psf_oversampled(5);
  ASSERT_EQ(ours.size(), theirs.size());
  ASSERT_EQ(ours_os.size(), theirs_os.size());
  auto worst = [](const std::vector<double>& a, const std::vector<double>& b) {
    double peak = 0, d = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      peak = std::max(peak, b[i]);
      d = std::max(d, std::abs(a[i] - b[i]));
    }
    return d / peak;
  };
  const double w = worst(ours, theirs), w_os = worst(ours_os, theirs_os);
  std::printf("PSF image: worst %.2e of peak; oversampled no-pixel: %.2e\n", w, w_os);
  // GalSim evaluates the no-pixel profile directly, and it agrees to 4e-8. Its pixel-integrated
  // image comes from an FFT at default accuracy and is off by 3.7e-4 at the centre, ringing
  // outwards; the direct quadrature below shows the error is GalSim's (ours agrees to 4e-7).
  EXPECT_LT(w_os, 1e-6);
  EXPECT_LT(w, 5e-4);
  const kernels::MoffatProfile& m = mini_simulator().options().psf.moffat;
  constexpr int kSub = 300;  // midpoint rule: its own error is ~7e-7 of the peak (h^2 scaling)
  double direct_worst = 0;
  for (int y = 18; y <= 20; ++y)
    for (int x = 18; x <= 20; ++x) {
      double sum = 0;
      for (int j = 0; j < kSub; ++j)
        for (int i = 0; i < kSub; ++i)
          sum += kernels::moffat_intensity(m, x - 19 - 0.5 + (i + 0.5) / kSub, y - 19 - 0.5 + (j + 0.5) / kSub);
      direct_worst = std::max(direct_worst, std::abs(sum / (kSub * kSub) - ours[y * 39 + x]));
    }
  std::printf("PSF image vs direct pixel quadrature (central 3x3): %.2e of peak\n", direct_worst / ours[19 * 39 + 19]);
  EXPECT_LT(direct_worst / ours[19 * 39 + 19], 2e-6);
  f.move_to(0);
  double sum = 0;
  for (double v : ours) sum += v;
  // The light of a unit-flux Moffat inside the stamp; GalSim's own sum differs by its image error.
  EXPECT_NEAR(sum, f.key_double("PSFSUM"), 2e-5);
}

// The size definition: GalSim's calibration for Rgp/Rp = 1.4 (run_info.json: hlr_disc_only,
// hlr_bulge_only) and the half-light radius of every truth row for its bulge fraction.
TEST(Great08Sim, SizeCalibrationMatchesGalSim) {
  const Great08Simulator& sim = mini_simulator();
  const double disc = sim.half_light_radius(0.0), bulge = sim.half_light_radius(1.0);
  std::printf("hlr for Rgp/Rp = 1.4: disc %.6f (GalSim 1.267388), bulge %.6f (GalSim 2.991651)\n", disc, bulge);
  EXPECT_NEAR(disc, 1.267388201586823, 2e-4 * disc);
  EXPECT_NEAR(bulge, 2.9916512065943093, 2e-4 * bulge);
  io::FitsFile truth = io::FitsFile::open_read(data_path("galsim-great08-mini/nf/truth_0.fits"));
  truth.move_to("TRUTH");
  const auto hlr = truth.read_column("hlr"), bf = truth.read_column("bulge_frac");
  double worst = 0;
  for (std::size_t i = 0; i < hlr.size(); i += 20) worst = std::max(worst, std::abs(sim.half_light_radius(bf[i]) / hlr[i] - 1));
  std::printf("worst relative hlr difference over sampled truth rows: %.2e\n", worst);
  EXPECT_LT(worst, 2e-4);
}

Great08SimOptions small_options() {
  Great08SimOptions o;
  o.grid = 4;
  o.sets = 1;
  return o;
}

SimSet draw_with_threads(const Great08Simulator& sim, int threads, int k) {
  tbb::task_arena arena(threads);
  SimSet out;
  arena.execute([&] { out = sim.simulate_set(k); });
  return out;
}

TEST(Great08Sim, SetIsIdenticalForAnyThreadCount) {
  Great08SimOptions o = small_options();
  const Great08Simulator sim(o);
  const SimSet one = draw_with_threads(sim, 1, 3), two = draw_with_threads(sim, 2, 3);
  ASSERT_EQ(one.image.size(), two.image.size());
  EXPECT_TRUE(std::equal(one.image.begin(), one.image.end(), two.image.begin()));
  EXPECT_EQ(one.shear1, two.shear1);
  EXPECT_EQ(one.noise_seed, two.noise_seed);
  for (std::size_t i = 0; i < one.truth.size(); ++i) EXPECT_EQ(one.truth[i].flux, two.truth[i].flux);
  // Another set is a different draw.
  const SimSet other = draw_with_threads(sim, 2, 4);
  EXPECT_NE(other.shear1, one.shear1);
}

TEST(Great08Sim, RingPairsSignalToNoiseAndShearRange) {
  Great08SimOptions o = small_options();
  o.noise_free = true;
  const Great08Simulator sim(o);
  const SimSet set = sim.simulate_set(0);
  EXPECT_LT(std::abs(set.shear1), o.shear_max);
  EXPECT_LT(std::abs(set.shear2), o.shear_max);
  ASSERT_EQ(set.truth.size(), 16u);
  for (std::size_t i = 0; i < set.truth.size(); ++i) {
    const SimObjectTruth& t = set.truth[i];
    EXPECT_EQ(t.index, static_cast<long long>(i));
    EXPECT_EQ(t.pair, static_cast<long long>(i / 2));
    EXPECT_NEAR(t.snr, o.snr, 1e-9 * o.snr);
    EXPECT_LT(std::hypot(t.e1_int, t.e2_int), o.e_max);
    // The stamp holds what the truth says: its S/N and flux sum, from the pixels themselves.
    double sum = 0, sum2 = 0;
    for (int y = 0; y < o.stamp_size; ++y)
      for (int x = 0; x < o.stamp_size; ++x) {
        const double v = set.image[(t.iy * o.stamp_size + y) * set.width + t.ix * o.stamp_size + x];
        sum += v;
        sum2 += v * v;
      }
    EXPECT_NEAR(std::sqrt(sum2) / o.noise_sigma, o.snr, 1e-9 * o.snr);
    EXPECT_NEAR(sum, t.stamp_flux, 1e-9 * sum);
    EXPECT_LT(sum, t.flux);  // some light falls outside the stamp
    EXPECT_NEAR(t.hlr, sim.half_light_radius(t.bulge_frac), 1e-9);
    if (i % 2 == 1) {
      const SimObjectTruth& a = set.truth[i - 1];
      EXPECT_EQ(t.e1_int, -a.e1_int);
      EXPECT_EQ(t.e2_int, -a.e2_int);
      EXPECT_EQ(t.hlr, a.hlr);
      EXPECT_EQ(t.x_centre, a.x_centre);
      // Lensing: e_obs = (e_int + g) / (1 + conj(g) e_int).
      const std::complex<double> g(set.shear1, set.shear2), e(t.e1_int, t.e2_int);
      const std::complex<double> obs = (e + g) / (1.0 + std::conj(g) * e);
      EXPECT_NEAR(t.e1_obs, obs.real(), 1e-15);
      EXPECT_NEAR(t.e2_obs, obs.imag(), 1e-15);
    }
  }
}

TEST(Great08Sim, NoiseHasTheRequestedSigma) {
  Great08SimOptions o = small_options();
  const Great08Simulator sim(o);
  const SimSet noisy = sim.simulate_set(0);
  o.noise_free = true;
  const SimSet clean = Great08Simulator(o).simulate_set(0);
  double s1 = 0, s2 = 0;
  for (std::size_t i = 0; i < noisy.image.size(); ++i) {
    const double d = noisy.image[i] - clean.image[i];
    s1 += d;
    s2 += d * d;
  }
  const double n = static_cast<double>(noisy.image.size());
  const double mean = s1 / n, sigma = std::sqrt(s2 / n - mean * mean);
  // 24336 pixels: the sample sigma has a standard error of sigma / sqrt(2n) = 0.45%.
  EXPECT_NEAR(sigma, o.noise_sigma, 0.02);
  EXPECT_NEAR(mean, 0.0, 5 * o.noise_sigma / std::sqrt(n));
  EXPECT_NE(noisy.noise_seed, 0u);
  EXPECT_EQ(clean.noise_seed, 0u);
}


// Noise pairs: 4q+2 and 4q+3 are 4q and 4q+1 again with the noise negated, so each copy pair
// averages to the noise-free stamp, and all four share the pair label q.
TEST(Great08Sim, NoisePairsRepeatTheRingPairWithNegatedNoise) {
  Great08SimOptions o = small_options();
  o.noise_pairs = true;
  const SimSet noisy = Great08Simulator(o).simulate_set(1);
  o.noise_free = true;
  const SimSet clean = Great08Simulator(o).simulate_set(1);
  const int s = o.stamp_size;
  auto pixel = [&](const SimSet& set, const SimObjectTruth& t, int x, int y) {
    return set.image[(t.iy * s + y) * set.width + t.ix * s + x];
  };
  ASSERT_EQ(noisy.truth.size(), 16u);
  for (std::size_t i = 0; i < noisy.truth.size(); ++i) {
    const SimObjectTruth& t = noisy.truth[i];
    EXPECT_EQ(t.pair, static_cast<long long>(i / 4));
    const SimObjectTruth& first = noisy.truth[i - i % 4 + i % 2];  // the copy with +n
    EXPECT_EQ(t.e1_obs, first.e1_obs);
    EXPECT_EQ(t.flux, first.flux);
    EXPECT_EQ(t.x_centre, first.x_centre);
    if (i % 4 == 1) {
      EXPECT_EQ(t.e1_int, -noisy.truth[i - 1].e1_int);  // still a ring pair
    }
    double max_sum_error = 0, noise2 = 0;
    for (int y = 0; y < s; ++y)
      for (int x = 0; x < s; ++x) {
        const double v = pixel(noisy, t, x, y), v_first = pixel(noisy, first, x, y), v_clean = pixel(clean, t, x, y);
        if (i % 4 >= 2) max_sum_error = std::max(max_sum_error, std::abs(v + v_first - 2 * v_clean));
        noise2 += (v - v_clean) * (v - v_clean);
      }
    EXPECT_LT(max_sum_error, 1e-12 * (1 + t.flux));
    EXPECT_NEAR(std::sqrt(noise2 / (s * s)), o.noise_sigma, 0.1);  // every copy is noisy
  }
}

// Shear pairs: set 2j+1 is set 2j under -g: the same intrinsic galaxies and the same noise field
// (noisy minus noise-free stamps agree pixel for pixel), opposite shears, and set 2j unchanged.
TEST(Great08Sim, ShearPairsRepeatGalaxiesAndNoiseUnderTheOppositeShear) {
  Great08SimOptions o = small_options();
  const SimSet unpaired = Great08Simulator(o).simulate_set(2);
  o.shear_pairs = true;
  const SimSet plus = Great08Simulator(o).simulate_set(2), minus = Great08Simulator(o).simulate_set(3);
  o.noise_free = true;
  const SimSet plus_clean = Great08Simulator(o).simulate_set(2), minus_clean = Great08Simulator(o).simulate_set(3);
  EXPECT_EQ(plus.image, unpaired.image);  // the even set is the unpaired run's set
  EXPECT_EQ(minus.shear1, -plus.shear1);
  EXPECT_EQ(minus.shear2, -plus.shear2);
  EXPECT_NE(plus.shear1, 0.0);
  EXPECT_EQ(minus.noise_seed, plus.noise_seed);
  ASSERT_EQ(plus.truth.size(), minus.truth.size());
  for (std::size_t i = 0; i < plus.truth.size(); ++i) {
    EXPECT_EQ(minus.truth[i].e1_int, plus.truth[i].e1_int);
    EXPECT_EQ(minus.truth[i].e2_int, plus.truth[i].e2_int);
    EXPECT_EQ(minus.truth[i].x_centre, plus.truth[i].x_centre);
    EXPECT_EQ(minus.truth[i].g1, -plus.truth[i].g1);
  }
  double largest = 0, sheared = 0;
  for (std::size_t p = 0; p < plus.image.size(); ++p) {
    largest = std::max(largest, std::abs((minus.image[p] - minus_clean.image[p]) - (plus.image[p] - plus_clean.image[p])));
    sheared = std::max(sheared, std::abs(minus_clean.image[p] - plus_clean.image[p]));
  }
  EXPECT_LT(largest, 1e-12);  // the same noise, to the rounding of signal + noise
  EXPECT_GT(sheared, 1e-3);  // while the galaxies differ by the shear
}

// --shear G1,G2: every set's shear, the odd set of a shear pair's negated.
TEST(Great08Sim, AFixedShearIsEverySetsShear) {
  Great08SimOptions o = small_options();
  o.shear_pairs = true;
  o.fixed_shear = true;
  o.shear1 = 0.02, o.shear2 = -0.015;
  const SimSet plus = Great08Simulator(o).simulate_set(4), minus = Great08Simulator(o).simulate_set(5);
  EXPECT_EQ(plus.shear1, 0.02);
  EXPECT_EQ(plus.shear2, -0.015);
  EXPECT_EQ(minus.shear1, -0.02);
  EXPECT_EQ(minus.shear2, 0.015);
  for (const auto& t : plus.truth) EXPECT_EQ(t.g1, 0.02);
  o.shear1 = 0.25;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("shear 0.25,-0.015: each component must be in [-0.2, 0.2]"), std::string::npos) << why;
}

// The b+d branch: a misaligned, offset bulge with its own radius, and the round-galaxy size kept.
TEST(Great08Sim, BulgePlusDiscBranch) {
  Great08SimOptions o = small_options();
  o.galaxy_type = SimGalaxyType::kBulgePlusDisc;
  o.noise_free = true;
  const Great08Simulator sim(o);
  const SimSet set = sim.simulate_set(0);
  double largest_offset = 0, largest_turn = 0;
  for (const SimObjectTruth& t : set.truth) {
    EXPECT_NEAR(t.hlr_bulge, o.bd_radius_ratio * t.hlr, 1e-12);
    largest_offset = std::max(largest_offset, std::hypot(t.bulge_dx, t.bulge_dy));
    largest_turn = std::max(largest_turn, std::abs(std::arg(std::complex<double>(t.e1_int_bulge, t.e2_int_bulge) /
                                                            std::complex<double>(t.e1_int, t.e2_int))));
  }
  EXPECT_GT(largest_offset, 0.0);
  EXPECT_LT(largest_offset, 1.1 * o.bd_offset);  // the shear stretches an offset by < 1.1
  EXPECT_GT(largest_turn, 0.0);
  // Size: the round galaxy with that bulge fraction and radius has Rgp/Rp = size_ratio.
  const SimObjectTruth& t = set.truth[0];
  const std::vector<SimComponent> round = {{4.0, t.bulge_frac, t.hlr_bulge, 0, 0, 0, 0},
                                           {1.0, 1 - t.bulge_frac, t.hlr, 0, 0, 0, 0}};
  EXPECT_NEAR(sim.renderer().round_fwhm(round) / sim.renderer().round_fwhm({}), o.size_ratio, 1e-8);
}

TEST(Great08Sim, InvalidOptionsNameTheOption) {
  Great08SimOptions o;
  o.size_ratio = 0.9;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("size_ratio 0.9"), std::string::npos) << why;
  o = Great08SimOptions{};
  o.psf.kind = PsfKind::kAiry;
  o.psf.airy.obscuration = 0.3;
  EXPECT_THROW(Great08Simulator{o}, std::invalid_argument);
  // Found by the Python argument fuzzer: psf_fwhm = 1e9 drew for hours (1e4: 22 s) instead of refusing.
  o = Great08SimOptions{};
  o.stamp_size = 8;
  o.psf.moffat.fwhm = 1e9;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("the PSF's FWHM must be at most the stamp (8 pixels)"), std::string::npos) << why;
  o.psf.moffat.fwhm = 8;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  // And (the same fuzzer) FWHM 1.1 with Rgp/Rp 2.85 took 59 s for one 8-pixel stamp.
  o.psf.moffat.fwhm = 1.1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("psf_fwhm 1.1: the simulator draws PSFs of FWHM >= 1.5 pixels"), std::string::npos) << why;
}

}  // namespace
}  // namespace stampede
