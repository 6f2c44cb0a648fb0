// Stability of the segmentation pipeline at the extremes: very anisotropic voxels, a constant image, a pure noise
// image, a NaN voxel and an image in metre units. Small grids, one or two levels and a coarse template keep every case
// fast. The scenes in other units are shared with bench/stability_bench.cpp, which reports their figures
// (BM_MetreSpacing).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "msk/core/error.h"
#include "msk/imaging/grid.h"
#include "msk/segmentation/segmenter.h"
#include "msk/test/ball_scenarios.h"
#include "msk/test/volumes.h"

namespace {

using msk::test::ballScene;
using msk::test::boxGrid;
using msk::test::meanRadius;
using msk::test::quickOptions;

/// The checks every case shares: finite closed output, displacement at most `maxDisplacement` mm, and every level
/// either converged or stopped on its step cap (ObjectResult::levels). Returns the largest displacement.
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
  return largest;
}

}  // namespace

// Voxels of 0.3 × 0.3 × 8 mm (thick slices): the ball still pulls the template out to about its radius.
TEST(SegmenterExtremes, VeryAnisotropicVoxels) {
  const msk::Grid g = boxGrid({0.3, 0.3, 8.0}, {13, 13, 16});
  const Eigen::Vector3d c(0.1, -0.2, 0.0);
  const msk::ImageF img = msk::test::ballImage(g, c, 9.0, 200.f, 800.f);
  const msk::SegmentOptions o = quickOptions(1, 30);
  const msk::SegmentationResult res = msk::segmentScene(img, ballScene(msk::makeIcosphere(7.5, 3, c)), o);
  expectSane(res, o, 8.0, "0.3x0.3x8 mm voxels");
  const double r = meanRadius(res.objects[0].mesh, c);
  EXPECT_GT(r, 7.5);   // moved outward, toward the edge
  EXPECT_LT(r, 11.0);  // and not through it
}

// A constant image is refused before any work; one flat but for a corner voxel has no edge near the template:
// nothing pulls, the template stays where it is.
TEST(SegmenterExtremes, FlatImageLeavesTheTemplateInPlace) {
  const msk::Grid g = boxGrid({1.0, 1.0, 1.0}, {16, 16, 16});
  msk::ImageF img(g, 500.f);
  const msk::SegmentOptions o = quickOptions(2, 20);
  EXPECT_THROW(msk::segmentScene(img, ballScene(msk::makeIcosphere(10.0, 3)), o), msk::Error);
  img.at(0, 0, 0) = 0.f;
  const msk::SegmentationResult res = msk::segmentScene(img, ballScene(msk::makeIcosphere(10.0, 3)), o);
  expectSane(res, o, 0.5, "flat image");
  EXPECT_EQ(res.status, msk::QualityStatus::Failed) << "no edge: the quality check says so";
}

// Pure noise (uniform, no structure): the template may jitter but stays finite, closed and near where it started.
TEST(SegmenterExtremes, PureNoiseImageStaysBounded) {
  const msk::Grid g = boxGrid({1.0, 1.0, 1.0}, {16, 16, 16});
  msk::ImageF img(g, 0.f);
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(0.f, 1000.f);
  for (float& v : img.data) v = u(rng);
  const msk::SegmentOptions o = quickOptions(2, 20);
  const msk::SegmentationResult res = msk::segmentScene(img, ballScene(msk::makeIcosphere(10.0, 3)), o);
  expectSane(res, o, 6.0, "pure noise");
  const double r = meanRadius(res.objects[0].mesh, Eigen::Vector3d::Zero());
  EXPECT_GT(r, 6.0);
  EXPECT_LT(r, 14.0);
  EXPECT_EQ(res.status, msk::QualityStatus::Failed) << "no edge stands out of the noise: the quality check says so";
}

// A NaN (or Inf) voxel is refused before any work with an Error that names the problem.
TEST(SegmenterExtremes, NaNVoxelIsRefusedWithAClearError) {
  const msk::Grid g = boxGrid({1.0, 1.0, 1.0}, {8, 8, 8});
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    msk::ImageF img = msk::test::ballImage(g, Eigen::Vector3d::Zero(), 5.0, 200.f, 800.f);
    img.at(3, 4, 5) = bad;
    try {
      msk::segmentScene(img, ballScene(msk::makeIcosphere(4.0, 2)), quickOptions(1, 5));
      ADD_FAILURE() << "an image with a " << bad << " voxel was accepted";
    } catch (const msk::Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("NaN"), std::string::npos) << what;
    }
  }
}

// The same scene with every length in metres (spacing 0.001, template and ball ×0.001) gives the same surface up to
// the factor 1000 (one level).
TEST(SegmenterExtremes, MetreSpacingGivesTheSameResultUpToScale) {
  const msk::TriangleMesh mm = msk::test::ballInUnits(1.0, 1), m = msk::test::ballInUnits(1e-3, 1);
  ASSERT_TRUE(m.vertices.allFinite());
  ASSERT_EQ(mm.vertexCount(), m.vertexCount());
  const double diff = (mm.vertices - m.vertices).cwiseAbs().maxCoeff();
  EXPECT_LT(diff, 1e-3);
}

// Coarse-to-fine (two levels) is just as scale-free: with every length scaled by 2⁻¹⁰ (exact in binary floating point)
// the surface is bitwise the same, so no length in the pipeline is tied to the millimetre (the coarse levels' extra
// search range is an option in mm, scaled like the others). In metres (× 1e-3, which rounds every coordinate) the
// rounding flips a few tie-breaks of the decimation that builds the coarse level: measured 0.004 mm, bound 0.01 mm.
TEST(SegmenterExtremes, MetreSpacingWithTwoLevels) {
  const msk::TriangleMesh mm = msk::test::ballInUnits(1.0, 2), pow2 = msk::test::ballInUnits(1.0 / 1024, 2),
                          m = msk::test::ballInUnits(1e-3, 2);
  ASSERT_TRUE(m.vertices.allFinite());
  ASSERT_EQ(mm.vertexCount(), m.vertexCount());
  ASSERT_EQ(mm.vertexCount(), pow2.vertexCount());
  const double exact = (mm.vertices - pow2.vertices).cwiseAbs().maxCoeff();
  const double diff = (mm.vertices - m.vertices).cwiseAbs().maxCoeff();
  EXPECT_EQ(exact, 0.0);
  EXPECT_LT(diff, 0.01);
}
