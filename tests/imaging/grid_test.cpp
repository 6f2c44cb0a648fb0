#include "msk/imaging/grid.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

TEST(Grid, WorldVoxelWorldIsIdentityOnObliqueAnisotropicGrid) {
  msk::Grid g;
  g.dims = {40, 50, 12};
  g.spacing = {0.8, 0.8, 3.0};
  g.direction = msk::Grid::rotationXYZ({20, -35, 50});
  g.direction.col(2) *= -1;  // an improper (left-handed) direction too
  g.origin = {-100.5, 20.25, 33.0};
  ASSERT_EQ(g.problem(), "");
  for (int t = 0; t < 100; ++t) {
    Eigen::Vector3d ijk = Eigen::Vector3d::Random().cwiseAbs().cwiseProduct(g.dims.cast<double>());
    Eigen::Vector3d w = g.toWorld(ijk);
    EXPECT_LT((g.toVoxel(w) - ijk).norm(), 1e-10);
    Eigen::Vector4d h = g.voxelToWorld() * ijk.homogeneous();
    EXPECT_LT((h.head<3>() - w).norm(), 1e-10);
    EXPECT_LT(((g.worldToVoxel() * h).head<3>() - ijk).norm(), 1e-10);
  }
  // Step of one voxel along k moves 3 mm in world space.
  EXPECT_NEAR((g.toWorld({0, 0, 1}) - g.toWorld({0, 0, 0})).norm(), 3.0, 1e-12);
}

TEST(Grid, FromAffineDecomposesAndRejectsShear) {
  msk::Grid g;
  Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
  a.topLeftCorner<3, 3>() = msk::Grid::rotationXYZ({10, 0, 30}) * Eigen::Vector3d(0.5, 0.6, 2.0).asDiagonal();
  a.topRightCorner<3, 1>() << 1, 2, 3;
  ASSERT_TRUE(msk::Grid::fromAffine({4, 5, 6}, a, g));
  EXPECT_LT((g.voxelToWorld() - a).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(g.spacing[2], 2.0, 1e-12);
  Eigen::Matrix4d sheared = a;
  sheared(0, 1) += 0.2;
  EXPECT_FALSE(msk::Grid::fromAffine({4, 5, 6}, sheared, g));
  msk::Grid bad;
  bad.dims = {0, 3, 3};
  EXPECT_NE(bad.problem(), "");
}
