// Volume preservation of a 2-simplex surface (volume_preservation.h): the volume is that of the recovered triangle
// mesh, its gradient matches finite differences, and the set holds the reference volume or follows the image as its
// decision rule says.
#include "msk/core/volume_preservation.h"

#include <gtest/gtest.h>

#include <cmath>

#include "msk/core/error.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/triangle_mesh.h"
#include "msk/test/shapes.h"

TEST(VolumePreservation, VolumeIsTheRecoveredSurfacesAndGradientMatchesFiniteDifferences) {
  const msk::SimplexMesh s = msk::test::simplexSphere(10.0);
  const msk::VolumePreservation vp(s);
  EXPECT_NEAR(vp.reference(), msk::enclosedVolume(msk::trianglesFromSimplex(s)), 1e-6 * vp.reference());
  msk::Points p = s.positions;
  p.col(0) *= 1.1;
  const msk::Points g = vp.volumeGradient(p);
  const double h = 1e-5;
  for (int v : {0, 7, 40}) {
    for (int c = 0; c < 3; ++c) {
      msk::Points a = p, b = p;
      a(v, c) += h;
      b(v, c) -= h;
      EXPECT_NEAR(g(v, c), (vp.volume(a) - vp.volume(b)) / (2 * h), 1e-5 * std::fabs(g.row(v).norm()) + 1e-6);
    }
  }
}

TEST(VolumePreservation, HoldsASmallChangeAndFollowsALargeOne) {
  const msk::SimplexMesh s = msk::test::simplexSphere(10.0);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(s.vertexCount());
  msk::VolumePreservationOptions o;
  o.maxObserveProjections = 2;
  // Inflated by 3 %: within the tolerance, so held back to the reference.
  msk::VolumePreservation hold(s, o);
  msk::Points p = s.positions * std::cbrt(1.03);
  for (int i = 0; i < 5; ++i) hold.project(p, w);
  EXPECT_EQ(hold.decision(), msk::VolumeDecision::Holding);
  EXPECT_NEAR(hold.volume(p), hold.reference(), 1e-6 * hold.reference());
  // Inflated by 20 %: the image demands it, left alone.
  msk::VolumePreservation follow(s, o);
  msk::Points q = s.positions * std::cbrt(1.2);
  const msk::Points q0 = q;
  for (int i = 0; i < 5; ++i) follow.project(q, w);
  EXPECT_EQ(follow.decision(), msk::VolumeDecision::Following);
  EXPECT_EQ((q - q0).cwiseAbs().maxCoeff(), 0.0);
  // Bad options.
  o.tolerance = 1.5;
  EXPECT_THROW(msk::VolumePreservation(s, o), msk::ParameterError);
  o = {};
  o.settleRate = -1;
  EXPECT_THROW(msk::VolumePreservation(s, o), msk::ParameterError);
}
