// Stability of the segmentation pipeline at the extremes (issue 5): very anisotropic voxels, a constant image, a pure
// noise image, a NaN voxel and an image in metre units. Small grids, one or two levels and a coarse template keep
// every case fast.
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "msk/core/error.h"
#include "msk/imaging/grid.h"
#include "msk/segmentation/segmenter.h"
#include "msk/test/volumes.h"

namespace {

/// A grid of spacing `spacing` (mm) covering ±halfWidth (mm) about the origin along each axis (at least 2 voxels).
msk::Grid boxGrid(const Eigen::Vector3d& spacing, const Eigen::Vector3d& halfWidth) {
  msk::Grid g;
  for (int a = 0; a < 3; ++a) g.dims[a] = std::max(2, static_cast<int>(std::ceil(2 * halfWidth[a] / spacing[a])));
  g.spacing = spacing;
  g.origin = -spacing.cwiseProduct((g.dims.cast<double>().array() - 1.0).matrix() / 2.0);
  return g;
}

msk::Scene oneObject(const msk::TriangleMesh& templ) {
  msk::Scene s;
  msk::SceneObject o;
  o.name = "ball";
  o.label = 1;
  o.templ = templ;
  o.hasPolarity = true;  // fixed, so the polarity estimate (fixed sampling distances in mm) plays no part
  o.polarity = msk::Polarity::DarkInside;
  s.objects.push_back(o);
  return s;
}

/// Small, fast settings: `levels` levels, at most `steps` steps each.
msk::SegmentOptions quick(int levels, int steps) {
  msk::SegmentOptions o;
  o.evolution.levels = levels;
  o.evolution.maxStepsPerLevel = steps;
  return o;
}

/// The checks every case shares: finite closed output, displacement at most `maxDisplacement` mm, and every level
/// either converged or stopped on its step cap (reported). Returns the largest displacement.
double expectSane(const msk::SegmentationResult& res, const msk::SegmentOptions& o, double maxDisplacement,
                  const std::string& what) {
  EXPECT_EQ(res.objects.size(), 1u) << what;
  if (res.objects.empty()) return 0;
  const msk::ObjectResult& ob = res.objects[0];
  EXPECT_TRUE(ob.mesh.vertices.allFinite()) << what;
  EXPECT_EQ(msk::closedMeshProblem(ob.mesh), "") << what;
  EXPECT_TRUE(std::isfinite(ob.volumeMm3) && ob.volumeMm3 > 0) << what;
  const Eigen::VectorXd& disp = ob.mesh.pointData.at("displacement_mm");
  EXPECT_TRUE(disp.allFinite()) << what;
  const double largest = disp.maxCoeff();
  EXPECT_LE(largest, maxDisplacement) << what;
  for (const msk::LevelReport& l : ob.levels) {
    EXPECT_TRUE(l.converged || l.steps == o.evolution.maxStepsPerLevel) << what;
    EXPECT_TRUE(std::isfinite(l.lastMaxMoveMm)) << what;
  }
  std::printf("[ %s ] %d vertices, displacement mean %.3f max %.3f mm, last level %d steps (%s), volume %.0f / %.0f mm3\n",
              what.c_str(), ob.mesh.vertexCount(), disp.mean(), largest, ob.levels.back().steps,
              ob.levels.back().converged ? "converged" : "step cap", ob.volumeMm3, ob.templateVolumeMm3);
  return largest;
}

double meanRadius(const msk::TriangleMesh& m, const Eigen::Vector3d& c) {
  double sum = 0;
  for (int i = 0; i < m.vertexCount(); ++i) sum += (m.vertices.row(i).transpose() - c).norm();
  return sum / m.vertexCount();
}

}  // namespace

// Voxels of 0.3 × 0.3 × 8 mm (thick slices): the ball still pulls the template out to about its radius.
TEST(SegmenterExtremes, VeryAnisotropicVoxels) {
  const msk::Grid g = boxGrid({0.3, 0.3, 8.0}, {13, 13, 16});
  const Eigen::Vector3d c(0.1, -0.2, 0.0);
  const msk::ImageF img = msk::test::ballImage(g, c, 9.0, 200.f, 800.f);
  const msk::SegmentOptions o = quick(1, 30);
  const msk::SegmentationResult res = msk::segmentScene(img, oneObject(msk::makeIcosphere(7.5, 3, c)), o);
  expectSane(res, o, 8.0, "0.3x0.3x8 mm voxels");
  const double r = meanRadius(res.objects[0].mesh, c);
  EXPECT_GT(r, 7.5);   // moved outward, toward the edge
  EXPECT_LT(r, 11.0);  // and not through it
}

// A constant image has no edges: nothing pulls, the template stays where it is.
TEST(SegmenterExtremes, ConstantImageLeavesTheTemplateInPlace) {
  const msk::Grid g = boxGrid({1.0, 1.0, 1.0}, {16, 16, 16});
  const msk::ImageF img(g, 500.f);
  const msk::SegmentOptions o = quick(2, 20);
  const msk::SegmentationResult res = msk::segmentScene(img, oneObject(msk::makeIcosphere(10.0, 3)), o);
  expectSane(res, o, 0.5, "constant image");
}

// Pure noise (uniform, no structure): the template may jitter but stays finite, closed and near where it started.
TEST(SegmenterExtremes, PureNoiseImageStaysBounded) {
  const msk::Grid g = boxGrid({1.0, 1.0, 1.0}, {16, 16, 16});
  msk::ImageF img(g, 0.f);
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(0.f, 1000.f);
  for (float& v : img.data) v = u(rng);
  const msk::SegmentOptions o = quick(2, 20);
  const msk::SegmentationResult res = msk::segmentScene(img, oneObject(msk::makeIcosphere(10.0, 3)), o);
  expectSane(res, o, 6.0, "pure noise");
  const double r = meanRadius(res.objects[0].mesh, Eigen::Vector3d::Zero());
  EXPECT_GT(r, 6.0);
  EXPECT_LT(r, 14.0);
}

// A NaN (or Inf) voxel is refused before any work with an Error that names the problem.
TEST(SegmenterExtremes, NaNVoxelIsRefusedWithAClearError) {
  const msk::Grid g = boxGrid({1.0, 1.0, 1.0}, {8, 8, 8});
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    msk::ImageF img = msk::test::ballImage(g, Eigen::Vector3d::Zero(), 5.0, 200.f, 800.f);
    img.at(3, 4, 5) = bad;
    try {
      msk::segmentScene(img, oneObject(msk::makeIcosphere(4.0, 2)), quick(1, 5));
      ADD_FAILURE() << "an image with a " << bad << " voxel was accepted";
    } catch (const msk::Error& e) {
      const std::string what = e.what();
      std::printf("[ nan voxel ] %s\n", what.c_str());
      EXPECT_NE(what.find("NaN"), std::string::npos) << what;
    }
  }
}

/// The ball scene with every length multiplied by `unit` (1 = mm, 1e-3 = metres), segmented with `levels` levels;
/// the result is returned in mm. Lengths given in mm in the options are scaled too (the coarse levels' extra search
/// range; edge penalty off: its rate is per mm).
msk::TriangleMesh ballInUnits(double unit, int levels) {
  const msk::Grid g = boxGrid(Eigen::Vector3d::Constant(1.0 * unit), Eigen::Vector3d::Constant(15.0 * unit));
  const Eigen::Vector3d c = Eigen::Vector3d(0.3, -0.2, 0.1) * unit;
  const msk::ImageF img = msk::test::ballImage(g, c, 10.0 * unit, 200.f, 800.f);
  msk::SegmentOptions o = quick(levels, 25);
  o.image.edgePenalty = 0;
  o.image.rangeCoarseExtraMm *= unit;
  const msk::SegmentationResult res = msk::segmentScene(img, oneObject(msk::makeIcosphere(8.0 * unit, 3, c)), o);
  msk::TriangleMesh m = res.objects.at(0).mesh;
  m.vertices /= unit;
  std::printf("[ units ] unit %g, %d level(s): mean radius %.4f mm, %d steps\n", unit, levels,
              meanRadius(m, Eigen::Vector3d(0.3, -0.2, 0.1)), res.objects[0].levels.back().steps);
  return m;
}

// The same scene with every length in metres (spacing 0.001, template and ball ×0.001) gives the same surface up to
// the factor 1000 (one level).
TEST(SegmenterExtremes, MetreSpacingGivesTheSameResultUpToScale) {
  const msk::TriangleMesh mm = ballInUnits(1.0, 1), m = ballInUnits(1e-3, 1);
  ASSERT_TRUE(m.vertices.allFinite());
  ASSERT_EQ(mm.vertexCount(), m.vertexCount());
  const double diff = (mm.vertices - m.vertices).cwiseAbs().maxCoeff();
  std::printf("[ units ] mm vs m, one level: largest vertex difference %.3g mm\n", diff);
  EXPECT_LT(diff, 1e-3);
}

// Coarse-to-fine (two levels) is just as scale-free: with every length scaled by 2⁻¹⁰ (exact in binary floating point)
// the surface is bitwise the same, so no length in the pipeline is tied to the millimetre (the coarse levels' extra
// search range is an option in mm, scaled like the others). In metres (× 1e-3, which rounds every coordinate) the
// rounding flips a few tie-breaks of the decimation that builds the coarse level: measured 0.004 mm, bound 0.01 mm.
TEST(SegmenterExtremes, MetreSpacingWithTwoLevels) {
  const msk::TriangleMesh mm = ballInUnits(1.0, 2), pow2 = ballInUnits(1.0 / 1024, 2), m = ballInUnits(1e-3, 2);
  ASSERT_TRUE(m.vertices.allFinite());
  ASSERT_EQ(mm.vertexCount(), m.vertexCount());
  ASSERT_EQ(mm.vertexCount(), pow2.vertexCount());
  const double exact = (mm.vertices - pow2.vertices).cwiseAbs().maxCoeff();
  const double diff = (mm.vertices - m.vertices).cwiseAbs().maxCoeff();
  std::printf("[ units ] two levels: largest vertex difference mm vs 2^-10 %.3g mm, mm vs m %.3g mm\n", exact, diff);
  EXPECT_EQ(exact, 0.0);
  EXPECT_LT(diff, 0.01);
}
