// repairOverlapVoxels(): voxel centres inside both surfaces of a pair are handed to one surface, by inward moves only.
#include "msk/segmentation/overlap_repair.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <iterator>

#include "msk/core/error.h"
#include "msk/imaging/rasterize.h"

namespace {

/// A 1 mm grid over [−16, 36] × [−16, 16] × [−16, 16] mm, axes slightly rotated so voxel centres fall anywhere.
msk::Grid testGrid() {
  msk::Grid g;
  g.spacing = Eigen::Vector3d(1.0, 1.0, 1.0);
  g.direction = msk::Grid::rotationXYZ(Eigen::Vector3d(3, -2, 5));
  g.dims = Eigen::Vector3i(53, 33, 33);
  g.origin = Eigen::Vector3d(-16.2, -16.3, -15.9);
  return g;
}

/// Voxels in both sorted lists.
size_t shared(const std::vector<size_t>& a, const std::vector<size_t>& b) {
  std::vector<size_t> both;
  std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both));
  return both.size();
}

}  // namespace

// Two balls of radius 10 mm whose centres are 17 mm apart share a lens 3 mm thick (about 134 mm³): every shared centre
// is handed over, every vertex moves inward or not at all, and the volume lost is of the order of the lens, not more.
TEST(OverlapRepair, OverlappingBallsEndWithNoSharedVoxel) {
  const msk::Grid g = testGrid();
  const Eigen::Vector3d ca(0, 0, 0), cb(17, 0.3, -0.2);
  msk::TriangleMesh a = msk::makeIcosphere(10, 4, ca), b = msk::makeIcosphere(10, 4, cb);
  const msk::TriangleMesh a0 = a, b0 = b;
  std::vector<std::vector<size_t>> masks = {msk::insideVoxels(a, g), msk::insideVoxels(b, g)};
  const size_t before = shared(masks[0], masks[1]);
  ASSERT_GT(before, 10u);
  const msk::OverlapRepairReport r = msk::repairOverlapVoxels({&a, &b}, {{0, 1}}, g, 0.1, masks);
  const size_t after = shared(msk::insideVoxels(a, g), msk::insideVoxels(b, g));
  EXPECT_EQ(after, 0u);
  EXPECT_EQ(r.remaining, 0u);
  EXPECT_GE(r.handedOver, static_cast<long>(before));
  EXPECT_EQ(shared(masks[0], masks[1]), 0u);  // the lists are kept up to date
  for (auto [m, m0, c] : {std::tuple{&a, &a0, ca}, std::tuple{&b, &b0, cb}}) {
    EXPECT_TRUE(msk::closedMeshProblem(*m).empty());
    for (Eigen::Index v = 0; v < m->vertices.rows(); ++v)
      EXPECT_LE((m->vertices.row(v).transpose() - c).norm(), (m0->vertices.row(v).transpose() - c).norm() + 1e-12);
  }
  // Each ball must give up about half the lens (2 caps of π h² (3r − h) / 3, h = 1.5 mm: 134 mm³ in all).
  const double lost =
      msk::enclosedVolume(a0) + msk::enclosedVolume(b0) - msk::enclosedVolume(a) - msk::enclosedVolume(b);
  EXPECT_GT(lost, 0.0);
  EXPECT_LT(lost, 300.0);
}

TEST(OverlapRepair, NothingSharedMovesNothing) {
  const msk::Grid g = testGrid();
  msk::TriangleMesh a = msk::makeIcosphere(10, 3, Eigen::Vector3d(0, 0, 0));
  msk::TriangleMesh b = msk::makeIcosphere(10, 3, Eigen::Vector3d(21, 0, 0));
  const msk::TriangleMesh a0 = a, b0 = b;
  std::vector<std::vector<size_t>> masks = {msk::insideVoxels(a, g), msk::insideVoxels(b, g)};
  const msk::OverlapRepairReport r = msk::repairOverlapVoxels({&a, &b}, {{0, 1}}, g, 0.1, masks);
  EXPECT_EQ(r.handedOver, 0);
  EXPECT_EQ(r.rounds, 0);
  EXPECT_EQ((a.vertices - a0.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((b.vertices - b0.vertices).cwiseAbs().maxCoeff(), 0.0);
}

TEST(OverlapRepair, OnlyDeclaredPairsAreRepaired) {
  const msk::Grid g = testGrid();
  msk::TriangleMesh a = msk::makeIcosphere(10, 3, Eigen::Vector3d(0, 0, 0));
  msk::TriangleMesh b = msk::makeIcosphere(10, 3, Eigen::Vector3d(19, 0, 0));
  msk::TriangleMesh c = msk::makeIcosphere(3, 2, Eigen::Vector3d(0, 0, 20));
  std::vector<std::vector<size_t>> masks = {msk::insideVoxels(a, g), msk::insideVoxels(b, g), msk::insideVoxels(c, g)};
  const msk::TriangleMesh a0 = a;
  const msk::OverlapRepairReport r = msk::repairOverlapVoxels({&a, &b, &c}, {{1, 2}}, g, 0.1, masks);
  EXPECT_EQ(r.handedOver, 0);
  EXPECT_EQ((a.vertices - a0.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(shared(masks[0], masks[1]), 0u);  // a and b are no declared pair: left as they are (and counted)
}

TEST(OverlapRepair, RejectsBadInput) {
  const msk::Grid g = testGrid();
  msk::TriangleMesh a = msk::makeIcosphere(10, 2), b = msk::makeIcosphere(10, 2, Eigen::Vector3d(19, 0, 0));
  std::vector<std::vector<size_t>> masks = {msk::insideVoxels(a, g), msk::insideVoxels(b, g)};
  EXPECT_THROW(msk::repairOverlapVoxels({&a, &b}, {{0, 1}}, g, -1.0, masks), msk::ParameterError);
  EXPECT_THROW(msk::repairOverlapVoxels({&a, &b}, {{0, 2}}, g, 0.1, masks), msk::ParameterError);
  EXPECT_THROW(msk::repairOverlapVoxels({&a, &b}, {{0, 1}}, g, 0.1, masks, -1), msk::ParameterError);
  std::vector<std::vector<size_t>> one = {masks[0]};
  EXPECT_THROW(msk::repairOverlapVoxels({&a, &b}, {{0, 1}}, g, 0.1, one), msk::ParameterError);
  std::vector<std::vector<size_t>> outside = {{g.voxelCount()}, {}};
  EXPECT_THROW(msk::repairOverlapVoxels({&a, &b}, {{0, 1}}, g, 0.1, outside), msk::ParameterError);
}
