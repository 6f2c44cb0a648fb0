#include "msk/core/collision_constraint.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/target_constraint.h"

#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "msk/core/error.h"
#include "msk/core/transform_fit.h"

namespace {
Eigen::Vector3d randomVec(std::mt19937& rng, double s = 1.0) {
  std::uniform_real_distribution<double> u(-s, s);
  return {u(rng), u(rng), u(rng)};
}
}  // namespace

// Internal-constraint corrections of method 2 carry no linear and no angular momentum (DESIGN-NOTES §2).
TEST(SimplexInternalKernel, ConservesLinearAndAngularMomentum) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> um(0.2, 5.0);
  int method2 = 0;
  for (int t = 0; t < 2000; ++t) {
    Eigen::Vector3d pi[3] = {Eigen::Vector3d(10, 0, 0) + randomVec(rng, 2), Eigen::Vector3d(-5, 8.7, 0) + randomVec(rng, 2),
                             Eigen::Vector3d(-5, -8.7, 0) + randomVec(rng, 2)};
    const Eigen::Vector3d p = Eigen::Vector3d(0, 0, 3) + randomVec(rng, 2);
    const double eps[3] = {0.3, 0.3, 0.4};
    const Eigen::Vector3d target = eps[0] * pi[0] + eps[1] * pi[1] + eps[2] * pi[2] + Eigen::Vector3d(0, 0, 2) +
                                   randomVec(rng, 0.5);
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

TEST(TargetKernel, MovesFreeParticlesOnly) {
  Eigen::Vector3d dp;
  ASSERT_TRUE(msk::targetCorrection({0, 0, 0}, {2, 0, 0}, 1.0, 0.25, dp));
  EXPECT_NEAR(dp.x(), 0.5, 1e-15);
  EXPECT_FALSE(msk::targetCorrection({0, 0, 0}, {2, 0, 0}, 0.0, 0.25, dp));
}

TEST(FitTransform, RecoversRigidSimilarityAndAffine) {
  std::mt19937 rng(3);
  msk::Points from(50, 3);
  for (int i = 0; i < 50; ++i) from.row(i) = randomVec(rng, 20).transpose();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(5, -3, 2);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(50);
  for (auto [kind, m] : {std::pair{msk::PriorTransform::Rigid, Eigen::Matrix3d(r)},
                         std::pair{msk::PriorTransform::Similarity, Eigen::Matrix3d(1.07 * r)},
                         std::pair{msk::PriorTransform::Affine, Eigen::Matrix3d(r * Eigen::Vector3d(1.1, 0.9, 1.2).asDiagonal())}}) {
    msk::Points to = (from * m.transpose()).rowwise() + t.transpose();
    const Eigen::Matrix4d fit = msk::fitTransform(from, to, w, kind);
    EXPECT_LT((fit.topLeftCorner<3, 3>() - m).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((fit.topRightCorner<3, 1>() - t).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(ShapeMatching, PullsTowardTheFittedReferenceWithoutNetMomentum) {
  std::mt19937 rng(5);
  msk::Points ref(40, 3);
  for (int i = 0; i < 40; ++i) ref.row(i) = randomVec(rng, 10).transpose();
  msk::Points p = ref;
  p.col(0) *= 1.3;  // a non-rigid stretch
  p.rowwise() += Eigen::RowVector3d(3, 4, 5);
  const msk::Points before = p;
  msk::ShapeMatchingConstraint c(ref, msk::PriorTransform::Rigid, 0.5);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(40);
  c.project(p, w);
  EXPECT_LT((p - before).colwise().sum().norm(), 1e-9);  // linear momentum
  // Projecting to λ = 1 gives a rigid copy of the reference.
  c.setLambda(1.0);
  c.project(p, w);
  for (int i = 0; i < 40; ++i)
    for (int j = i + 1; j < 40; j += 7)
      EXPECT_NEAR((p.row(i) - p.row(j)).norm(), (ref.row(i) - ref.row(j)).norm(), 1e-9);
  EXPECT_THROW(c.setLambda(1.5), msk::ParameterError);
  EXPECT_THROW(msk::TargetConstraints(-0.1), msk::ParameterError);
}

// Collision position correction (Table 4.23, spring): reaches the gap, conserves linear momentum.
TEST(CollisionKernel, PushesOutToTheGapAndConservesLinearMomentum) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> um(0.2, 5.0), ub(0.05, 1.0);
  for (int t = 0; t < 500; ++t) {
    const Eigen::Vector3d pi[3] = {Eigen::Vector3d(0, 0, 0) + randomVec(rng, 0.3), Eigen::Vector3d(4, 0, 0) + randomVec(rng, 0.3),
                                   Eigen::Vector3d(0, 4, 0) + randomVec(rng, 0.3)};
    double b[3] = {ub(rng), ub(rng), ub(rng)};
    const double sum = b[0] + b[1] + b[2];
    for (double& x : b) x /= sum;
    const Eigen::Vector3d n = (pi[1] - pi[0]).cross(pi[2] - pi[0]).normalized();
    const Eigen::Vector3d pbar = b[0] * pi[0] + b[1] * pi[1] + b[2] * pi[2];
    const Eigen::Vector3d p = pbar - 0.7 * n + randomVec(rng, 0.2);  // 0.7 mm inside the partner
    const double w = 1.0 / um(rng), wi[3] = {1.0 / um(rng), 1.0 / um(rng), 1.0 / um(rng)};
    Eigen::Vector3d dp, dpi[3];
    ASSERT_TRUE(msk::collisionCorrection(p, pi, b, n, 0.5, 0.0, w, wi, dp, dpi));
    const Eigen::Vector3d lin = dp / w + dpi[0] / wi[0] + dpi[1] / wi[1] + dpi[2] / wi[2];
    EXPECT_LT(lin.norm(), 1e-9 * (1 + dp.norm() / w));
    // After the correction (same normal, linearised), P sits exactly `gap` outside along n.
    const Eigen::Vector3d newBar = b[0] * (pi[0] + dpi[0]) + b[1] * (pi[1] + dpi[1]) + b[2] * (pi[2] + dpi[2]);
    EXPECT_NEAR(((p + dp) - newBar).dot(n), 0.5, 1e-9);
  }
  // Already outside by more than the gap: nothing.
  const Eigen::Vector3d pi[3] = {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}};
  const double b[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3}, wi[3] = {1, 1, 1};
  Eigen::Vector3d dp, dpi[3];
  EXPECT_FALSE(msk::collisionCorrection(Eigen::Vector3d(1, 1, 2), pi, b, Eigen::Vector3d::UnitZ(), 0.5, 0.0, 1, wi, dp, dpi));
}

// Two overlapping spheres stacked in one particle system separate under the collision sets of both directions.
TEST(CollisionConstraints, OverlappingSpheresSeparate) {
  const msk::TriangleMesh a = msk::makeIcosphere(10, 3, {0, 0, 0}), b = msk::makeIcosphere(10, 3, {18, 0, 0});
  const int na = a.vertexCount(), nb = b.vertexCount();
  msk::Points p(na + nb, 3);
  p.topRows(na) = a.vertices;
  p.bottomRows(nb) = b.vertices;
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(na + nb);
  msk::Triangles ta = a.faces, tb = b.faces.array() + na;
  msk::CollisionConstraints ab(0, na, tb, 0.0, 3.0, 0.0), ba(na, nb, ta, 0.0, 3.0, 0.0);
  const Eigen::RowVector3d momentumBefore = p.colwise().sum();
  for (int it = 0; it < 30; ++it) {
    ab.detect(p);
    ba.detect(p);
    ab.project(p, w);
    ba.project(p, w);
  }
  ab.detect(p);
  ba.detect(p);
  EXPECT_LT(ab.maxPenetration(p), 0.1);
  EXPECT_LT(ba.maxPenetration(p), 0.1);
  EXPECT_LT((p.colwise().sum() - momentumBefore).norm(), 1e-8 * p.rows());
  EXPECT_THROW(msk::CollisionConstraints(0, na, tb, -1.0, 3.0, 0.0), msk::ParameterError);
}

// Without the inside test a vertex is taken to be outside the partner: a contact can keep it `gap` away but never
// pushes it through the surface; with the test, a vertex inside is pushed out along the partner's outward normal.
TEST(CollisionConstraints, InsideTestDecidesTheSideAndTheOutsideAssumptionNeverPushesThrough) {
  const msk::TriangleMesh b = msk::makeIcosphere(10, 3);
  const int nb = b.vertexCount();
  for (const double start : {9.5, 10.1}) {  // 0.5 mm inside, 0.1 mm outside (within the 0.2 mm gap)
    for (const bool insideTest : {true, false}) {
      msk::Points p(nb + 1, 3);
      p.topRows(nb) = b.vertices;
      p.row(nb) = Eigen::RowVector3d(start, 0.01, 0.02);
      msk::Triangles tb = b.faces;
      msk::CollisionConstraints c(nb, 1, tb, 0.2, 1.0, 0.0);
      const Eigen::VectorXd w = Eigen::VectorXd::Ones(nb + 1);
      const double r0 = p.row(nb).norm();
      c.detect(p, insideTest);
      ASSERT_EQ(c.contacts(), 1);
      c.project(p, w);
      const double r = p.row(nb).norm();
      if (start > 10 || insideTest) {
        EXPECT_GT(r, r0 + 0.02) << "start " << start << " insideTest " << insideTest;  // moved outward
      } else {
        EXPECT_LE(r, r0 + 1e-12) << "an assumed-outside vertex is pushed away from the surface it faces, inward";
        EXPECT_GT(r, 9.5 - 0.25);  // ... by at most the gap: never through
      }
    }
  }
}

// The reference parameters rebuild every vertex of a simplex sphere from its neighbours, P = Σ ε̃i Pi + h̃ r⊥ n (so
// the shape memory's target of the template is the template), with ε̃ near ⅓ on the nearly regular mesh and h̃ > 0
// (convex); collinear neighbours give ε̃ = ⅓ and h̃ = 0.
TEST(SimplexReferenceParameters, RebuildEveryVertexOfASphereFromItsNeighbours) {
  msk::SimplexMesh s = msk::simplexFromTriangles(msk::makeIcosphere(15.0, 3, Eigen::Vector3d(1, -2, 3)));
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
