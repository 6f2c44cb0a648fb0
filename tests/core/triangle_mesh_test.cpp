#include "msk/core/triangle_mesh.h"

#include <gtest/gtest.h>

#include <cmath>

TEST(TriangleMesh, IcosphereIsClosedAndApproximatesTheBall) {
  msk::TriangleMesh m = msk::makeIcosphere(10.0, 4, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(m.faceCount(), 20 * 256);
  EXPECT_EQ(msk::closedMeshProblem(m), "");
  const double v = 4.0 / 3.0 * M_PI * 1000.0;
  EXPECT_NEAR(msk::enclosedVolume(m), v, 0.01 * v);
  EXPECT_NEAR(msk::surfaceArea(m), 4 * M_PI * 100.0, 0.01 * 4 * M_PI * 100.0);
  msk::Points n = msk::vertexNormals(m);
  Eigen::Vector3d radial = (m.vertices.row(7).transpose() - Eigen::Vector3d(1, 2, 3)).normalized();
  EXPECT_GT(n.row(7).dot(radial), 0.999);
}

TEST(TriangleMesh, MirrorTransformKeepsNormalsOutward) {
  msk::TriangleMesh m = msk::makeIcosphere(5.0, 2);
  const double v = msk::enclosedVolume(m);
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  msk::transformMesh(m, mirror);
  EXPECT_NEAR(msk::enclosedVolume(m), v, 1e-9);
  msk::transformMesh(m, msk::rasLpsFlip());  // det +1: no flip needed, volume unchanged
  EXPECT_NEAR(msk::enclosedVolume(m), v, 1e-9);
}

TEST(TriangleMesh, ClosedMeshProblemsAreNamed) {
  msk::TriangleMesh m = msk::makeIcosphere(5.0, 1);
  msk::TriangleMesh open = m;
  open.faces.conservativeResize(open.faceCount() - 1, 3);
  EXPECT_NE(msk::closedMeshProblem(open).find("not closed"), std::string::npos);
  msk::TriangleMesh flipped = m;
  std::swap(flipped.faces(0, 1), flipped.faces(0, 2));
  EXPECT_NE(msk::closedMeshProblem(flipped).find("used twice"), std::string::npos);
  // A face listed twice: the repeat named is the first one made, its first edge.
  msk::TriangleMesh doubled = m;
  doubled.faces.conservativeResize(doubled.faceCount() + 1, 3);
  doubled.faces.row(doubled.faceCount() - 1) = doubled.faces.row(3);
  EXPECT_EQ(msk::closedMeshProblem(doubled), "edge " + std::to_string(m.faces(3, 0)) + "-" +
                                                 std::to_string(m.faces(3, 1)) +
                                                 " is used twice in the same direction (non-manifold or inconsistently "
                                                 "oriented)");
  msk::TriangleMesh empty;
  EXPECT_NE(msk::closedMeshProblem(empty).find("empty"), std::string::npos);
  msk::TriangleMesh nan = m;
  nan.vertices(0, 0) = NAN;
  EXPECT_NE(msk::closedMeshProblem(nan).find("non-finite"), std::string::npos);
}
