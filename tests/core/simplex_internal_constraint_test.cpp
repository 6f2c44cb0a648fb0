#include "msk/core/simplex_internal_constraint.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "msk/test/shapes.h"

namespace {
using msk::test::uniformVector;
}  // namespace

// Internal-constraint corrections of method 2 carry no linear and no angular momentum (DESIGN-NOTES §2).
TEST(SimplexInternalKernel, ConservesLinearAndAngularMomentum) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> um(0.2, 5.0);
  int method2 = 0;
  for (int t = 0; t < 2000; ++t) {
    Eigen::Vector3d pi[3] = {Eigen::Vector3d(10, 0, 0) + uniformVector(rng, 2),
                             Eigen::Vector3d(-5, 8.7, 0) + uniformVector(rng, 2),
                             Eigen::Vector3d(-5, -8.7, 0) + uniformVector(rng, 2)};
    const Eigen::Vector3d p = Eigen::Vector3d(0, 0, 3) + uniformVector(rng, 2);
    const double eps[3] = {0.3, 0.3, 0.4};
    const Eigen::Vector3d target =
        eps[0] * pi[0] + eps[1] * pi[1] + eps[2] * pi[2] + Eigen::Vector3d(0, 0, 2) + uniformVector(rng, 0.5);
    const double w = 1.0 / um(rng), wi[3] = {1.0 / um(rng), 1.0 / um(rng), 1.0 / um(rng)};
    Eigen::Vector3d dp, dpi[3];
    bool torqueFree = false;
    ASSERT_TRUE(msk::simplexInternalCorrection(p, pi, target, w, wi, eps, 1.0, dp, dpi, &torqueFree));
    Eigen::Vector3d lin = dp / w, ang = p.cross(dp) / w;
    for (int i = 0; i < 3; ++i) {
      lin += dpi[i] / wi[i];
      ang += pi[i].cross(dpi[i]) / wi[i];
    }
    const double scale = dp.norm() / w + 1e-12;
    EXPECT_LT(lin.norm(), 1e-9 * scale * 10);
    // Angular momentum vanishes whenever the torque-free split exists (method 2 proper).
    if (torqueFree) {
      ++method2;
      EXPECT_LT(ang.norm(), 1e-9 * scale * 100) << "trial " << t;
    }
  }
  EXPECT_GT(method2, 1500);  // most random configurations take the torque-free branch
}

TEST(SimplexInternalKernel, FullStepReachesTheTargetToFirstOrder) {
  Eigen::Vector3d pi[3] = {{10, 0, 0}, {-5, 8.7, 0}, {-5, -8.7, 0}};
  const double eps[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  const Eigen::Vector3d p(0.3, -0.2, 2.0);
  const Eigen::Vector3d target = (pi[0] + pi[1] + pi[2]) / 3 + Eigen::Vector3d(0, 0, 2.2);
  const double w = 1, wi[3] = {1, 1, 1};
  Eigen::Vector3d dp, dpi[3];
  ASSERT_TRUE(msk::simplexInternalCorrection(p, pi, target, w, wi, eps, 1.0, dp, dpi));
  // New target with the moved neighbours, same plane normal and height offset (linearised constraint).
  Eigen::Vector3d moved[3] = {pi[0] + dpi[0], pi[1] + dpi[1], pi[2] + dpi[2]};
  const Eigen::Vector3d newTarget = (moved[0] + moved[1] + moved[2]) / 3 + Eigen::Vector3d(0, 0, 2.2);
  EXPECT_LT((newTarget - (p + dp)).norm(), 1e-9);
  // γ = 0 moves nothing; a fixed vertex with fixed neighbours is degenerate.
  ASSERT_TRUE(msk::simplexInternalCorrection(p, pi, target, w, wi, eps, 0.0, dp, dpi));
  EXPECT_EQ(dp.norm(), 0.0);
  const double fixed[3] = {0, 0, 0};
  EXPECT_FALSE(msk::simplexInternalCorrection(p, pi, target, 0.0, fixed, eps, 1.0, dp, dpi));
}

TEST(SimplexInternalKernel, FixedNeighboursLeaveAllTheCorrectionToTheVertex) {
  Eigen::Vector3d pi[3] = {{10, 0, 0}, {-5, 8.7, 0}, {-5, -8.7, 0}};
  const double eps[3] = {0.2, 0.3, 0.5};
  const Eigen::Vector3d p(1, 1, 1), target(0.5, -0.5, 3);
  const double wi[3] = {0, 0, 0};
  Eigen::Vector3d dp, dpi[3];
  ASSERT_TRUE(msk::simplexInternalCorrection(p, pi, target, 1.0, wi, eps, 1.0, dp, dpi));
  EXPECT_LT((p + dp - target).norm(), 1e-12);
  for (const auto& d : dpi) EXPECT_EQ(d.norm(), 0.0);
}

TEST(SimplexShapeTarget, ScalesHeightWithTheNeighbourhood) {
  Eigen::Vector3d pi[3] = {{1, 0, 0}, {-0.5, 0.8660254, 0}, {-0.5, -0.8660254, 0}};
  const double eps[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  Eigen::Vector3d t;
  ASSERT_TRUE(msk::simplexShapeTarget(pi, eps, 0.5, t));
  EXPECT_NEAR(t.z(), 0.5, 1e-6);  // circumradius 1
  for (auto& q : pi) q *= 4.0;
  ASSERT_TRUE(msk::simplexShapeTarget(pi, eps, 0.5, t));
  EXPECT_NEAR(t.z(), 2.0, 1e-6);
  Eigen::Vector3d line[3] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  EXPECT_FALSE(msk::simplexShapeTarget(line, eps, 0.5, t));
}

// The reference parameters rebuild every vertex of a simplex sphere from its neighbours, P = Σ ε̃i Pi + h̃ r⊥ n (so
// the shape memory's target of the template is the template), with ε̃ near ⅓ on the nearly regular mesh and h̃ > 0
// (convex); collinear neighbours give ε̃ = ⅓ and h̃ = 0.
TEST(SimplexReferenceParameters, RebuildEveryVertexOfASphereFromItsNeighbours) {
  msk::SimplexMesh s = msk::test::simplexSphere(15.0, 3, Eigen::Vector3d(1, -2, 3));
  Eigen::MatrixX3d eps;
  Eigen::VectorXd hr;
  msk::simplexReferenceParameters(s, eps, hr);
  ASSERT_EQ(eps.rows(), s.vertexCount());
  for (int v = 0; v < s.vertexCount(); ++v) {
    const Eigen::Vector3d pi[3] = {s.positions.row(s.neighbors(v, 0)), s.positions.row(s.neighbors(v, 1)),
                                   s.positions.row(s.neighbors(v, 2))};
    const double e[3] = {eps(v, 0), eps(v, 1), eps(v, 2)};
    Eigen::Vector3d target;
    ASSERT_TRUE(msk::simplexShapeTarget(pi, e, hr[v], target));
    EXPECT_LT((target - s.positions.row(v).transpose()).norm(), 1e-9) << v;
    EXPECT_NEAR(eps.row(v).sum(), 1.0, 1e-12);
    EXPECT_LT((eps.row(v).array() - 1.0 / 3.0).abs().maxCoeff(), 0.1) << v;
    EXPECT_GT(hr[v], 0) << v;
  }
  const int v = 7;
  const Eigen::Vector3d p1 = s.positions.row(s.neighbors(v, 0)), p3 = s.positions.row(s.neighbors(v, 2));
  s.positions.row(s.neighbors(v, 1)) = (0.5 * (p1 + p3)).transpose();  // collinear neighbours
  msk::simplexReferenceParameters(s, eps, hr);
  EXPECT_EQ(hr[v], 0);
  EXPECT_NEAR(eps(v, 0), 1.0 / 3.0, 1e-15);
  EXPECT_TRUE(eps.allFinite() && hr.allFinite());
}
