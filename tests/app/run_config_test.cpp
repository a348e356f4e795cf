// Tests for app/run_config (and io/option_registry beneath it): defaults equal the engine's struct defaults, every key round-trips
// exactly and is documented, the ini reader's syntax, and that every bad input is a ConfigError
// naming the file, line and key.
#include "app/run_config.hpp"

#include <gtest/gtest.h>

#include "support/error_assertions.hpp"
#include "support/scratch_dir.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace stampede::app {
namespace {

using stampede::testing::Contains;
using stampede::testing::error_of;

namespace fs = std::filesystem;

// NaN == NaN and -0 != +0: "the same value" as a round trip must preserve it.
bool same_double(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0 || (std::isnan(a) && std::isnan(b)); }

// A fresh private directory per test, removed afterwards, so parallel ctest runs cannot collide.
class RunConfigFile : public ::testing::Test {
 protected:
  // Writes `text` to DIR/run.ini and returns the path.
  std::string write_ini(const std::string& text, const std::string& name = "run.ini") const {
    const std::string path = scratch_.path(name);
    std::ofstream(path) << text;
    return path;
  }
  // The ConfigError message of loading `text` into a default config (which must stay unchanged).
  std::string load_error(const std::string& text) const {
    RunConfig c;
    const std::string msg = error_of<ConfigError>([&] { load_ini(c, write_ini(text)); });
    EXPECT_TRUE(c.explicitly_set.empty()) << "a failed load changed the config";
    return msg;
  }

  stampede::testing::ScratchDir scratch_{"stampede_cfg_"};
};

// --- defaults and the registry -------------------------------------------------------------------

TEST(RunConfigDefaults, EqualTheEngineStructDefaults) {
  const RunConfig c;
  const FitterOptions f;
  EXPECT_EQ(c.fitter.render.stamp_size, f.render.stamp_size);
  EXPECT_EQ(c.fitter.render.upsampling, f.render.upsampling);
  EXPECT_EQ(c.fitter.render.padding, f.render.padding);
  EXPECT_EQ(c.fitter.lm.max_iterations, f.lm.max_iterations);
  EXPECT_EQ(c.fitter.noise_sigma, 0.0);
  EXPECT_EQ(c.psf_kind, PsfKind::kMoffat);
  EXPECT_FALSE(c.psf_from_catalogue);
  EXPECT_EQ(c.fitter.renderer, RendererKind::kAuto);
  EXPECT_EQ(c.fitter.renderer, f.renderer);
  EXPECT_EQ(c.fitter.render.exact.surrogate, f.render.exact.surrogate);
  EXPECT_EQ(c.fitter.surrogate_eps4, f.surrogate_eps4);
  EXPECT_EQ(c.batch_size, 32);
  EXPECT_TRUE(c.explicitly_set.empty());

  // And as text: the registry's documented defaults are the structs' values.
  const auto text = [&](const char* key) { return get_option(c, key); };
  EXPECT_EQ(text("stamp_size"), "39");
  EXPECT_EQ(text("upsampling"), "5");
  EXPECT_EQ(text("n_central_pixels_to_upsample"), "3");
  EXPECT_EQ(text("n_central_pixel_upsampling"), "7");
  EXPECT_EQ(text("padding"), "4");
  EXPECT_EQ(text("noise_sigma"), "0");
  EXPECT_EQ(text("levmar_eps4"), "1e-06");
  EXPECT_EQ(text("levmar_LM_INIT_MU"), "0.001");
  EXPECT_EQ(text("minimizer_max_iterations"), "200");
  EXPECT_EQ(text("ellipticity_mirror"), "0.95");
  EXPECT_EQ(text("radius_softening"), "0.4");
  EXPECT_EQ(text("psf_input"), "moffat");
  EXPECT_EQ(text("psf_beta"), "3");
  EXPECT_EQ(text("psf_fwhm"), "2.85");
  EXPECT_EQ(text("psf_truncation"), "0");
  EXPECT_EQ(text("airy_lambda_over_d"), "2");
  EXPECT_EQ(text("psf_upsampling"), "1");
  EXPECT_EQ(text("psf_pixel_integrated"), "true");
  EXPECT_EQ(text("batch_size"), "32");
  EXPECT_EQ(text("fft_wisdom"), "");
  EXPECT_EQ(text("catalog_id_column"), "id");
  EXPECT_EQ(text("catalog_psf_e2_column"), "psf_e2");
  EXPECT_EQ(text("save_images"), "");
  EXPECT_EQ(text("x0_start"), "auto");
  EXPECT_EQ(text("x0_min"), "auto");
  EXPECT_EQ(text("e1_min"), "-3");
  EXPECT_EQ(text("bulge_A_min"), "-inf");
  EXPECT_EQ(text("bulge_A_max"), "inf");
  EXPECT_EQ(text("radius_ratio_start"), "1");
  EXPECT_EQ(text("bulge_index_start"), "4");
  EXPECT_EQ(text("disc_A_free"), "true");
  EXPECT_EQ(text("delta_theta_free"), "false");

  EXPECT_NO_THROW(validate(c));
}

TEST(RunConfigDefaults, ParameterSpecsEqualParameterSetDefaults) {
  const RunConfig c;
  const auto defaults = ParameterSet::defaults();
  for (int k = 0; k < kNumParams; ++k) {
    const std::string n(param_name(static_cast<Param>(k)));
    EXPECT_TRUE(same_double(c.fitter.params.spec[k].start, defaults[k].start)) << n;
    EXPECT_TRUE(same_double(c.fitter.params.spec[k].lower, defaults[k].lower)) << n;
    EXPECT_TRUE(same_double(c.fitter.params.spec[k].upper, defaults[k].upper)) << n;
    EXPECT_EQ(c.fitter.params.spec[k].free, defaults[k].free) << n;
  }
}

TEST(RunConfigRegistry, ListsEveryKeyOnceWithItsDefaultAndHelp) {
  const auto& options = run_config_options();
  std::set<std::string> names;
  for (const io::OptionInfo& o : options) {
    EXPECT_TRUE(names.insert(o.name).second) << "duplicate key " << o.name;
    EXPECT_EQ(o.default_value, get_option(RunConfig{}, o.name)) << o.name;
    EXPECT_FALSE(o.help.empty()) << o.name;
  }
  for (const char* key :
       {"renderer", "stamp_size", "upsampling", "n_central_pixels_to_upsample", "n_central_pixel_upsampling", "padding",
        "noise_sigma", "levmar_eps1", "levmar_eps2", "levmar_eps3", "levmar_eps4", "levmar_LM_INIT_MU",
        "minimizer_max_iterations", "project_amplitudes", "metacal", "metacal_step", "metacal_psf_dilation",
        "metacal_fixnoise", "metacal_seed", "ellipticity_mirror", "radius_softening", "psf_input", "psf_beta", "psf_fwhm",
        "psf_e1", "psf_e2", "psf_truncation", "airy_lambda_over_d", "airy_obscuration", "psf_image",
        "psf_upsampling", "psf_pixel_integrated", "batch_size", "fft_wisdom", "catalog_id_column",
        "catalog_x_column", "catalog_y_column", "catalog_psf_beta_column", "catalog_psf_fwhm_column",
        "catalog_psf_e1_column", "catalog_psf_e2_column", "meds_model", "meds_psf", "meds_fit_coadd", "meds_bmask_bits",
        "meds_uberseg", "meds_min_unmasked_fraction", "meds_magzp_ref", "meds_psf_dir", "save_images", "exact_surrogate",
        "surrogate_period", "surrogate_psf_tolerance", "surrogate_wrap_rings", "surrogate_wrap_nodes", "surrogate_eps4", "metacal_model",
        "metacal_weight_fwhm", "metacal_reconvolution_psf"})
    EXPECT_TRUE(names.contains(key)) << key;
  for (int k = 0; k < kNumParams; ++k) {
    const std::string n(param_name(static_cast<Param>(k)));
    for (const char* suffix : {"_start", "_min", "_max", "_free"})
      EXPECT_TRUE(names.contains(n + suffix)) << n + suffix;
  }
  EXPECT_EQ(options.size(), 64u + 4u * kNumParams);
}

// The survey options: bmask bits in decimal or hex, the two models, and the bounds validate checks.
TEST(RunConfigRegistry, MedsOptionsParseAndValidate) {
  RunConfig c;
  set_option(c, "meds_bmask_bits", "0x40000001");
  EXPECT_EQ(c.meds.bmask_bits, 0x40000001u);
  EXPECT_EQ(get_option(c, "meds_bmask_bits"), "1073741825");
  set_option(c, "meds_bmask_bits", "4294967295");
  EXPECT_EQ(c.meds.bmask_bits, 0xffffffffu);
  for (const char* bad : {"-1", "4294967296", "0x", "12abc", ""})
    EXPECT_TRUE(Contains(error_of<ConfigError>([&] { set_option(c, "meds_bmask_bits", bad); }), "meds_bmask_bits")) << bad;
  set_option(c, "meds_model", "BORD");
  EXPECT_EQ(c.meds.model, io::MedsModel::kBulgeOrDisc);
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { set_option(c, "meds_model", "sersic"); }), "expected bd or bord"));
  set_option(c, "meds_min_unmasked_fraction", "1.5");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "meds_min_unmasked_fraction = 1.5: must be in [0, 1]"));
}

// metacal_model's four values (wmom: the weighted moments, no fit) and the weight's width bounds.
TEST(RunConfigRegistry, MetacalModelAndWeightParseAndValidate) {
  RunConfig c;
  EXPECT_EQ(get_option(c, "metacal_model"), "wmom");  // the default
  set_option(c, "metacal", "true");
  set_option(c, "metacal_model", "BD");
  EXPECT_EQ(c.metacal.model, MetacalModel::kBulgeDisc);
  set_option(c, "metacal_model", "WMOM");
  EXPECT_EQ(c.metacal.model, MetacalModel::kWeightedMoments);
  EXPECT_EQ(get_option(c, "metacal_model"), "wmom");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { set_option(c, "metacal_model", "moments"); }),
                       "expected bd, exp, gauss or wmom"));
  set_option(c, "metacal_weight_fwhm", "4.5");
  EXPECT_NO_THROW(validate(c));
  set_option(c, "metacal_weight_fwhm", "0.05");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }),
                       "metacal_weight_fwhm = 0.05: must be 0 (automatic) or in [0.1, 1000] (pixels; arcsec for MEDS tiles)"));
}

// metacal_reconvolution_psf's three rules (auto the default), case-insensitive; anything else refused.
TEST(RunConfigRegistry, MetacalReconvolutionPsfParses) {
  RunConfig c;
  EXPECT_EQ(get_option(c, "metacal_reconvolution_psf"), "auto");
  set_option(c, "metacal_reconvolution_psf", "Gauss");
  EXPECT_EQ(c.metacal.reconvolution, ReconvolutionRule::kGauss);
  set_option(c, "metacal_reconvolution_psf", "moffat");
  EXPECT_EQ(get_option(c, "metacal_reconvolution_psf"), "moffat");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { set_option(c, "metacal_reconvolution_psf", "fitgauss"); }),
                       "expected auto, gauss or moffat"));
}

// metacal_weight_fwhm is the wmom moments' weight: with a model fit (bd, exp, gauss) it was
// silently unused; refused, naming both options.
TEST(RunConfigValidate, AMomentsWeightWithAModelFitIsRefused) {
  RunConfig c;
  set_option(c, "metacal", "true");
  set_option(c, "metacal_weight_fwhm", "4.5");
  EXPECT_NO_THROW(validate(c));  // wmom, the default
  for (const char* model : {"bd", "exp", "gauss"}) {
    set_option(c, "metacal_model", model);
    EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }),
                         std::string("metacal_weight_fwhm = 4.5 with metacal_model = ") + model +
                             ": it is the wmom moments' weight, and a model fit has none"))
        << model;
  }
  set_option(c, "metacal_weight_fwhm", "0");  // automatic: nothing to ignore
  EXPECT_NO_THROW(validate(c));
}

// metacal_step was accepted in (0, 0.1], but at 1e-4 .. 1e-8 errors in e over 2 step swamped R, with
// status ok (bd at 1e-4: mean R11 3.2). Refused below the measured floor (docs/metacal.md, "The
// step's floor"), naming the option, its value and the bound.
TEST(RunConfigValidate, MetacalStepBelowItsFloorIsRefused) {
  RunConfig c;
  set_option(c, "metacal", "true");
  for (const char* step : {"1e-04", "1e-08", "9e-04"}) {  // as the message writes them
    set_option(c, "metacal_step", step);
    EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }),
                         std::string("metacal_step = ") + step + ": must be in [0.001, 0.1] (below it, errors in e of the "
                         "image operations and fits, over 2 metacal_step, swamp R"))
        << step;
  }
  set_option(c, "metacal_step", "0");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "metacal_step = 0: must be in [0.001, 0.1]"));
  for (const char* step : {"0.001", "0.1"}) {
    set_option(c, "metacal_step", step);
    EXPECT_NO_THROW(validate(c)) << step;
  }
  EXPECT_EQ(MetacalOptions::kMinStep, 0.001);  // the help text and docs/usage.md say 0.001
}

// --- get / set -----------------------------------------------------------------------------------

// Every key, from the defaults and from awkward values: the text get_option gives sets the
// identical value, and reading it again gives the identical text.
TEST(RunConfigRoundTrip, EveryKeyGetSetGetIsExact) {
  const std::vector<std::string> candidates = {
      "0.30000000000000004", "1e-300", "-0", "123456789.123456789", "7", "-2", "true", "no",
      "inf", "-inf", "auto", "image", "moffat_catalog", "a path/with spaces.fits", "3, 17 ,42", ""};
  int accepted = 0;
  for (const io::OptionInfo& o : run_config_options()) {
    RunConfig c;
    const std::string first = get_option(c, o.name);
    set_option(c, o.name, first);
    EXPECT_EQ(get_option(c, o.name), first) << o.name;
    for (const std::string& v : candidates) {
      RunConfig d;
      try {
        set_option(d, o.name, v);
      } catch (const ConfigError&) {
        continue;  // not a value of this key's type
      }
      ++accepted;
      const std::string text = get_option(d, o.name);
      RunConfig e;
      set_option(e, o.name, text);
      EXPECT_EQ(get_option(e, o.name), text) << o.name << " = '" << v << "'";
    }
  }
  EXPECT_GT(accepted, 200);
}

TEST(RunConfigRoundTrip, DoublesKeepEveryBit) {
  RunConfig c;
  const double values[] = {0.1 + 0.2, 1e-300, 4.9406564584124654e-324, -0.0, 1.7976931348623157e308, 2.85};
  for (double v : values) {
    c.fitter.noise_sigma = v;
    RunConfig d;
    set_option(d, "noise_sigma", get_option(c, "noise_sigma"));
    EXPECT_TRUE(same_double(d.fitter.noise_sigma, v)) << get_option(c, "noise_sigma");
  }
  EXPECT_EQ(get_option(c, "noise_sigma"), "2.85");  // shortest exact text, not %.17g's 2.8500000000000001
}

TEST(RunConfigSet, ParsesEachKindAndRecordsExplicitKeys) {
  RunConfig c;
  set_option(c, "stamp_size", "+48");
  EXPECT_EQ(c.fitter.render.stamp_size, 48);
  EXPECT_TRUE(c.explicitly_set.contains("stamp_size"));
  EXPECT_FALSE(c.explicitly_set.contains("upsampling"));
  set_option(c, "noise_sigma", "2.5e-1");
  EXPECT_EQ(c.fitter.noise_sigma, 0.25);
  set_option(c, "psf_input", "Moffat_Catalog");
  EXPECT_TRUE(c.psf_from_catalogue);
  EXPECT_EQ(c.psf_kind, PsfKind::kMoffat);
  EXPECT_EQ(get_option(c, "psf_input"), "moffat_catalog");
  set_option(c, "psf_input", "image");
  EXPECT_FALSE(c.psf_from_catalogue);
  EXPECT_EQ(c.psf_kind, PsfKind::kImage);
  EXPECT_EQ(get_option(c, "renderer"), "auto");  // the default
  set_option(c, "renderer", "Upsampled");
  EXPECT_EQ(get_option(c, "renderer"), "upsampled");
  for (const char* t : {"true", "TRUE", "Yes", "1"}) {
    set_option(c, "psf_pixel_integrated", "false");
    set_option(c, "psf_pixel_integrated", t);
    EXPECT_TRUE(c.psf_pixel_integrated) << t;
  }
  for (const char* f : {"false", "False", "NO", "0"}) {
    set_option(c, "psf_pixel_integrated", "true");
    set_option(c, "psf_pixel_integrated", f);
    EXPECT_FALSE(c.psf_pixel_integrated) << f;
  }
  set_option(c, "x0_min", "-inf");
  set_option(c, "x0_max", "inf");
  set_option(c, "e1_start", "auto");
  set_option(c, "radius_start", "2.5");
  EXPECT_EQ(c.fitter.params[Param::kX0].lower, -std::numeric_limits<double>::infinity());
  EXPECT_EQ(c.fitter.params[Param::kX0].upper, std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(c.fitter.params[Param::kE1].start));
  EXPECT_EQ(c.fitter.params[Param::kRadius].start, 2.5);
  set_option(c, "save_images", " 3, 17 ,-42");
  EXPECT_EQ(get_option(c, "save_images"), "3,17,-42");
  EXPECT_EQ(save_image_ids(c), (std::vector<std::int64_t>{3, 17, -42}));
  set_option(c, "save_images", "  ");
  EXPECT_TRUE(save_image_ids(c).empty());
}

TEST(RunConfigSet, RejectsBadValuesAndLeavesTheConfigUnchanged) {
  struct Case {
    const char* key;
    const char* value;
    const char* why;
  };
  const Case cases[] = {
      {"upsampling", "5.5", "expected an integer"},
      {"upsampling", "5x", "expected an integer"},
      {"upsampling", "", "empty value"},
      {"upsampling", "99999999999", "out of range"},
      {"noise_sigma", "1e", "expected a number"},
      {"noise_sigma", "abc", "expected a number"},
      {"noise_sigma", "", "empty value"},
      {"noise_sigma", "inf", "must be finite"},
      {"noise_sigma", "nan", "finite"},
      {"noise_sigma", "auto", "expected a number"},
      {"noise_sigma", "1e999", "out of range"},
      {"e1_start", "inf", "must be finite"},
      {"e1_min", "nan", "'auto'"},
      {"psf_pixel_integrated", "maybe", "expected true/false"},
      {"psf_pixel_integrated", "", "expected true/false"},
      {"psf_input", "gaussian", "expected moffat, airy, moffat_catalog or image"},
      {"renderer", "gpu", "expected auto, exact, upsampled"},
      {"simd", "avx3", "expected best, scalar, sse4.2, avx2 or avx512"},
      {"save_images", "3,,4", "comma-separated"},
      {"save_images", "3,x", "comma-separated"},
  };
  for (const Case& k : cases) {
    RunConfig c;
    const std::string before = get_option(c, k.key);
    const std::string msg = error_of<ConfigError>([&] { set_option(c, k.key, k.value); });
    EXPECT_TRUE(Contains(msg, std::string("option '") + k.key + "' = '" + k.value + "': ")) << msg;
    EXPECT_TRUE(Contains(msg, k.why));
    EXPECT_EQ(get_option(c, k.key), before) << k.key;
    EXPECT_TRUE(c.explicitly_set.empty()) << k.key;
  }
}

TEST(RunConfigSet, UnknownKeysAreRejectedWithASuggestion) {
  RunConfig c;
  EXPECT_EQ(error_of<ConfigError>([&] { set_option(c, "frobnicate", "1"); }), "unknown option 'frobnicate'");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { set_option(c, "upsamplng", "1"); }),
                       "unknown option 'upsamplng' (did you mean 'upsampling'?)"));
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { (void)get_option(c, "nope"); }), "unknown option 'nope'"));
}

TEST(RunConfigSet, ApplySetOverridesAndNamesTheAssignment) {
  RunConfig c;
  apply_set(c, " padding = 6 ");
  EXPECT_EQ(c.fitter.render.padding, 6);
  EXPECT_EQ(c.explicitly_set.at("padding"), "--set");
  apply_set(c, "psf_image=a=b.fits");  // split at the first '='
  EXPECT_EQ(c.psf_image, "a=b.fits");
  EXPECT_EQ(error_of<ConfigError>([&] { apply_set(c, "padding=abc"); }),
            "--set 'padding=abc': option 'padding' = 'abc': expected an integer");
  EXPECT_EQ(error_of<ConfigError>([&] { apply_set(c, "padding"); }), "--set 'padding': expected key=value");
  EXPECT_EQ(error_of<ConfigError>([&] { apply_set(c, "=3"); }), "--set '=3': expected key=value");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { apply_set(c, "nokey=3"); }), "--set 'nokey=3': unknown option 'nokey'"));
}

// --- ini files -----------------------------------------------------------------------------------

TEST_F(RunConfigFile, ParsesCommentsBlankLinesAndSections) {
  const std::string path = write_ini(
      "# a run of the GREAT08 set\n"
      "\n"
      "[render]\n"
      "  upsampling   =  7   # finer\n"
      "padding=2\r\n"
      "\t\n"
      "[ psf ]\n"
      "psf_input = airy\n"
      "airy_lambda_over_d = 1.75\n"
      "psf_image = \n"
      "radius_ratio_start = 1.5\n"
      "e1_free = no\n"
      "bulge_A_min = -inf\n"
      "x0_start = auto\n");
  RunConfig c;
  load_ini(c, path);
  EXPECT_EQ(c.fitter.render.upsampling, 7);
  EXPECT_EQ(c.fitter.render.padding, 2);
  EXPECT_EQ(c.psf_kind, PsfKind::kAiry);
  EXPECT_EQ(c.airy.lambda_over_d, 1.75);
  EXPECT_EQ(c.psf_image, "");
  EXPECT_EQ(c.fitter.params[Param::kRadiusRatio].start, 1.5);
  EXPECT_FALSE(c.fitter.params[Param::kE1].free);
  EXPECT_EQ(c.fitter.params[Param::kBulgeA].lower, -std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(c.fitter.params[Param::kX0].start));
  EXPECT_EQ(c.fitter.render.stamp_size, 39);  // untouched
  EXPECT_EQ(c.explicitly_set.size(), 9u);
  EXPECT_EQ(c.explicitly_set.at("upsampling"), path + ":4");
  EXPECT_EQ(c.explicitly_set.at("padding"), path + ":5");
  EXPECT_FALSE(c.explicitly_set.contains("stamp_size"));  // the command takes it from STAMPSZ
  EXPECT_NO_THROW(validate(c));
}

TEST_F(RunConfigFile, SetOverridesTheFile) {
  RunConfig c;
  load_ini(c, write_ini("upsampling = 7\nbatch_size = 8\n"));
  apply_set(c, "upsampling=9");
  EXPECT_EQ(c.fitter.render.upsampling, 9);
  EXPECT_EQ(c.batch_size, 8);
  EXPECT_EQ(c.explicitly_set.at("upsampling"), "--set");
}

TEST_F(RunConfigFile, ErrorsNameTheFileLineAndKey) {
  std::string msg = load_error("upsampling = 5\n\nfoo = 3\n");
  EXPECT_TRUE(Contains(msg, "run.ini:3: unknown option 'foo'"));

  msg = load_error("# header\npadding = 5.5\n");
  EXPECT_TRUE(Contains(msg, "run.ini:2: option 'padding' = '5.5': expected an integer"));

  msg = load_error("padding = 5x\n");
  EXPECT_TRUE(Contains(msg, "run.ini:1: option 'padding' = '5x'"));

  msg = load_error("padding =\n");
  EXPECT_TRUE(Contains(msg, "run.ini:1: option 'padding' = '': empty value"));

  msg = load_error("\n\nnoise_sigma = 1e\n");
  EXPECT_TRUE(Contains(msg, "run.ini:3: option 'noise_sigma' = '1e': expected a number"));

  msg = load_error("levmar_eps4 = abc # comment\n");
  EXPECT_TRUE(Contains(msg, "run.ini:1: option 'levmar_eps4' = 'abc'"));

  msg = load_error("[model]\nx0_free = maybe\n");
  EXPECT_TRUE(Contains(msg, "run.ini:2: option 'x0_free' = 'maybe': expected true/false"));

  msg = load_error("padding = 3\nupsampling 5\n");
  EXPECT_TRUE(Contains(msg, "run.ini:2: expected 'key = value'"));
  msg = load_error("= 5\n");
  EXPECT_TRUE(Contains(msg, "run.ini:1: expected 'key = value'"));
  msg = load_error("[unclosed\n");
  EXPECT_TRUE(Contains(msg, "run.ini:1: expected 'key = value'"));

  msg = load_error("padding = 3\n\npadding = 4\n");
  EXPECT_TRUE(Contains(msg, "run.ini:3: option 'padding' is set twice (first on line 1)"));
}

TEST_F(RunConfigFile, UnreadableFilesAreConfigErrors) {
  RunConfig c;
  const std::string missing = scratch_.path("x.ini");
  EXPECT_EQ(error_of<ConfigError>([&] { load_ini(c, missing); }), "cannot read config file '" + missing + "'");
  EXPECT_EQ(error_of<ConfigError>([&] { load_ini(c, scratch_.dir().string()); }), "cannot read config file '" + scratch_.dir().string() + "'");
}

TEST_F(RunConfigFile, OutOfRangeValuesFailValidationNamingKeyAndLine) {
  RunConfig c;
  load_ini(c, write_ini("padding = 4\nupsampling = 0\n"));  // parses: the range is validate()'s job
  const std::string msg = error_of<ConfigError>([&] { validate(c); });
  EXPECT_TRUE(Contains(msg, "upsampling = 0"));
  EXPECT_TRUE(Contains(msg, "run.ini:2: upsampling = 0"));

  RunConfig d;
  set_option(d, "upsampling", "0");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(d); }), "upsampling = 0: must be"));
}

// --- validation ----------------------------------------------------------------------------------

TEST(RunConfigValidate, FixedOnlyParameterCannotBeFree) {
  RunConfig c;
  set_option(c, "radius_ratio_free", "true");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "parameter 'radius_ratio' cannot be free"));
}

// Found by the Python argument fuzzer: Options.from_ini('/dev/zero') (and --config /dev/zero) took
// 29 s and gigabytes before failing, getline growing one line without end.
TEST(RunConfigIni, AFileWithoutLineEndsIsAnErrorNotAHang) {
  RunConfig c;
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { load_ini(c, "/dev/zero"); }),
                       "/dev/zero:1: a line longer than 16777216 bytes: not a configuration file"));
}

TEST(RunConfigValidate, APsfImageWithAnotherPsfInputIsRefused) {
  // The image was silently unused: a PSF given two ways is an error naming both.
  for (const char* kind : {"airy", "moffat"}) {
    RunConfig c;
    set_option(c, "psf_input", kind);
    set_option(c, "psf_image", "psf.fits");
    EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }),
                         std::string("psf_image = 'psf.fits' with psf_input = ") + kind + ": the image would not be used"));
  }
}

TEST(RunConfigValidate, ImagePsfNeedsAnImage) {
  RunConfig c;
  set_option(c, "psf_input", "image");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "psf_input = image needs psf_image"));
  set_option(c, "psf_image", "psf.fits");
  EXPECT_NO_THROW(validate(c));
  set_option(c, "psf_upsampling", "0");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "psf_upsampling = 0: must be >= 1"));
}

TEST(RunConfigValidate, RunAndPsfOptions) {
  const auto error_with = [](const char* key, const char* value) {
    RunConfig c;
    set_option(c, key, value);
    return error_of<ConfigError>([&] { validate(c); });
  };
  EXPECT_TRUE(Contains(error_with("batch_size", "0"), "batch_size = 0: must be in [1, 100000]"));
  EXPECT_TRUE(Contains(error_with("batch_size", "100001"), "batch_size = 100001"));
  EXPECT_TRUE(Contains(error_with("psf_beta", "1"), "psf_beta = 1"));
  EXPECT_TRUE(Contains(error_with("levmar_eps2", "1"), "levmar_eps2 = 1"));
  EXPECT_TRUE(Contains(error_with("noise_sigma", "-1"), "noise_sigma = -1"));
  EXPECT_TRUE(Contains(error_with("ellipticity_mirror", "1"), "ellipticity_mirror = 1"));
  EXPECT_TRUE(Contains(error_with("catalog_x_column", ""), "catalog_x_column = '': must name a catalogue column"));
  EXPECT_TRUE(Contains(error_with("e1_min", "auto"), "e1_min = auto: only x0 and y0 have automatic bounds"));
  EXPECT_TRUE(Contains(error_with("disc_A_max", "auto"), "disc_A_max = auto"));
  EXPECT_TRUE(Contains(error_with("e1_start", "5"), "parameter 'e1' start 5 is outside its bounds"));

  // Only the selected PSF's options are checked, except that moffat_catalog keeps the Moffat's.
  RunConfig c;
  set_option(c, "psf_beta", "0.5");
  set_option(c, "psf_input", "airy");
  EXPECT_NO_THROW(validate(c));
  set_option(c, "airy_obscuration", "1");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "airy_obscuration = 1"));
  set_option(c, "psf_input", "moffat_catalog");
  EXPECT_TRUE(Contains(error_of<ConfigError>([&] { validate(c); }), "psf_beta = 0.5"));

  RunConfig centroid;
  set_option(centroid, "x0_min", "auto");  // the default: the stamp's edge
  EXPECT_NO_THROW(validate(centroid));
}

// --- output --------------------------------------------------------------------------------------

TEST(RunConfigOutput, EffectiveOptionsListEveryKeyOnceInRegistryOrder) {
  RunConfig c;
  set_option(c, "padding", "6");
  set_option(c, "psf_input", "image");
  const auto effective = effective_options(c);
  const auto& options = run_config_options();
  ASSERT_EQ(effective.size(), options.size());
  std::set<std::string> seen;
  for (std::size_t i = 0; i < effective.size(); ++i) {
    EXPECT_EQ(effective[i].first, options[i].name);
    EXPECT_TRUE(seen.insert(effective[i].first).second) << effective[i].first;
    EXPECT_EQ(effective[i].second, get_option(c, effective[i].first));
  }
  EXPECT_EQ(get_option(c, "padding"), "6");
  EXPECT_EQ(get_option(c, "psf_input"), "image");
}

TEST_F(RunConfigFile, TemplateDocumentsEveryKeyAndLoadsAsTheDefaults) {
  const std::string text = ini_template();
  for (const io::OptionInfo& o : run_config_options()) {
    const std::string line = "#" + o.name + (o.default_value.empty() ? " =" : " = " + o.default_value);
    EXPECT_TRUE(Contains(text, "\n# " + o.help + "\n" + line + "\n"));
  }
  const RunConfig kDefaults;  // named: GCC 12 warns falsely (maybe-uninitialized) on a temporary's strings
  RunConfig c;
  load_ini(c, write_ini(text, "template.ini"));
  EXPECT_TRUE(c.explicitly_set.empty());  // every assignment is commented out
  EXPECT_EQ(effective_options(c), effective_options(kDefaults));

  // Uncommented, it sets every key to its default: the template is also a valid full config.
  std::string uncommented;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);)
    uncommented += (line.size() > 1 && line[0] == '#' && line[1] != ' ' ? line.substr(1) : line) + "\n";
  RunConfig d;
  load_ini(d, write_ini(uncommented, "full.ini"));
  EXPECT_EQ(d.explicitly_set.size(), run_config_options().size());
  EXPECT_EQ(effective_options(d), effective_options(kDefaults));
  EXPECT_NO_THROW(validate(d));
}

}  // namespace
}  // namespace stampede::app
