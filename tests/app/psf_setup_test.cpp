// renderer = auto (the default) resolved by the run's PSF: exact wherever the exact renderer takes
// it, upsampled, with a note saying why, where it refuses; an explicit kind is kept as it is.
#include <gtest/gtest.h>

#include "app/psf_setup.hpp"
#include "engine/render/exact_psf.hpp"
#include "app/run_config.hpp"

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

}  // namespace
}  // namespace stampede::app
