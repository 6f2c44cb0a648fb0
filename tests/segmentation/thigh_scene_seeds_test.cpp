// The acceptance check for multi-object scenes: the whole thigh scene (femur + quadriceps, hamstrings, adductors, with
// the phantom's touching pairs as collision pairs) on five more phantom seeds, oblique and anisotropic grids included:
// a mean surface distance over objects ≤ 0.8 mm, every Dice ≥ 0.92, no voxel inside two output surfaces (the voxel
// centres the separation's samples miss are handed to one surface, segmentation/overlap_repair.h) and no vertex more
// than 0.1 mm inside a partner, on every seed. The boundary error where the fat septum between two muscles is missing
// (the image cannot separate them there) is measured apart. The scenario is shared with bench/phantom_bench.cpp, which
// reports the figures (BM_ThighSceneSeeds). Every object passes the quality check (quality_check.h).
#include <gtest/gtest.h>

#include <string>

#include "msk/test/phantom_scenarios.h"

namespace {
// One test per seed (ThighSceneSeeds/FiveMoreSeeds.*/seed<k>).
class FiveMoreSeeds : public ::testing::TestWithParam<msk::test::PhantomCase> {};
}  // namespace

TEST_P(FiveMoreSeeds, IncludingObliqueAndAnisotropicGrids) {
  const msk::test::PhantomCase& c = GetParam();
  const std::string what = c.name();
  const msk::test::ThighSceneScore sc = msk::test::segmentPhantomThigh(c, msk::test::TemplateScores::Skip);
  ASSERT_EQ(sc.objectsInScene, 4u) << what;
  ASSERT_GE(sc.collisionPairs, 5u) << what;
  for (const msk::test::ThighObjectScore& o : sc.objects) {
    EXPECT_GE(o.dice, 0.92) << what << " " << o.name;
    EXPECT_EQ(o.quality.status, msk::QualityStatus::Ok)
        << what << " " << o.name << ": " << (o.quality.reasons.empty() ? "" : o.quality.reasons[0]);
  }
  EXPECT_LE(sc.meanAssd, 0.8) << what;
  EXPECT_EQ(sc.overlapVoxels, 0u) << what;
  EXPECT_LE(sc.deepestMm, 0.1) << what;
  EXPECT_GT(sc.septaMissingVertices, 0) << what << ": the phantom should have muscle boundaries without a septum";
}

INSTANTIATE_TEST_SUITE_P(ThighSceneSeeds, FiveMoreSeeds, ::testing::ValuesIn(msk::test::otherPhantomCases()),
                         [](const ::testing::TestParamInfo<msk::test::PhantomCase>& info) {
                           return "seed" + std::to_string(info.param.seed);
                         });
