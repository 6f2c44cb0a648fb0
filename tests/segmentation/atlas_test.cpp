// The atlas route (msk/test/atlas_scenarios.h): an atlas from one subject placed by registration in another and
// segmented loses nothing against templates already in place. Phantom: another seed in another pose. Real scans: the
// scan mirrored (one side standing for the other) onto the scan moved by 15° and 40 mm. bench/atlas_bench prints the
// figures.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "msk/test/atlas_scenarios.h"
#include "msk/test/files.h"

namespace {

using msk::test::AtlasObjectScore;
using msk::test::AtlasRun;

/// The deepest vertex of either surface of a pair inside the other, mm, over the run's pairs.
double deepestMm(const AtlasRun& run) {
  double d = 0;
  for (double p : run.result.pairPenetrationMm) d = std::max(d, p);
  return d;
}

}  // namespace

TEST(AtlasRoute, PhantomSubjectInAnotherPoseAndSizeLosesNothing) {
  msk::PhantomPose pose;
  pose.rotationDegrees = Eigen::Vector3d(10, -6, 9);  // 14.7° in all
  pose.translationMm = Eigen::Vector3d(20, -25, 15);  // 35.4 mm
  pose.scale = 1.08;
  msk::test::ScratchDir dir;
  const AtlasRun run = msk::test::runAtlasCase(msk::test::phantomAtlasCase(1, 2, pose), dir.path());
  ASSERT_EQ(run.objects.size(), 4u);
  for (const AtlasObjectScore& o : run.objects) {
    EXPECT_GE(o.result.dice, 0.92) << o.name;
    EXPECT_GT(o.result.dice, o.placed.dice) << o.name;
  }
  EXPECT_LE(run.meanAssd, 0.8);
  EXPECT_EQ(run.result.overlapVoxels, 0u);
  EXPECT_LE(deepestMm(run), 0.1);
  // The global registration found the pose: it improved the match well beyond the start.
  ASSERT_TRUE(run.placement.registration.has_value());
  EXPECT_GT(run.placement.registration->metric, 0.9);
  EXPECT_GT(run.placement.registration->metric, run.placement.registration->startMetric + 0.1);
}

TEST(AtlasRoute, MirroredCtOntoTheCtMovedInWorldSpace) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  msk::test::ScratchDir dir;
  const AtlasRun run = msk::test::runAtlasCase(msk::test::ctAtlasCase(data, 15, 40), dir.path());
  ASSERT_EQ(run.objects.size(), 4u);
  // The templates-in-place scene of the same scan (RealScenes.CtFemurHipAndGlutealMusclesOfOneSide) asserts
  // 0.90 / 0.93 / 0.88 / 0.85.
  const double floor[] = {0.90, 0.93, 0.85, 0.85};
  for (size_t i = 0; i < run.objects.size(); ++i)
    EXPECT_GE(run.objects[i].result.dice, floor[i]) << run.objects[i].name;
  EXPECT_EQ(run.result.overlapVoxels, 0u);
}

TEST(AtlasRoute, MirroredMrOntoTheMrMovedInWorldSpace) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  msk::test::ScratchDir dir;
  const AtlasRun run = msk::test::runAtlasCase(msk::test::mrAtlasCase(data, 15, 40), dir.path());
  ASSERT_EQ(run.objects.size(), 3u);
  EXPECT_GE(run.objects[0].result.dice, 0.87) << run.objects[0].name;
  EXPECT_GE(run.objects[1].result.dice, 0.87) << run.objects[1].name;
  EXPECT_EQ(run.result.overlapVoxels, 0u);
}
