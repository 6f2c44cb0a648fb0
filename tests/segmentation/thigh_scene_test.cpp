// The whole thigh scene of the bundled phantom (femur + three muscle compartments): collision response between the
// declared pairs is what keeps the objects from overlapping, and it does not cost accuracy. The scenario is shared
// with bench/phantom_bench.cpp, which reports its figures (BM_ThighScene).
#include <gtest/gtest.h>

#include "msk/test/phantom_scenarios.h"

namespace {

msk::test::ThighRun segment(const msk::test::BundledThigh& thigh, bool collisions, bool remeshMuscles = true,
                            bool unfold = true) {
  msk::SegmentOptions opts;
  opts.collision.enabled = collisions;
  opts.surface.remeshTemplates = remeshMuscles;
  opts.surface.unfoldSurfaces = unfold;
  return msk::test::segmentThigh(thigh, thigh.scene, opts);
}

}  // namespace

TEST(ThighScene, CollisionResponseRemovesTheOverlapWithoutCostingAccuracy) {
  const msk::test::BundledThigh thigh = msk::test::loadBundledThigh();
  const msk::test::ThighRun without = segment(thigh, false), with = segment(thigh, true);
  EXPECT_EQ(without.res.collisionSetsBuilt, 0);                              // nothing built when not asked for
  EXPECT_EQ(with.res.collisionSetsBuilt, 2 * 6 * with.res.settings.levels);  // both directions of 6 pairs per level
  // Without collision response the muscles overlap by thousands of voxels; with it, not at all, and no vertex of an
  // output surface is more than 0.1 mm inside a partner.
  EXPECT_GT(without.res.overlapVoxels, 2000u);
  EXPECT_EQ(with.res.overlapVoxels, 0u);
  ASSERT_EQ(with.res.pairPenetrationMm.size(), 6u);
  for (double depth : with.res.pairPenetrationMm) EXPECT_LE(depth, 0.1);
  EXPECT_TRUE(without.res.pairPenetrationMm.empty());
  for (int i = 0; i < 4; ++i) {
    EXPECT_GE(with.dice[i], 0.95) << "object " << i + 1;
    // The response may cost a muscle a little Dice where it now shares a boundary (at most 0.006).
    EXPECT_GE(with.dice[i], without.dice[i] - 0.006) << "object " << i + 1;
    EXPECT_LE(with.assd[i], 0.8) << "object " << i + 1;
  }
  // No output surface crosses itself (the muscles' templates are remeshed, see the next test; what folds are left is
  // unfolded).
  for (const msk::test::ThighRun* r : {&without, &with})
    for (const msk::ObjectResult& o : r->res.objects)
      EXPECT_EQ(o.selfIntersections, 0u) << (r == &with ? "with collisions, " : "without, ") << o.name;
  // Both runs pass the quality check.
  for (const msk::test::ThighRun* r : {&without, &with})
    for (const msk::ObjectResult& o : r->res.objects)
      EXPECT_EQ(o.quality.status, msk::QualityStatus::Ok)
          << (r == &with ? "with collisions, " : "without, ") << o.name << ": "
          << (o.quality.reasons.empty() ? "" : o.quality.reasons[0]);
}

// Without the isotropic remeshing of the muscles' templates (decimated: triangles with edges from 0.2 to 28 mm), the
// image forces fold their 2-simplex duals and the output surfaces cross themselves in hundreds of places (measured
// 256 / 369 / 342 face pairs, without the unfolding; the femur, whose template is kept either way, none); remeshed,
// none, for the same accuracy (the test above). SurfaceOptions::remeshTemplates, docs/method.md (Surface quality).
TEST(ThighScene, MusclesKeptOnTheirDecimatedTemplatesFoldOntoThemselves) {
  const msk::test::ThighRun kept = segment(msk::test::loadBundledThigh(), true, false, false);
  for (const msk::ObjectResult& o : kept.res.objects) {
    EXPECT_FALSE(o.remeshed) << o.name;
    if (o.name == "femur")
      EXPECT_EQ(o.selfIntersections, 0u);
    else
      EXPECT_GT(o.selfIntersections, 50u) << o.name;
  }
}
