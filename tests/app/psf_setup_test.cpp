// renderer = auto (the default) resolved by the run's PSF: exact wherever the exact renderer takes
// it, upsampled, with a note saying why, where it refuses; an explicit kind is kept as it is.
#include <gtest/gtest.h>

#include "app/psf_setup.hpp"
#include "engine/render/exact_psf.hpp"
#include "app/run_config.hpp"
#include "io/config_error.hpp"
#include "support/error_assertions.hpp"

#include <cmath>
#include <memory>

namespace stampede::app {
namespace {

TEST(PsfSetup, AutoIsExactForAMoffatAndUpsampledForAnAiryDisc) {
  FftPlanCache plans(FftPlanning::kEstimate);
  app::RunConfig cfg;
  EXPECT_EQ(cfg.fitter.renderer, RendererKind::kAuto);
  const SharedPsf moffat = build_shared_psf(cfg, plans);
  EXPECT_EQ(moffat.kind, RendererKind::kExact);
  EXPECT_TRUE(moffat.auto_note.empty());
  EXPECT_NE(dynamic_cast<const ExactPsf*>(moffat.prepared.get()), nullptr);

  app::set_option(cfg, "psf_input", "airy");
  const SharedPsf airy = build_shared_psf(cfg, plans);
  EXPECT_EQ(airy.kind, RendererKind::kUpsampled);
  ASSERT_TRUE(airy.prepared);
  EXPECT_EQ(dynamic_cast<const ExactPsf*>(airy.prepared.get()), nullptr);
  EXPECT_NE(airy.auto_note.find("renderer = auto: the upsampled renderer"), std::string::npos) << airy.auto_note;
  EXPECT_NE(airy.auto_note.find("exact_period"), std::string::npos) << airy.auto_note;

  // Asked for by name, exact refuses the Airy disc as before.
  app::set_option(cfg, "renderer", "exact");
  EXPECT_THROW(build_shared_psf(cfg, plans), std::runtime_error);
  app::set_option(cfg, "renderer", "upsampled");
  app::set_option(cfg, "psf_input", "moffat");
  EXPECT_EQ(build_shared_psf(cfg, plans).kind, RendererKind::kUpsampled);
}

// A PSF image metacal cannot normalise (a NaN pixel) was reported as "metacal_psf_dilation = 0:
// ...", an option the run had not set: the run's PSF is named instead; the option is named where
// the run sets it.
TEST(PsfSetup, AReconvolutionFailureNamesWhatTheRunSet) {
  auto image = std::make_shared<PsfImage>();
  image->nx = image->ny = 9;
  image->pixels.assign(81, 1.0);
  image->pixels[10] = NAN;
  const PsfModel psf = PsfModel::Image(image);
  app::RunConfig cfg;
  app::set_option(cfg, "metacal", "true");
  app::set_option(cfg, "psf_input", "image");
  app::set_option(cfg, "psf_image", "nan_psf.fits");
  const std::string message = testing::error_of<io::ConfigError>([&] { checked_reconvolution_psf(psf, cfg); });
  EXPECT_TRUE(testing::Contains(message, "metacal = true cannot use the run's PSF (psf_input = image, psf_image = "
                                         "'nan_psf.fits'): ")) << message;
  EXPECT_FALSE(testing::Contains(message, "metacal_psf_dilation")) << message;
  app::set_option(cfg, "metacal_psf_dilation", "1.5");
  EXPECT_TRUE(testing::Contains(testing::error_of<io::ConfigError>([&] { checked_reconvolution_psf(psf, cfg); }),
                                "metacal_psf_dilation = 1.5: "));
}

}  // namespace
}  // namespace stampede::app
