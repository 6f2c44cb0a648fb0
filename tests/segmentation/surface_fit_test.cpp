// A template fitted onto another subject's surface with its own triangulation (surface_fit.h).
#include "msk/segmentation/surface_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "msk/core/error.h"

namespace {

/// An ellipsoid with semi-axes (30, 20, 15) mm and a bump of 6 mm on its +y side, turned 25° about z and 10° about
/// x, centred at (5, -8, 12): a structure of another shape, size and pose than a sphere.
msk::TriangleMesh targetShape(Eigen::Matrix3d* turn, Eigen::Vector3d* centre) {
  msk::TriangleMesh m = msk::makeIcosphere(1, 3);  // another triangulation than the template's
  for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
    const Eigen::Vector3d u = m.vertices.row(v).transpose().normalized();
    const double bump = 6.0 * std::exp(-((u - Eigen::Vector3d::UnitY()).squaredNorm()) / 0.15);
    m.vertices.row(v) = Eigen::Vector3d(30 * u.x(), (20 + bump) * u.y(), 15 * u.z()).transpose();
  }
  *turn = (Eigen::AngleAxisd(25 * M_PI / 180, Eigen::Vector3d::UnitZ()) *
           Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitX()))
              .toRotationMatrix();
  *centre = Eigen::Vector3d(5, -8, 12);
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = *turn;
  t.topRightCorner<3, 1>() = *centre;
  msk::transformMesh(m, t);
  return m;
}

}  // namespace

TEST(SurfaceFit, ATemplateTakesAnotherSubjectsShapeAndPoseAndKeepsItsCorrespondence) {
  Eigen::Matrix3d turn;
  Eigen::Vector3d centre;
  const msk::TriangleMesh target = targetShape(&turn, &centre);
  // The template: an ellipsoid (26, 17, 13) mm without the bump, 5 mm off and not turned; its triangulation is not
  // the target's.
  msk::TriangleMesh sphere = msk::makeIcosphere(1, 4);
  sphere.vertices = sphere.vertices * Eigen::Vector3d(26, 17, 13).asDiagonal();
  sphere.vertices.rowwise() += (centre + Eigen::Vector3d(4, 0, -3)).transpose();
  msk::SurfaceFitReport rep;
  const msk::TriangleMesh fitted = msk::fitSurface(sphere, target, {}, &rep);
  ASSERT_EQ(fitted.vertexCount(), sphere.vertexCount());
  EXPECT_TRUE((fitted.faces.array() == sphere.faces.array()).all());
  EXPECT_LT(rep.meanDistanceMm, 0.1);
  EXPECT_LT(rep.maxDistanceMm, 1.0);
  EXPECT_LT(rep.meanReverseDistanceMm, 0.3);
  EXPECT_NEAR(rep.volumeRatio, 1.0, 0.02);
  EXPECT_EQ(rep.selfIntersections, 0u);
  // The template's points facing the target's long axis, its bump and its short axis end there.
  for (const Eigen::Vector3d& dir :
       {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(-1, 0, 0)}) {
    Eigen::Index best = 0;
    double bestDot = -2;
    for (Eigen::Index v = 0; v < sphere.vertices.rows(); ++v) {
      const Eigen::Vector3d u =
          (sphere.vertices.row(v).transpose() - (centre + Eigen::Vector3d(4, 0, -3))).normalized();
      if (u.dot(dir) > bestDot) bestDot = u.dot(dir), best = v;
    }
    const Eigen::Vector3d landed = turn.transpose() * (fitted.vertices.row(best).transpose() - centre);
    const Eigen::Vector3d pole = dir.cwiseProduct(Eigen::Vector3d(30, 26, 15));
    EXPECT_LT((landed - pole).norm(), 4.0) << "direction " << dir.transpose() << " landed at " << landed.transpose();
  }
}

TEST(SurfaceFit, RefusesAnOpenSurface) {
  msk::TriangleMesh open = msk::makeIcosphere(10, 2);
  open.faces.conservativeResize(open.faces.rows() - 1, 3);
  EXPECT_THROW(msk::fitSurface(open, msk::makeIcosphere(10, 2)), msk::Error);
  EXPECT_THROW(msk::fitSurface(msk::makeIcosphere(10, 2), open), msk::Error);
}
