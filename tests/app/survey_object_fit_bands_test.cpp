// Multi-band fits of `stampede sim meds --bands` tiles (app/survey_object_fit):
// noise-free three bands of four epochs under four shears have no bias and give each band's flux
// (must-show 1); one band through the multi-band path is the single tile's rows bit for bit
// (must-show 2); bad inputs are refused naming the tile, or are flagged rows (must-show 5): band
// names apart only in case, the same tile as two bands, objects at other places in another band's
// tile, a band masked in every cutout of an object.
#include "app/survey_object_fit.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <span>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "app/fit_run.hpp"
#include "app/meds_simulation.hpp"
#include "app/shard_merge.hpp"
#include "io/fits_error.hpp"
#include "io/fits_file.hpp"
#include "io/meds_file.hpp"
#include "app/run_config.hpp"
#include "support/error_assertions.hpp"
#include "support/meds_edit.hpp"
#include "support/scratch_dir.hpp"
#include "support/shear_regression.hpp"

namespace stampede::app {
namespace {

std::vector<double> column(const std::string& file, const char* hdu, const std::string& name) {
  io::FitsFile f = io::FitsFile::open_read(file);
  f.move_to(hdu);
  return f.read_column(name);
}

// Tiles of the same galaxies in `bands` under (g1, g2), DIR/<band>/meds.fits.
void simulate(const std::string& dir, const std::vector<std::string>& bands, MedsSimOptions o) {
  o.bands = static_cast<int>(bands.size());
  for (std::size_t b = 0; b < bands.size(); ++b) {
    o.band = static_cast<int>(b);
    write_meds_simulation(o, dir + "/" + bands[b], true);
  }
}

FitRunOptions run_of(const std::string& dir, const std::vector<std::string>& bands, const std::string& out) {
  FitRunOptions r;
  for (const std::string& b : bands) r.meds.push_back(dir + "/" + b + "/meds.fits");
  r.bands = bands;
  r.output = out;
  r.overwrite = true;
  return r;
}

// `body` throws a ConfigError whose message has every part.
void expect_refused(const std::function<void()>& body, const std::vector<std::string>& parts) {
  const std::string message = testing::error_of<io::ConfigError>(body);
  for (const std::string& p : parts) EXPECT_TRUE(testing::Contains(message, p));
}

using testing::regress;

// Must-show 1: noise-free, 3 bands x 4 epochs, random WCS, per-band PSFs and colours, four shears
// of 8 objects: the common shape's m and c against the galaxies' sheared e, and every band's total
// flux against its truth.
TEST(MultiBandObjectFit, NoiseFreeThreeBandsHaveNoBiasAndGiveEachBandsFlux) {
  testing::ScratchDir dir("stampede_multi_band_");
  const std::vector<std::string> bands = {"g", "r", "i"};
  const double shears[4][2] = {{0.02, -0.015}, {-0.03, 0.01}, {0.0, 0.035}, {0.04, 0.025}};
  std::vector<double> fit1, fit2, true1, true2;
  double worst_e = 0, worst_flux = 0;
  int at_limit = 0;
  for (int s = 0; s < 4; ++s) {
    MedsSimOptions o;
    o.objects = 8, o.epochs = 4, o.noise_free = true, o.snr = 40;
    o.g1 = shears[s][0], o.g2 = shears[s][1];
    o.seed = 300 + static_cast<std::uint64_t>(s);
    const std::string d = dir.path("set" + std::to_string(s)), out = d + "/fit.fits";
    simulate(d, bands, o);
    FitRun(run_of(d, bands, out)).run();
    const auto e1 = column(out, "RESULTS", "e1"), e2 = column(out, "RESULTS", "e2"),
               status = column(out, "RESULTS", "status");
    const auto t1 = column(d + "/g/truth.fits", "TRUTH", "e1_obs"), t2 = column(d + "/g/truth.fits", "TRUTH", "e2_obs");
    for (std::size_t i = 0; i < e1.size(); ++i) {
      // As for one band: a barely resolved galaxy may crawl to the iteration limit with e exact.
      ASSERT_TRUE(status[i] == 0 || status[i] == 1) << "set " << s << " object " << i;
      at_limit += status[i] == 1;
      worst_e = std::max({worst_e, std::abs(e1[i] - t1[i]), std::abs(e2[i] - t2[i])});
      fit1.push_back(e1[i]), fit2.push_back(e2[i]), true1.push_back(t1[i]), true2.push_back(t2[i]);
    }
    for (const std::string& b : bands) {
      const auto flux = column(out, "RESULTS", "flux_" + b), truth = column(d + "/" + b + "/truth.fits", "TRUTH", "flux");
      const auto n = column(out, "RESULTS", "n_epochs_" + b);
      for (std::size_t i = 0; i < flux.size(); ++i) {
        EXPECT_EQ(n[i], 4) << b;
        worst_flux = std::max(worst_flux, std::abs(flux[i] / truth[i] - 1));
      }
    }
    // The bands' truths are the same galaxies: one shape, other fluxes and bulge fractions.
    const auto fg = column(d + "/g/truth.fits", "TRUTH", "bulge_frac"), fi = column(d + "/i/truth.fits", "TRUTH", "bulge_frac");
    EXPECT_NEAR(fi[0], 3 * fg[0], 1e-12);
  }
  double m1, c1, m2, c2;
  regress(true1, fit1, &m1, &c1);
  regress(true2, fit2, &m2, &c2);
  std::printf("noise-free, 3 bands x 4 epochs, 4 shears x 8 objects (%d at the iteration limit): worst |e - e_true| = "
              "%.2e, m = (%+.2e, %+.2e), c = (%+.2e, %+.2e); worst band flux error %.2e relative\n",
              at_limit, worst_e, m1, m2, c1, c2, worst_flux);
  EXPECT_LT(worst_e, 1e-6);
  EXPECT_LT(std::abs(m1), 1e-4);
  EXPECT_LT(std::abs(m2), 1e-4);
  EXPECT_LT(std::abs(c1), 1e-5);
  EXPECT_LT(std::abs(c2), 1e-5);
  EXPECT_LT(worst_flux, 1e-6);
}

// Must-show 2: a noisy tile fitted alone and as the one band of a multi-band run: every column the
// single-tile table has is equal bit for bit, and the band's columns repeat its fit.
TEST(MultiBandObjectFit, OneBandIsTheSingleTileRowsBitForBit) {
  testing::ScratchDir dir("stampede_multi_band_");
  MedsSimOptions o;
  o.objects = 12, o.epochs = 3, o.snr = 25, o.bad_column_fraction = 0.2;
  simulate(dir.path("t"), {"r"}, o);
  FitRunOptions single;
  single.meds = {dir.path("t/r/meds.fits")};
  single.output = dir.path("single.fits");
  FitRun(single).run();
  FitRun(run_of(dir.path("t"), {"r"}, dir.path("band.fits"))).run();
  io::FitsFile f = io::FitsFile::open_read(dir.path("single.fits"));
  f.move_to("RESULTS");
  int compared = 0;
  for (const std::string& name : f.column_names()) {
    if (name == "time_us") continue;
    const auto a = column(dir.path("single.fits"), "RESULTS", name), b = column(dir.path("band.fits"), "RESULTS", name);
    ASSERT_EQ(a.size(), b.size()) << name;
    for (std::size_t i = 0; i < a.size(); ++i, ++compared)
      EXPECT_EQ(std::memcmp(&a[i], &b[i], sizeof(double)), 0) << name << " row " << i << ": " << a[i] << " vs " << b[i];
  }
  const std::pair<const char*, const char*> same[] = {{"flux", "flux_r"}, {"snr", "snr_r"}, {"n_epochs", "n_epochs_r"}};
  for (const auto& [common, band] : same) {
    const auto a = column(dir.path("band.fits"), "RESULTS", common), b = column(dir.path("band.fits"), "RESULTS", band);
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(std::memcmp(&a[i], &b[i], sizeof(double)), 0) << band << " " << i;
  }
  std::printf("one band through the multi-band path: %d values equal the single tile's bitwise\n", compared);
}

// Metacal across bands: one Gamma for both bands' cutouts, each image set fitted jointly; on
// noise-free tiles (2 bands x 2 epochs, random WCS, per-band PSFs) under four shears the combined
// response calibrates the common shape to |m| < 1e-3, |c| < 1e-4, as for one band (fixnoise off:
// the weight maps describe a noise the pixels lack). The same galaxies under each shear: the default
// wmom's e depends on each object's Gamma, so ring partners with other epochs do not cancel and
// other galaxies per shear would put that into m (meds_simulation_test, MedsMetacal).
TEST(MultiBandObjectFit, NoiseFreeMetacalAcrossBandsRecoversTheShear) {
  testing::ScratchDir dir("stampede_multi_band_");
  const std::vector<std::string> bands = {"r", "i"};
  const double shears[4][2] = {{0.02, -0.015}, {-0.015, 0.01}, {0.0, 0.02}, {0.012, 0.016}};
  std::vector<double> g1_fit, g2_fit, g1_applied, g2_applied;
  double r_mean = 0;
  for (int s = 0; s < 4; ++s) {
    MedsSimOptions o;
    o.objects = 16, o.epochs = 2, o.noise_free = true, o.snr = 40;
    o.g1 = shears[s][0], o.g2 = shears[s][1];
    o.seed = 400;
    const std::string d = dir.path("set" + std::to_string(s)), out = d + "/fit.fits";
    simulate(d, bands, o);
    FitRunOptions r = run_of(d, bands, out);
    for (const char* set : {"metacal=true", "metacal_fixnoise=false"}) app::apply_set(r.config, set);
    FitRun(r).run();
    std::vector<std::vector<double>> c;
    for (const char* name : {"e1", "e2", "R11", "R12", "R21", "R22", "flags", "status", "n_epochs_r", "gamma_fwhm", "flux_i"})
      c.push_back(column(out, "RESULTS", name));
    double a1 = 0, a2 = 0, m11 = 0, m12 = 0, m21 = 0, m22 = 0;
    const double n = static_cast<double>(c[0].size());
    for (std::size_t i = 0; i < c[0].size(); ++i) {
      ASSERT_EQ(c[7][i], 0) << "set " << s << " object " << i;
      ASSERT_EQ(c[6][i], 0) << "set " << s << " object " << i;
      EXPECT_EQ(c[8][i], 2);
      EXPECT_GT(c[9][i], 0);
      EXPECT_GT(c[10][i], 0);
      a1 += c[0][i] / n, a2 += c[1][i] / n;
      m11 += c[2][i] / n, m12 += c[3][i] / n, m21 += c[4][i] / n, m22 += c[5][i] / n;
    }
    const double det = m11 * m22 - m12 * m21;
    g1_fit.push_back((m22 * a1 - m12 * a2) / det), g2_fit.push_back((-m21 * a1 + m11 * a2) / det);
    g1_applied.push_back(o.g1), g2_applied.push_back(o.g2);
    r_mean += 0.125 * (m11 + m22);
  }
  double m1, c1, m2, c2;
  regress(g1_applied, g1_fit, &m1, &c1);
  regress(g2_applied, g2_fit, &m2, &c2);
  std::printf("metacal across 2 bands x 2 epochs, noise-free, 4 shears x 16 objects: <R> diagonal %.3f; m = (%+.2e, %+.2e), "
              "c = (%+.2e, %+.2e)\n", r_mean, m1, m2, c1, c2);
  EXPECT_LT(std::abs(m1), 1e-3);
  EXPECT_LT(std::abs(m2), 1e-3);
  EXPECT_LT(std::abs(c1), 1e-4);
  EXPECT_LT(std::abs(c2), 1e-4);
}

// As for one tile: any thread count, shards joined by merge, and a stopped run resumed give the
// same table (time_us aside), the band columns and the BANDS key included.
TEST(MultiBandObjectFit, ThreadsShardsMergeAndResumeGiveTheSameTable) {
  testing::ScratchDir dir("stampede_multi_band_");
  MedsSimOptions o;
  o.objects = 12, o.epochs = 2, o.snr = 25;
  const std::vector<std::string> bands = {"r", "i"};
  simulate(dir.path("t"), bands, o);
  auto run = [&](const std::string& out, int threads, int shard = 0, int shards = 1) {
    FitRunOptions r = run_of(dir.path("t"), bands, out);
    r.threads = threads, r.shard = shard, r.shards = shards;
    app::apply_set(r.config, "batch_size=2");
    return r;
  };
  FitRun(run(dir.path("one.fits"), 1)).run();
  FitRun(run(dir.path("two.fits"), 2)).run();
  FitRun(run(dir.path("s0.fits"), 1, 0, 2)).run();
  FitRun(run(dir.path("s1.fits"), 2, 1, 2)).run();
  ShardMergeOptions merge;
  merge.shards = {dir.path("s1.fits"), dir.path("s0.fits")};
  merge.output = dir.path("merged.fits");
  merge_shards(merge);
  std::atomic<bool> stop{false};
  FitRunOptions stopped = run(dir.path("resumed.fits"), 1);
  stopped.stop = &stop;
  stopped.on_rows = [&](std::span<const ObjectRecord>) { stop.store(true); };
  ASSERT_TRUE(FitRun(stopped).run().interrupted);
  stopped.stop = nullptr, stopped.on_rows = nullptr, stopped.resume = true;
  EXPECT_GT(FitRun(stopped).run().resumed, 0);
  io::FitsFile f = io::FitsFile::open_read(dir.path("one.fits"));
  f.move_to("RESULTS");
  EXPECT_EQ(f.read_key_string("BANDS").value_or(""), "r,i");
  const std::vector<std::string> names = f.column_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "bulge_flux_i"), names.end());
  for (const char* other : {"two.fits", "merged.fits", "resumed.fits"})
    for (const std::string& name : names) {
      if (name == "time_us") continue;
      const auto a = column(dir.path("one.fits"), "RESULTS", name), b = column(dir.path(other), "RESULTS", name);
      ASSERT_EQ(a.size(), b.size()) << other << " " << name;
      for (std::size_t i = 0; i < a.size(); ++i)
        EXPECT_EQ(std::memcmp(&a[i], &b[i], sizeof(double)), 0) << other << " " << name << " row " << i;
    }
}

// Must-show 5: mismatched ids, another object count, a --bands list of the wrong length, a tile
// given twice and a truncated tile are refused before any fit, naming the tile or option; a
// band whose PSFEx models are missing leaves flagged rows fitted from the other bands.
TEST(MultiBandObjectFit, BadInputsAreRefusedOrFlagged) {
  testing::ScratchDir dir("stampede_multi_band_");
  MedsSimOptions o;
  o.objects = 4, o.epochs = 2, o.snr = 30;
  const std::vector<std::string> bands = {"g", "r"};
  simulate(dir.path("t"), bands, o);
  const std::string out = dir.path("out.fits");

  std::filesystem::copy(dir.path("t"), dir.path("ids"), std::filesystem::copy_options::recursive);
  testing::MedsEditor(dir.path("ids/r/meds.fits")).set_cell("object_data", "id", 2, 0, 99LL);
  expect_refused([&] { FitRun(run_of(dir.path("ids"), bands, out)).run(); }, {"ids/r/meds.fits", "row 2 has id 99", "id 3"});

  MedsSimOptions fewer = o;
  fewer.objects = 2;
  simulate(dir.path("few"), bands, o);
  fewer.bands = 2, fewer.band = 1;
  write_meds_simulation(fewer, dir.path("few/r"), true);
  expect_refused([&] { FitRun(run_of(dir.path("few"), bands, out)).run(); }, {"few/r/meds.fits", "has 2 objects", "4"});

  FitRunOptions wrong = run_of(dir.path("t"), bands, out);
  wrong.bands = {"g", "r", "i"};
  expect_refused([&] { FitRun(wrong).run(); }, {"--bands", "3 bands for 2 --meds tiles"});
  wrong.bands = {"g", "g r"};
  expect_refused([&] { FitRun(wrong).run(); }, {"--bands", "'g r'"});
  FitRunOptions twice = run_of(dir.path("t"), bands, out);
  twice.meds[1] = twice.meds[0];
  expect_refused([&] { FitRun(twice).run(); }, {"g/meds.fits", "given twice"});
  // A band's tile cut short (a failed copy): refused at open, naming the tile, before any fit.
  std::filesystem::copy(dir.path("t"), dir.path("cut"), std::filesystem::copy_options::recursive);
  std::filesystem::resize_file(dir.path("cut/r/meds.fits"), std::filesystem::file_size(dir.path("cut/r/meds.fits")) * 3 / 5);
  const std::string cut = testing::error_of<io::FitsError>([&] { FitRun(run_of(dir.path("cut"), bands, out)).run(); });
  EXPECT_TRUE(testing::Contains(cut, "cut/r/meds.fits"));
  EXPECT_TRUE(testing::Contains(cut, "truncated"));
  EXPECT_FALSE(std::filesystem::exists(out));

  // The r band's PSFEx models gone: every row says so, is fitted from g alone (usable for shear:
  // a PSF failure excludes a row only when no band is left), and its r columns say it had no
  // cutouts.
  std::filesystem::copy(dir.path("t"), dir.path("nopsf"), std::filesystem::copy_options::recursive);
  std::filesystem::remove_all(dir.path("nopsf/r/psfex"));
  FitRun(run_of(dir.path("nopsf"), bands, out)).run();
  const auto flags = column(out, "RESULTS", "flags"), status = column(out, "RESULTS", "status");
  const auto n_r = column(out, "RESULTS", "n_epochs_r"), n_g = column(out, "RESULTS", "n_epochs_g");
  const auto flux_r = column(out, "RESULTS", "flux_r"), flux_g = column(out, "RESULTS", "flux_g");
  for (std::size_t i = 0; i < flags.size(); ++i) {
    EXPECT_TRUE(static_cast<std::uint32_t>(flags[i]) & kFlagPsfCutoutDropped) << i;
    EXPECT_FALSE(static_cast<std::uint32_t>(flags[i]) & kFlagPsfFailure) << i;
    EXPECT_TRUE(usable_for_shear(FitStatus::kOk, static_cast<std::uint32_t>(flags[i]))) << i;
    EXPECT_EQ(status[i], 0) << i;
    EXPECT_EQ(n_r[i], 0) << i;
    EXPECT_EQ(n_g[i], 2) << i;
    EXPECT_TRUE(std::isnan(flux_r[i])) << i;
    EXPECT_GT(flux_g[i], 0) << i;
    EXPECT_TRUE(static_cast<std::uint32_t>(flags[i]) & kFlagBandLeftOut) << i;
  }
}

// Band names apart only in case: FITS column lookup ignores case, so flux_G and flux_g were one
// column to readers and merge. Refused before any tile is opened, naming the option and both.
TEST(MultiBandObjectFit, BandNamesDifferingOnlyInCaseAreRefused) {
  testing::ScratchDir dir("stampede_multi_band_");
  FitRunOptions r = run_of(dir.path("t"), {"G", "r", "g"}, dir.path("out.fits"));
  expect_refused([&] { FitRun(r).run(); }, {"--bands: bands 'G' and 'g' differ only in case"});
  EXPECT_FALSE(std::filesystem::exists(dir.path("out.fits")));
}

// The same tile given as two bands (another spelling of its path, a hard link, a copy, "t[0]") was
// fitted as two bands: S/N sqrt(2) too high, errors sqrt(2) too small. Refused by the tiles'
// digests, which the table records, naming both tiles and bands; with no output as well.
TEST(MultiBandObjectFit, TheSameTileAsTwoBandsIsRefused) {
  testing::ScratchDir dir("stampede_multi_band_");
  MedsSimOptions o;
  o.objects = 2, o.epochs = 1, o.snr = 30;
  simulate(dir.path("t"), {"g", "r"}, o);
  const std::string g = dir.path("t/g/meds.fits"), out = dir.path("out.fits");
  std::filesystem::create_hard_link(g, dir.path("link.fits"));
  std::filesystem::copy_file(g, dir.path("copy.fits"));
  for (const std::string& same : {dir.path("t/./g/meds.fits"), dir.path("link.fits"), dir.path("copy.fits"), g + "[0]"}) {
    FitRunOptions r = run_of(dir.path("t"), {"g", "r"}, out);
    r.meds[1] = same;
    const std::string refusal = "--meds '" + same + "' (band r) holds the same bytes as --meds '" + g + "' (band g)";
    expect_refused([&] { FitRun(r).run(); }, {refusal, "one tile per band"});
    r.output.clear();
    expect_refused([&] { FitRun(r).run(); }, {refusal});
  }
  EXPECT_FALSE(std::filesystem::exists(out));
}

// Zero weight in every cutout (coadd included) of object `row` of `tile`.
void mask_object(const std::string& tile, long long row) {
  io::MedsObject o;
  {
    io::MedsFile m = io::MedsFile::open(tile);
    o = m.object(row);
  }
  const std::vector<double> zeros(static_cast<std::size_t>(o.box_size * o.box_size), 0.0);
  testing::MedsEditor(tile).edit([&](fitsfile* f, int* status) {
    fits_movnam_hdu(f, IMAGE_HDU, const_cast<char*>("weight_cutouts"), 0, status);
    for (const io::MedsCutout& c : o.cutouts)
      fits_write_img(f, TDOUBLE, c.start_row + 1, static_cast<LONGLONG>(zeros.size()), const_cast<double*>(zeros.data()),
                     status);
  });
}

// A band masked in every cutout of an object was dropped without a word: n_epochs_r 0, flux_r NaN,
// status ok, no flag. The row is still fitted from the other band, and now says so
// (kFlagBandLeftOut); the other objects' rows do not.
TEST(MultiBandObjectFit, ABandMaskedInEveryCutoutFlagsTheRow) {
  testing::ScratchDir dir("stampede_multi_band_");
  MedsSimOptions o;
  o.objects = 4, o.epochs = 2, o.snr = 30;
  const std::vector<std::string> bands = {"g", "r"};
  simulate(dir.path("t"), bands, o);
  mask_object(dir.path("t/r/meds.fits"), 1);
  const std::string out = dir.path("out.fits");
  FitRun(run_of(dir.path("t"), bands, out)).run();
  const auto flags = column(out, "RESULTS", "flags"), status = column(out, "RESULTS", "status");
  const auto n_r = column(out, "RESULTS", "n_epochs_r"), n_g = column(out, "RESULTS", "n_epochs_g");
  const auto flux_r = column(out, "RESULTS", "flux_r");
  ASSERT_EQ(flags.size(), 4u);
  for (std::size_t i = 0; i < flags.size(); ++i) {
    const bool masked = i == 1;
    EXPECT_EQ(static_cast<bool>(static_cast<std::uint32_t>(flags[i]) & kFlagBandLeftOut), masked) << i;
    EXPECT_EQ(status[i], 0) << i;
    EXPECT_EQ(n_g[i], 2) << i;
    EXPECT_EQ(n_r[i], masked ? 0 : 2) << i;
    EXPECT_EQ(std::isnan(flux_r[i]), masked) << i;
  }
}

}  // namespace
}  // namespace stampede::app
