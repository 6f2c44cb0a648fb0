#include "msk/imaging/rasterize.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "msk/core/error.h"
#include "msk/test/shapes.h"
#include "msk/test/volumes.h"

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A grid of `dims` voxels of `spacing` with direction `dir`, centred (roughly) on `centre`, slightly offset
/// so that no symmetry lines up with voxel centres.
msk::Grid gridAround(const Eigen::Vector3d& centre, const Eigen::Vector3i& dims, const Eigen::Vector3d& spacing,
                     const Eigen::Matrix3d& dir) {
  msk::Grid g;
  g.dims = dims;
  g.spacing = spacing;
  g.direction = dir;
  const Eigen::Vector3d half =
      (dims.cast<double>() - Eigen::Vector3d::Ones()) / 2 + Eigen::Vector3d(0.137, 0.291, 0.043);
  g.origin = centre - dir * spacing.cwiseProduct(half);
  return g;
}

struct Overlap {
  double dice = 0;
  size_t meshVoxels = 0;
};

/// Dice of the rasterised label (1) against the analytic ball |x − c| ≤ r sampled at voxel centres, and the number
/// of labelled voxels.
Overlap compareWithBall(const msk::LabelMap& labels, const Eigen::Vector3d& c, double r) {
  Overlap o;
  o.dice = msk::test::labelDice(labels, 1, msk::test::ballLabels(labels.grid, c, r), 1);
  o.meshVoxels =
      static_cast<size_t>(std::count_if(labels.data.begin(), labels.data.end(), [](int32_t v) { return v != 0; }));
  return o;
}

TEST(Rasterize, SphereOnObliqueAnisotropicGridMatchesTheBall) {
  const Eigen::Vector3d c(5.3, -7.1, 12.9);
  const double r = 20.0;
  const msk::TriangleMesh sphere = msk::makeIcosphere(r, 5, c);
  ASSERT_EQ(sphere.faceCount(), 20480);
  for (bool improper : {false, true}) {
    SCOPED_TRACE(improper ? "det -1" : "det +1");
    Eigen::Matrix3d dir = msk::Grid::rotationXYZ({30, -20, 45});
    if (improper) dir.col(1) *= -1;
    ASSERT_NEAR(dir.determinant(), improper ? -1.0 : 1.0, 1e-12);
    const msk::Grid g = gridAround(c, {64, 64, 18}, {0.8, 0.8, 3.0}, dir);
    ASSERT_EQ(g.problem(), "");
    const msk::LabelMap labels = msk::rasterize(sphere, g);
    ASSERT_TRUE(labels.grid.sameGeometry(g));
    const Overlap o = compareWithBall(labels, c, r);
    const double voxelVolume = g.spacing.prod();
    const double ballVolume = 4.0 / 3.0 * kPi * r * r * r;
    EXPECT_GE(o.dice, 0.97);
    EXPECT_NEAR(o.meshVoxels * voxelVolume, ballVolume, 0.03 * ballVolume);
    // Only 0/1 values, and the grid border (beyond the ball) stays empty.
    for (int32_t v : labels.data) ASSERT_TRUE(v == 0 || v == 1);
  }
}

TEST(Rasterize, IntoKeepsOtherVoxelsAndOverwritesInside) {
  const Eigen::Vector3d c(0, 0, 0);
  const msk::TriangleMesh sphere = msk::makeIcosphere(6.0, 3, c);
  const msk::Grid g = gridAround(c, {20, 20, 20}, {1, 1, 1}, Eigen::Matrix3d::Identity());
  msk::LabelMap labels(g, 3);
  msk::rasterizeInto(labels, sphere, 7);
  size_t sevens = 0, threes = 0;
  for (int32_t v : labels.data) {
    sevens += v == 7;
    threes += v == 3;
  }
  EXPECT_EQ(sevens + threes, g.voxelCount());
  EXPECT_NEAR(static_cast<double>(sevens), msk::enclosedVolume(sphere), 0.06 * msk::enclosedVolume(sphere));
  EXPECT_EQ(labels.at(10, 10, 10), 7);
  EXPECT_EQ(labels.at(0, 0, 0), 3);
}

// A cube whose corners, edges and face diagonals pass exactly through voxel-centre rows, including rays lying
// in a face plane: any inconsistency at edges or vertices would fill stray segments or leave gaps.
TEST(Rasterize, RaysThroughVerticesAndEdgesAreCountedOnce) {
  msk::TriangleMesh cube;
  cube.vertices.resize(8, 3);
  for (int v = 0; v < 8; ++v) cube.vertices.row(v) << (v & 1 ? 7 : 2), (v & 2 ? 7 : 2), (v & 4 ? 7 : 2);
  cube.faces.resize(12, 3);
  cube.faces << 0, 2, 1, 1, 2, 3,  // z = 2 (normal −z)
      4, 5, 6, 5, 7, 6,            // z = 7
      0, 1, 4, 1, 5, 4,            // y = 2
      2, 6, 3, 3, 6, 7,            // y = 7
      0, 4, 2, 2, 4, 6,            // x = 2
      1, 3, 5, 3, 7, 5;            // x = 7
  ASSERT_EQ(msk::closedMeshProblem(cube), "");
  ASSERT_NEAR(msk::enclosedVolume(cube), 125.0, 1e-12);
  msk::Grid g;
  g.dims = {10, 10, 10};
  const msk::LabelMap labels = msk::rasterize(cube, g);
  for (int k = 0; k < 10; ++k)
    for (int j = 0; j < 10; ++j) {
      int first = -1, last = -1, count = 0;
      for (int i = 0; i < 10; ++i)
        if (labels.at(i, j, k)) {
          if (first < 0) first = i;
          last = i;
          ++count;
        }
      if (count) {
        EXPECT_EQ(last - first + 1, count) << "row j=" << j << " k=" << k << " is not one run";
        EXPECT_TRUE(first >= 2 && last <= 7) << "row j=" << j << " k=" << k;
      }
      const bool interiorRow = j >= 3 && j <= 6 && k >= 3 && k <= 6;
      const bool outsideRow = j < 2 || j > 7 || k < 2 || k > 7;
      if (interiorRow) {
        EXPECT_TRUE(first == 2 && last == 7) << "row j=" << j << " k=" << k;
      }
      if (outsideRow) {
        EXPECT_EQ(count, 0) << "row j=" << j << " k=" << k;
      }
    }
  // The same cube, voxel grid shifted by half a voxel: no ties, exactly 5×5×5 centres inside.
  g.origin = {0.5, 0.5, 0.5};
  const msk::LabelMap shifted = msk::rasterize(cube, g);
  size_t inside = 0;
  for (int32_t v : shifted.data) inside += v != 0;
  EXPECT_EQ(inside, 125u);
}

// The volume of a 20 480-triangle sphere on a 256 × 256 × 100 oblique grid (BM_RasterizeLargeGrid in
// bench/mesh_bench.cpp times it).
TEST(Rasterize, LargeGridAndTwentyThousandTriangles) {
  const Eigen::Vector3d c(1.5, -2.25, 3.0);
  const double r = 45.0;
  const msk::TriangleMesh sphere = msk::makeIcosphere(r, 5, c);
  const msk::Grid g = gridAround(c, {256, 256, 100}, {0.4, 0.4, 1.0}, msk::Grid::rotationXYZ({5, 10, -15}));
  const msk::LabelMap labels = msk::rasterize(sphere, g);
  size_t inside = 0;
  for (int32_t v : labels.data) inside += v != 0;
  const double volume = static_cast<double>(inside) * g.spacing.prod();
  EXPECT_NEAR(volume, msk::enclosedVolume(sphere), 0.01 * msk::enclosedVolume(sphere));
}

TEST(Rasterize, OpenMeshThrows) {
  msk::TriangleMesh open = msk::makeIcosphere(5.0, 2);
  open.faces.conservativeResize(open.faceCount() - 1, 3);
  msk::Grid g;
  g.dims = {16, 16, 16};
  g.origin = {-8, -8, -8};
  try {
    msk::rasterize(open, g);
    FAIL() << "open mesh accepted";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("not closed"), std::string::npos) << e.what();
  }
  msk::LabelMap labels(g, 0);
  EXPECT_THROW(msk::rasterizeInto(labels, msk::TriangleMesh{}, 1), msk::Error);
}

}  // namespace

// A folded surface covers some points twice and turns some sheets inside out. The label follows the winding number
// (inside where it is positive), not the parity of crossings: a region covered twice is filled (parity would leave a
// hole) and a region enclosed only by a turned-over sheet (winding number −1) is left out (parity would fill it).
TEST(Rasterize, FollowsTheWindingNumberWhereTheSurfaceFolds) {
  auto join = [](const msk::TriangleMesh& a, msk::TriangleMesh b, bool flipB) {
    if (flipB) msk::flipFaces(b);
    return msk::test::joinedMeshes(a, b);
  };
  const msk::TriangleMesh a = msk::makeIcosphere(6.0, 3, {0, 0, 0}), b = msk::makeIcosphere(6.0, 3, {6.3, 0.2, 0.1});
  msk::Grid g;
  g.dims = {40, 30, 30};
  g.spacing = {0.5, 0.5, 0.5};
  g.origin = {-8.1, -7.3, -7.2};
  auto at = [&](const msk::LabelMap& l, const Eigen::Vector3d& p) {
    const Eigen::Vector3d v = g.toVoxel(p);
    return l.at(static_cast<int>(std::lround(v.x())), static_cast<int>(std::lround(v.y())),
                static_cast<int>(std::lround(v.z())));
  };
  const msk::LabelMap twice = msk::rasterize(join(a, b, false), g);
  EXPECT_NE(at(twice, {3.1, 0, 0}), 0);  // covered twice (both spheres)
  EXPECT_NE(at(twice, {-3, 0, 0}), 0);   // once (a only)
  EXPECT_NE(at(twice, {9.5, 0, 0}), 0);  // once (b only)
  const msk::LabelMap turned = msk::rasterize(join(a, b, true), g);
  EXPECT_NE(at(turned, {-3, 0, 0}), 0);   // a only: winding number 1
  EXPECT_EQ(at(turned, {3.1, 0, 0}), 0);  // a and the turned sheet: 0
  EXPECT_EQ(at(turned, {9.5, 0, 0}), 0);  // the turned sheet only: −1
  // Volumes: the union, and a minus b.
  size_t nTwice = 0, nTurned = 0;
  for (size_t i = 0; i < twice.data.size(); ++i) {
    nTwice += twice.data[i] != 0;
    nTurned += turned.data[i] != 0;
  }
  EXPECT_GT(nTwice, nTurned * 2);
}

namespace {

/// An axis-aligned box [lo, hi] as 12 outward-facing triangles.
msk::TriangleMesh boxMesh(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  msk::TriangleMesh box;
  box.vertices.resize(8, 3);
  for (int v = 0; v < 8; ++v)
    box.vertices.row(v) << (v & 1 ? hi.x() : lo.x()), (v & 2 ? hi.y() : lo.y()), (v & 4 ? hi.z() : lo.z());
  box.faces.resize(12, 3);
  box.faces << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7,
      5;
  return box;
}

std::vector<size_t> labelledIndices(const msk::LabelMap& labels) {
  std::vector<size_t> out;
  for (size_t v = 0; v < labels.data.size(); ++v)
    if (labels.data[v] != 0) out.push_back(v);
  return out;
}

}  // namespace

// The voxel list without a label map is the label map's, voxel for voxel and ascending: on ties at voxel centres, on
// two boxes that touch in a plane of voxel centres (where one run of a row ends on the voxel the next starts on), on a
// folded surface and on an oblique grid.
TEST(Rasterize, InsideVoxelIndicesAreTheLabelledVoxels) {
  msk::Grid unit;
  unit.dims = {12, 10, 10};
  const msk::TriangleMesh touching =
      msk::test::joinedMeshes(boxMesh({2, 2, 2}, {5, 7, 7}), boxMesh({5, 2, 2}, {9, 7, 7}));
  const std::vector<size_t> touchingList = msk::insideVoxelIndices(touching, unit);
  EXPECT_EQ(touchingList, labelledIndices(msk::rasterize(touching, unit)));
  const size_t row44 = unit.index(0, 4, 4);  // an interior row: i 2..9, the shared voxel i = 5 once
  EXPECT_EQ(
      std::count_if(touchingList.begin(), touchingList.end(), [&](size_t v) { return v >= row44 && v < row44 + 12; }),
      8);
  EXPECT_TRUE(std::adjacent_find(touchingList.begin(), touchingList.end(), std::greater_equal<size_t>()) ==
              touchingList.end());

  const msk::TriangleMesh cube = boxMesh({2, 2, 2}, {7, 7, 7});
  EXPECT_EQ(msk::insideVoxelIndices(cube, unit), labelledIndices(msk::rasterize(cube, unit)));

  msk::TriangleMesh turned = msk::makeIcosphere(6.0, 3, {6.3, 0.2, 0.1});
  msk::flipFaces(turned);
  const msk::TriangleMesh folded = msk::test::joinedMeshes(msk::makeIcosphere(6.0, 3, {0, 0, 0}), turned);
  msk::Grid g;
  g.dims = {40, 30, 30};
  g.spacing = {0.5, 0.5, 0.5};
  g.origin = {-8.1, -7.3, -7.2};
  EXPECT_EQ(msk::insideVoxelIndices(folded, g), labelledIndices(msk::rasterize(folded, g)));

  const Eigen::Vector3d c(5.3, -7.1, 12.9);
  const msk::TriangleMesh sphere = msk::makeIcosphere(20.0, 4, c);
  const msk::Grid oblique = gridAround(c, {64, 64, 18}, {0.8, 0.8, 3.0}, msk::Grid::rotationXYZ({30, -20, 45}));
  const std::vector<size_t> sphereList = msk::insideVoxelIndices(sphere, oblique);
  EXPECT_GT(sphereList.size(), 1000u);
  EXPECT_EQ(sphereList, labelledIndices(msk::rasterize(sphere, oblique)));
}
