// The whole thigh scene of the bundled phantom (femur + three muscle compartments): collision response between the
// declared pairs is what keeps the objects from overlapping, and it does not cost accuracy. The scenario is shared
// with bench/phantom_bench.cpp, which reports its figures (BM_ThighScene).
#include <gtest/gtest.h>

#include "msk/phantom/phantom.h"
#include "msk/segmentation/surface_quality.h"
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

/// The bundled thigh scene with the muscles' templates decimated (the bundled ones are remeshed, as the phantom writes
/// them): the phantom's mean-anatomy templates without the remeshing.
msk::test::BundledThigh withDecimatedMuscleTemplates() {
  msk::test::BundledThigh thigh = msk::test::loadBundledThigh();
  msk::PhantomOptions po;
  po.seed = 1;
  po.remeshMuscleTemplates = false;
  const msk::Phantom ph = msk::makePhantom(po);
  for (msk::SceneObject& o : thigh.scene.objects)
    for (const msk::PhantomObject& p : ph.objects)
      if (p.name == o.name && o.kind != msk::ObjectKind::Bone) o.templ = p.templ;
  return thigh;
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
  // The collision-only sweeps after the last step stop once a sweep's corrections are only rounding (moving nothing by
  // a picometre), well before the cap of 10; earlier levels and the run without collisions have none.
  for (const msk::ObjectResult& o : with.res.objects) {
    EXPECT_GE(o.levels.back().cleanUpSweeps, 1) << o.name;
    EXPECT_LT(o.levels.back().cleanUpSweeps, 10) << o.name;
    EXPECT_EQ(o.levels.front().cleanUpSweeps, 0) << o.name;
  }
  for (const msk::ObjectResult& o : without.res.objects) EXPECT_EQ(o.levels.back().cleanUpSweeps, 0) << o.name;
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
  const msk::test::BundledThigh thigh = withDecimatedMuscleTemplates();
  for (const msk::SceneObject& o : thigh.scene.objects) EXPECT_FALSE(msk::isotropicTriangulation(o.templ)) << o.name;
  const msk::test::ThighRun kept = segment(thigh, true, false, false);
  for (const msk::ObjectResult& o : kept.res.objects) {
    EXPECT_FALSE(o.remeshed) << o.name;
    if (o.name == "femur")
      EXPECT_EQ(o.selfIntersections, 0u);
    else
      EXPECT_GT(o.selfIntersections, 50u) << o.name;
  }
}

// A muscle template remeshed beforehand (as the phantom writes them, or `mskseg convert --remesh`) is used as it is:
// the same triangulation, and outputs bitwise the same, as when segment remeshes the decimated template itself.
TEST(ThighScene, MuscleTemplatesRemeshedBeforehandAreUsedAsTheyAre) {
  const msk::test::BundledThigh decimated = withDecimatedMuscleTemplates();
  msk::test::BundledThigh remeshed = decimated;
  for (msk::SceneObject& o : remeshed.scene.objects)
    if (o.kind != msk::ObjectKind::Bone) o.templ = msk::remeshIsotropic(o.templ, o.templ.vertexCount());
  const msk::test::ThighRun a = segment(decimated, true), b = segment(remeshed, true);
  ASSERT_EQ(a.res.objects.size(), b.res.objects.size());
  for (size_t i = 0; i < a.res.objects.size(); ++i) {
    const msk::ObjectResult &x = a.res.objects[i], &y = b.res.objects[i];
    EXPECT_EQ(x.remeshed, x.name != "femur") << x.name;
    EXPECT_FALSE(y.remeshed) << y.name;
    EXPECT_EQ(x.polarity, y.polarity) << x.name;
    ASSERT_EQ(x.mesh.faces, y.mesh.faces) << x.name;
    EXPECT_EQ(x.mesh.vertices, y.mesh.vertices) << x.name;
  }
  EXPECT_TRUE(a.res.labels.data == b.res.labels.data);
  // The bundled scene's muscle templates are the remeshed kind.
  for (const msk::SceneObject& o : msk::test::loadBundledThigh().scene.objects)
    EXPECT_EQ(msk::isotropicTriangulation(o.templ), o.kind != msk::ObjectKind::Bone) << o.name;
}
