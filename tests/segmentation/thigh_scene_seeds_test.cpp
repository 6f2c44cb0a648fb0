// Issue 4's acceptance check for multi-object scenes: the whole thigh scene (femur + quadriceps, hamstrings,
// adductors, with the phantom's touching pairs as collision pairs) on five more phantom seeds, oblique and anisotropic
// grids included. The issue asks for a mean surface distance over objects ≤ 0.8 mm, every Dice ≥ 0.92, no voxel
// inside two output surfaces and no vertex more than 0.1 mm inside a partner; each is printed per seed with whether it
// is met. All four are asserted on every seed (zero overlap since the voxel centres the separation's samples miss
// are handed to one surface, segmentation/overlap_repair.h; seed 3 had 2 such voxels before). The boundary error where the fat septum between two muscles is missing (the image cannot separate them there) is
// reported apart.
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "msk/core/collision_surface.h"
#include "msk/segmentation/metrics.h"
#include "msk/phantom/phantom.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace {

struct Case {
  uint32_t seed;
  Eigen::Vector3d spacing, oblique;
};


/// Tissue class at the voxel nearest to a world point (Air outside the grid).
int tissueAt(const msk::Phantom& p, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = p.tissues.grid.toVoxel(x);
  const int i = static_cast<int>(std::lround(v.x())), j = static_cast<int>(std::lround(v.y())),
            k = static_cast<int>(std::lround(v.z()));
  return p.tissues.grid.contains(i, j, k) ? p.tissues.at(i, j, k) : 0;
}

/// Mean distance from the truth surface's vertices to the result surface, split by whether the truth vertex lies
/// where the septum is missing: 1.5 mm outside it along its normal there is muscle of a neighbour, not fat.
void septaErrors(const msk::Phantom& p, const msk::TriangleMesh& truth, const msk::TriangleMesh& result,
                 double& missingMm, int& missingCount, double& otherMm, int& otherCount) {
  msk::CollisionSurface surface(result.faces, 20.0);
  surface.update(result.vertices);
  const msk::Points normals = msk::vertexNormals(truth);
  for (int v = 0; v < truth.vertexCount(); ++v) {
    const Eigen::Vector3d x = truth.vertices.row(v).transpose(), n = normals.row(v).transpose();
    const int out = tissueAt(p, x + 1.5 * n);
    const bool missing = out == static_cast<int>(msk::PhantomTissue::Muscle) ||
                         out == static_cast<int>(msk::PhantomTissue::IntramuscularFat);
    const msk::SurfacePoint s = surface.closest(result.vertices, x, 20.0);
    const double d = s.triangle < 0 ? 20.0 : s.distance;
    (missing ? missingMm : otherMm) += d;
    ++(missing ? missingCount : otherCount);
  }
}

}  // namespace

TEST(ThighSceneSeeds, FiveMoreSeedsIncludingObliqueAndAnisotropicGrids) {
  const Case cases[] = {{2, {1.2, 1.2, 3}, {0, 0, 0}},
                        {3, {1.2, 1.2, 3}, {10, -15, 20}},
                        {4, {1, 1.5, 2.5}, {0, 0, 0}},
                        {5, {0.9, 0.9, 4}, {-20, 10, 5}},
                        {6, {1.5, 1.5, 1.5}, {0, 0, 30}}};
  std::printf("%-34s %-12s %7s %9s %9s %9s   %s\n", "phantom", "object", "Dice", "ASSD mm", "template", "septa-", "");
  for (const Case& c : cases) {
    msk::PhantomOptions o;
    o.seed = c.seed;
    o.spacing = c.spacing;
    o.obliqueDegrees = c.oblique;
    const msk::Phantom p = msk::makePhantom(o);
    const msk::Scene scene = msk::phantomScene(p);
    ASSERT_EQ(scene.objects.size(), 4u);
    ASSERT_GE(scene.collisions.size(), 5u);
    const msk::SegmentationResult res = msk::segmentScene(p.image, scene, msk::SegmentOptions{});
    char what[96];
    std::snprintf(what, sizeof what, "seed %u (%gx%gx%g, oblique %g,%g,%g)", c.seed, c.spacing[0], c.spacing[1],
                  c.spacing[2], c.oblique[0], c.oblique[1], c.oblique[2]);
    double assdSum = 0, missingMm = 0, otherMm = 0;
    int missingCount = 0, otherCount = 0;
    for (size_t i = 0; i < scene.objects.size(); ++i) {
      const int label = scene.objects[i].label;
      const msk::SegmentationMetrics vox = msk::labelMetrics(res.labels, label, p.labels, label);
      const msk::SegmentationMetrics mesh = msk::meshMetrics(res.objects[i].mesh, p.objects[i].truth);
      const msk::SegmentationMetrics start = msk::meshMetrics(scene.objects[i].templ, p.objects[i].truth);
      if (scene.objects[i].kind == msk::ObjectKind::Muscle)
        septaErrors(p, p.objects[i].truth, res.objects[i].mesh, missingMm, missingCount, otherMm, otherCount);
      std::printf("%-34s %-12s %7.3f %9.3f %9.2f\n", i == 0 ? what : "", scene.objects[i].name.c_str(), vox.dice,
                  mesh.assd, start.assd);
      assdSum += mesh.assd;
      EXPECT_GE(vox.dice, 0.92) << what << " " << scene.objects[i].name;
    }
    const double meanAssd = assdSum / static_cast<double>(scene.objects.size());
    double deepest = 0;
    for (double d : res.pairPenetrationMm) deepest = std::max(deepest, d);
    std::printf("%-34s mean ASSD %.3f mm, overlap %zu voxels (%ld handed over after the separation), deepest "
                "penetration %.3f mm, %.1f s\n",
                "", meanAssd, res.overlapVoxels, res.overlapVoxelsRepaired, deepest, res.seconds);
    std::printf("%-34s muscle boundary error where septa are missing %.3f mm (%d truth vertices), elsewhere %.3f mm "
                "(%d)\n",
                "", missingCount ? missingMm / missingCount : 0.0, missingCount, otherCount ? otherMm / otherCount : 0.0,
                otherCount);
    std::printf("%-34s issue 4: mean ASSD <= 0.8 %s, zero overlap %s, penetration <= 0.1 mm %s\n", "",
                meanAssd <= 0.8 ? "met" : "NOT met", res.overlapVoxels == 0 ? "met" : "NOT met",
                deepest <= 0.1 ? "met" : "NOT met");
    EXPECT_LE(meanAssd, 0.8) << what;
    EXPECT_EQ(res.overlapVoxels, 0u) << what;
    EXPECT_LE(deepest, 0.1) << what;
    EXPECT_GT(missingCount, 0) << what << ": the phantom should have muscle boundaries without a septum";
  }
}
