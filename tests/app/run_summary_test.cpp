// RunSummary: the brief line `stampede fit` prints, the full report, and a status array that
// covers every FitStatus.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "app/run_summary.hpp"

namespace {

using stampede::FitStatus;
using stampede::app::RunSummary;

RunSummary example() {
  RunSummary s;
  s.objects = 390;
  s.resumed = 10;
  s.batches = 13;
  s.threads = 2;
  s.by_status[static_cast<int>(FitStatus::kOk)] = 385;
  s.by_status[static_cast<int>(FitStatus::kMaxIterations)] = 4;
  s.by_status[static_cast<int>(FitStatus::kPsfFailure)] = 1;
  s.setup_seconds = 0.25;
  s.pipeline_seconds = 13;
  s.finish_seconds = 0.125;
  s.total_seconds = 13.5;
  s.input = "in.fits";
  s.output = "out.fits";
  return s;
}

TEST(RunSummary, StatusArrayCoversTheEnum) {
  std::set<std::string> names;
  for (int s = 0; s < stampede::kFitStatusCount; ++s) names.insert(stampede::ToString(static_cast<FitStatus>(s)));
  EXPECT_EQ(names.size(), static_cast<std::size_t>(stampede::kFitStatusCount));
  EXPECT_EQ(names.count("?"), 0u);  // every index is a status...
  EXPECT_STREQ(stampede::ToString(static_cast<FitStatus>(stampede::kFitStatusCount)), "?");  // ...and no more
}

TEST(RunSummary, BriefReportIsTheLineOfStampedeFit) {
  RunSummary s = example();
  EXPECT_EQ(s.count(FitStatus::kMaxIterations), 4);
  EXPECT_DOUBLE_EQ(s.objects_per_second(), 30.0);
  EXPECT_EQ(s.BriefReport(),
            "stampede fit: 400 objects (10 resumed) in 13.0 s, 30.0 objects/s; status: ok=385 max_iterations=4 "
            "psf_failure=1; wrote out.fits");
  s.output.clear();
  EXPECT_EQ(s.BriefReport(),
            "stampede fit: 400 objects (10 resumed) in 13.0 s, 30.0 objects/s; status: ok=385 max_iterations=4 "
            "psf_failure=1");
  EXPECT_EQ(RunSummary().BriefReport(), "stampede fit: 0 objects (0 resumed) in 0.0 s, 0.0 objects/s; status:");
}

TEST(RunSummary, FullReportHasEveryStatusPhaseAndPath) {
  const std::string r = example().FullReport();
  for (int s = 0; s < stampede::kFitStatusCount; ++s)
    EXPECT_NE(r.find(stampede::ToString(static_cast<FitStatus>(s))), std::string::npos) << r;
  for (const char* part : {"in.fits", "out.fits", "setup", "pipeline", "finish", "total", "30.0 objects/s",
                           "400 (390 fitted by this run, 10 resumed) in 13 batches", "threads        2"})
    EXPECT_NE(r.find(part), std::string::npos) << part << "\n" << r;
  EXPECT_NE(r.find("    ok                        385\n"), std::string::npos) << r;
  EXPECT_NE(r.find("    no_data                     0\n"), std::string::npos) << r;
  EXPECT_EQ(r.back(), '\n');
}

}  // namespace
