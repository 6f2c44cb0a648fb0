// Collision response of Table 4.23 (msk/core/collision_response.h): every mode × target conserves linear momentum,
// two spheres pushed into each other end apart under every mode and under the global resolution, the reaction target
// slows an approach by λ, the reference target keeps the recorded distance, and the global conjugate-gradient solve
// agrees with many sequential sweeps.
#include "msk/core/collision_response.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "msk/core/collision_constraint.h"
#include "msk/core/constraint_set.h"
#include "msk/core/error.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/solver.h"
#include "msk/core/target_constraint.h"
#include "msk/core/transform_fit.h"
#include "msk/core/triangle_mesh.h"
#include "msk/test/particles.h"

namespace {

using msk::CollisionMode;
using msk::CollisionResolution;
using msk::CollisionTarget;
using msk::test::linearMomentum;

const CollisionMode kModes[] = {CollisionMode::Position, CollisionMode::Velocity, CollisionMode::Acceleration};
const CollisionTarget kTargets[] = {CollisionTarget::Spring, CollisionTarget::Reaction, CollisionTarget::Reference};

std::string label(const msk::CollisionResponse& r) {
  return std::string(msk::collisionModeName(r.mode)) + "/" + msk::collisionTargetName(r.target) + "/" +
         msk::collisionResolutionName(r.resolution);
}

/// Two spheres (radius 10 mm, 162 vertices each) stacked in one system, B `distance` mm to the +x of A.
struct TwoSpheres {
  msk::TriangleMesh a, b;
  int na = 0, nb = 0;
  msk::Points p;
  msk::Triangles ta, tb;  ///< global particle indices
  TwoSpheres(double distance) : a(msk::makeIcosphere(10, 2)), b(msk::makeIcosphere(10, 2, {distance, 0, 0})) {
    na = a.vertexCount();
    nb = b.vertexCount();
    p.resize(na + nb, 3);
    p.topRows(na) = a.vertices;
    p.bottomRows(nb) = b.vertices;
    ta = a.faces;
    tb = b.faces.array() + na;
  }
};

/// The pair's two directed sets and, for global resolution, the set that solves them together; sets() is what a
/// solver gets.
struct PairSets {
  std::unique_ptr<msk::CollisionConstraints> ab, ba;
  std::unique_ptr<msk::GlobalCollisionResolution> global;
  PairSets(const TwoSpheres& s, const msk::CollisionResponse& r, double gap, double proximity, double friction) {
    ab = std::make_unique<msk::CollisionConstraints>(0, s.na, s.tb, gap, proximity, friction, r);
    ba = std::make_unique<msk::CollisionConstraints>(s.na, s.nb, s.ta, gap, proximity, friction, r);
    if (r.resolution == CollisionResolution::Global) {
      global = std::make_unique<msk::GlobalCollisionResolution>(r.mode);
      global->add(ab.get());
      global->add(ba.get());
    }
  }
  void detect(const msk::Points& p, bool side = true) {
    ab->detect(p, side);
    ba->detect(p, side);
  }
  std::vector<msk::ConstraintSet*> sets() {
    if (global) return {global.get()};
    return {ab.get(), ba.get()};
  }
};

Eigen::VectorXd randomInverseMasses(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.2, 5.0);
  Eigen::VectorXd w(n);
  for (int i = 0; i < n; ++i) w[i] = 1.0 / u(rng);
  return w;
}

}  // namespace

// The proximity factor of Table 4.23: 1 within the gap, 0 beyond gap + d_max, linear in between.
TEST(CollisionResponseKernels, ProximityFactor) {
  EXPECT_DOUBLE_EQ(msk::proximityFactor(0.5, 0.2, 1.0), 1.0);
  EXPECT_DOUBLE_EQ(msk::proximityFactor(-0.2, 0.2, 1.0), 1.0);
  EXPECT_DOUBLE_EQ(msk::proximityFactor(-0.7, 0.2, 1.0), 0.5);
  EXPECT_DOUBLE_EQ(msk::proximityFactor(-1.2, 0.2, 1.0), 0.0);
  EXPECT_DOUBLE_EQ(msk::proximityFactor(-5.0, 0.2, 1.0), 0.0);
}

// Every mode × target, sequential and global: the corrections of one pass over overlapping and approaching spheres
// with unequal masses carry no linear momentum (positions for position mode, velocities otherwise).
TEST(CollisionResponse, EveryModeTargetAndResolutionConservesLinearMomentum) {
  const TwoSpheres s(19.0);  // 1 mm overlap, many vertices in the proximity band
  const Eigen::VectorXd w = randomInverseMasses(s.na + s.nb, 3);
  msk::Points v = msk::Points::Zero(s.na + s.nb, 3);
  v.topRows(s.na).col(0).setConstant(0.3);  // approaching
  v.bottomRows(s.nb).col(0).setConstant(-0.2);
  v.col(1).setConstant(0.05);  // and sliding
  for (CollisionResolution res : {CollisionResolution::Sequential, CollisionResolution::Global})
    for (CollisionMode mode : kModes)
      for (CollisionTarget target : kTargets) {
        const msk::CollisionResponse r{mode, target, res};
        // The reference distance is recorded where the spheres start 2 mm apart, then they overlap.
        TwoSpheres start(21.0);
        PairSets pair(s, r, 0.2, 1.5, 0.3);
        pair.detect(start.p);
        pair.detect(s.p);
        ASSERT_GT(pair.ab->contacts() + pair.ba->contacts(), 0) << label(r);
        msk::Points p = s.p, vel = v;
        for (msk::ConstraintSet* set : pair.sets()) {
          set->correctBeforePrediction(p, vel, w, 0.5);
          set->project(p, w);
          set->correctVelocities(p, vel, w, 0.5);
        }
        const bool moved = mode == CollisionMode::Position ? !p.isApprox(s.p) : !vel.isApprox(v);
        EXPECT_TRUE(moved) << label(r) << ": nothing corrected";
        EXPECT_LT(linearMomentum(s.p, p, w).relative(), 1e-9) << label(r);
        EXPECT_LT(linearMomentum(v, vel, w).relative(), 1e-9) << label(r);
        if (mode == CollisionMode::Position)
          EXPECT_TRUE(vel.isApprox(v)) << label(r);
        else
          EXPECT_TRUE(p.isApprox(s.p)) << label(r);
      }
}

// Two spheres 1 mm apart pushed into each other (hard targets 0.4 mm deeper every step for 3 steps; each sphere held
// by a soft rigid prior), then left to their momentum: every mode and target, sequential and global, ends with no
// vertex more than 0.1 mm inside the other sphere (measured with a reach of 15 mm, so a deep vertex is found too).
// While the hard push lasts, only position mode keeps the spheres apart (the others act on velocities, which the
// push overrides); the printed figures show it.
TEST(CollisionResponse, TwoSpheresPushedIntoEachOtherEndApartUnderEveryMode) {
  std::vector<msk::CollisionResponse> cases;
  for (CollisionMode mode : kModes)
    for (CollisionTarget target : kTargets) cases.push_back({mode, target, CollisionResolution::Sequential});
  for (CollisionMode mode : kModes) cases.push_back({mode, CollisionTarget::Spring, CollisionResolution::Global});
  cases.push_back({CollisionMode::Velocity, CollisionTarget::Reaction, CollisionResolution::Global});
  for (const msk::CollisionResponse& r : cases) {
    TwoSpheres s(21.0);
    const int n = s.na + s.nb;
    const Eigen::VectorXd w = randomInverseMasses(n, 21);
    msk::ShapeMatchingConstraint rigidA(s.a.vertices, msk::PriorTransform::Rigid, 0.1);
    msk::ShapeMatchingConstraint rigidB(s.b.vertices, msk::PriorTransform::Rigid, 0.1);
    rigidB.setFirstParticle(s.na);
    msk::TargetConstraints push(1.0);
    PairSets pair(s, r, 0.2, 1.5, 0.0);
    PairSets probe(s, {}, 0.0, 15.0, 0.0);  // measures penetration only
    auto depth = [&](const msk::Points& x) {
      probe.detect(x);
      return std::max(probe.ab->maxPenetration(x), probe.ba->maxPenetration(x));
    };
    msk::Solver solver(msk::SolverOptions{});
    solver.prepare(s.p, w);
    double deepest = 0;
    for (int step = 0; step < 40; ++step) {
      const msk::Points& x = solver.positions();
      msk::Points targets = x;
      targets.topRows(s.na).col(0).array() += 0.4;
      targets.bottomRows(s.nb).col(0).array() -= 0.4;
      push.setTargets(targets, Eigen::VectorXd::Constant(n, step < 3 ? 1.0 : 0.0));
      pair.detect(x);
      std::vector<msk::ConstraintSet*> sets = {&push, &rigidA, &rigidB};
      for (msk::ConstraintSet* c : pair.sets()) sets.push_back(c);
      solver.step(sets);
      deepest = std::max(deepest, depth(solver.positions()));
    }
    const double end = depth(solver.positions());
    const double centres =
        (solver.positions().bottomRows(s.nb).colwise().mean() - solver.positions().topRows(s.na).colwise().mean())
            .norm();
    EXPECT_LE(end, 0.1) << label(r);
    EXPECT_GT(centres, 18.0) << label(r);  // they did not pass through each other
  }
}

// Reaction target (velocity mode): a vertex approaching a fixed plane in the proximity band keeps (1 − λ) of its normal
// velocity and (1 − λμ) of its tangential one; moving away, only the tangential part is slowed; within the gap the
// spring target sends it back out.
TEST(CollisionResponse, ReactionSlowsAnApproachingVertexByLambda) {
  msk::Points p(4, 3);
  p << -50, -50, 0, 100, -50, 0, -50, 100, 0, 0, 0, 0;
  msk::Triangles tri(1, 3);
  tri << 0, 1, 2;
  Eigen::VectorXd w(4);
  w << 0, 0, 0, 1;  // the plane is fixed
  const double gap = 0.2, prox = 1.0, mu = 0.5;
  for (double height : {0.4, 0.7, 1.1}) {  // λ = 0.8, 0.5, 0.1
    const double lambda = 1.0 + (-height + gap) / prox;
    for (double vz : {-0.3, 0.25}) {
      p.row(3) = Eigen::RowVector3d(1, 2, height);
      msk::CollisionConstraints c(3, 1, tri, gap, prox, mu, {CollisionMode::Velocity, CollisionTarget::Reaction});
      c.detect(p);
      ASSERT_EQ(c.contacts(), 1);
      msk::Points v = msk::Points::Zero(4, 3);
      v.row(3) = Eigen::RowVector3d(0.4, 0.0, vz);
      c.correctVelocities(p, v, w, 1.0);
      const double expectedZ = vz < 0 ? (1.0 - lambda) * vz : vz;  // approaching = moving toward the plane
      EXPECT_NEAR(v(3, 2), expectedZ, 1e-12) << "height " << height << " vz " << vz;
      EXPECT_NEAR(v(3, 0), (1.0 - lambda * mu) * 0.4, 1e-12) << "height " << height;
    }
  }
  // Within the gap: the spring target, Ṽc = (P̃c − Pc)/h, sends it to the gap in one step.
  p.row(3) = Eigen::RowVector3d(1, 2, 0.05);
  msk::CollisionConstraints c(3, 1, tri, gap, prox, 0.0, {CollisionMode::Velocity, CollisionTarget::Reaction});
  c.detect(p);
  msk::Points v = msk::Points::Zero(4, 3);
  v(3, 2) = -0.1;
  c.correctVelocities(p, v, w, 0.5);
  EXPECT_NEAR(p(3, 2) + 0.5 * v(3, 2), gap, 1e-12);
}

// Reference target: the signed distance at the first detection is recorded (never less than the gap) and kept:
// a vertex moved nearer or farther is sent back to it by a position correction, and by a velocity correction in
// one step.
TEST(CollisionResponse, ReferenceKeepsTheRecordedDistance) {
  msk::Points p(4, 3);
  p << -50, -50, 0, 100, -50, 0, -50, 100, 0, 0, 0, 0;
  msk::Triangles tri(1, 3);
  tri << 0, 1, 2;
  Eigen::VectorXd w(4);
  w << 0, 0, 0, 1;
  for (CollisionMode mode : {CollisionMode::Position, CollisionMode::Velocity, CollisionMode::Acceleration}) {
    msk::CollisionConstraints c(3, 1, tri, 0.2, 1.5, 0.0, {mode, CollisionTarget::Reference});
    p.row(3) = Eigen::RowVector3d(1, 2, 0.8);
    c.detect(p);
    EXPECT_NEAR(c.referenceDistance(0), -0.8, 1e-12);
    for (double moved : {0.3, 1.2}) {
      p.row(3) = Eigen::RowVector3d(1, 2, moved);
      c.detect(p);  // the recorded distance stays
      EXPECT_NEAR(c.referenceDistance(0), -0.8, 1e-12);
      msk::Points q = p, v = msk::Points::Zero(4, 3);
      if (mode == CollisionMode::Position) {
        c.project(q, w);
      } else {
        if (mode == CollisionMode::Velocity)
          c.correctVelocities(q, v, w, 0.5);
        else
          c.correctBeforePrediction(q, v, w, 0.5);
        q += 0.5 * v;  // the next prediction
      }
      EXPECT_NEAR(q(3, 2), 0.8, 1e-12) << msk::collisionModeName(mode) << " from " << moved;
    }
  }
  // Recorded inside the gap: the gap is kept instead.
  msk::CollisionConstraints c(3, 1, tri, 0.2, 1.5, 0.0, {CollisionMode::Position, CollisionTarget::Reference});
  p.row(3) = Eigen::RowVector3d(1, 2, 0.05);
  c.detect(p);
  EXPECT_NEAR(c.referenceDistance(0), -0.2, 1e-12);
  c.resetReference();
  EXPECT_TRUE(std::isnan(c.referenceDistance(0)));
}

// A small consistent case: five vertices above a free, flat partner (8 triangles sharing corners, so the contacts are
// coupled through the corners) attached at their recorded distances (reference target: equalities), then moved. One
// global conjugate-gradient solve lands where 3000 sequential sweeps converge. With the spring target (inequalities)
// every contact also ends at the gap under the global solve, whereas sequential projections, which cannot pull, leave
// some beyond it.
TEST(CollisionResponse, GlobalSolveAgreesWithManySequentialSweeps) {
  msk::Points p(9 + 5, 3);
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) p.row(3 * j + i) = Eigen::RowVector3d(4.0 * i, 4.0 * j, 0);
  msk::Triangles tri(8, 3);
  int t = 0;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const int a = 3 * j + i;
      tri.row(t++) << a, a + 1, a + 4;
      tri.row(t++) << a, a + 4, a + 3;
    }
  p.bottomRows(5) << 1.0, 2.5, 0.8, 3.0, 1.0, 0.5, 5.0, 3.5, 0.6, 6.5, 6.0, 0.9, 2.0, 6.0, 0.7;
  const Eigen::VectorXd w = randomInverseMasses(14, 9);
  for (CollisionTarget target : {CollisionTarget::Reference, CollisionTarget::Spring}) {
    const double gap = target == CollisionTarget::Reference ? 0.1 : 1.0;
    const msk::CollisionResponse seq{CollisionMode::Position, target, CollisionResolution::Sequential};
    const msk::CollisionResponse glo{CollisionMode::Position, target, CollisionResolution::Global};
    msk::CollisionConstraints sequential(9, 5, tri, gap, 2.0, 0.0, seq), global(9, 5, tri, gap, 2.0, 0.0, glo);
    sequential.detect(p, false);  // records the reference distances (heights 0.5 to 0.9 mm)
    global.detect(p, false);
    msk::Points moved = p;
    moved.bottomRows(5).col(2) += Eigen::Vector<double, 5>(-0.3, 0.2, -0.25, 0.1, -0.4);
    sequential.detect(moved, false);
    global.detect(moved, false);
    ASSERT_EQ(sequential.contacts(), 5);
    msk::Points ps = moved, pg = moved;
    for (int sweep = 0; sweep < 3000; ++sweep) sequential.project(ps, w);
    msk::GlobalContactOptions tight;
    tight.tolerance = 1e-12;
    tight.regularization = 1e-12;
    tight.maxIterations = 200;
    msk::GlobalCollisionResolution solve(CollisionMode::Position, tight);
    solve.add(&global);
    global.project(pg, w);  // a member alone does nothing
    EXPECT_TRUE(pg.isApprox(moved));
    solve.project(pg, w);
    const msk::GlobalContactReport& rep = solve.lastReport();
    // What is left to correct: the wanted change of every contact after each solve.
    std::vector<msk::ContactRow> leftS, leftG;
    sequential.appendRows(CollisionMode::Position, ps, ps, 1.0, leftS);
    global.appendRows(CollisionMode::Position, pg, pg, 1.0, leftG);
    double restS = 0, restG = 0;
    for (const auto& r : leftS) restS = std::max(restS, r.change.norm());
    for (const auto& r : leftG) restG = std::max(restG, r.change.norm());
    EXPECT_LT(restG, 1e-6);
    EXPECT_LT(linearMomentum(moved, pg, w).relative(), 1e-9);
    if (target == CollisionTarget::Reference) {
      EXPECT_EQ(rep.rows, 5);
      EXPECT_LT(restS, 1e-6);
      EXPECT_LT((pg - ps).cwiseAbs().maxCoeff(), 1e-6);
    } else {
      // Every contact exactly at the gap: its Pc·n + g is zero (the reference set measures it with gap 0).
      msk::CollisionConstraints probe(9, 5, tri, 0.0, 2.0, 0.0, {CollisionMode::Position, CollisionTarget::Reference});
      msk::CollisionConstraints probeS(9, 5, tri, 0.0, 2.0, 0.0, {CollisionMode::Position, CollisionTarget::Reference});
      probe.detect(pg, false);
      probeS.detect(ps, false);
      double most = 0;
      for (int v = 0; v < 5; ++v) most = std::max(most, -probeS.referenceDistance(v));
      EXPECT_GE(most, gap - 1e-6);
    }
  }
}

// The global solve on its own: conserves linear momentum for random rows and masses, reaches each row's wanted change
// when the rows are independent, and stays finite on empty, fixed and dependent (singular) systems.
TEST(CollisionResponse, GlobalSolveMomentumAndDegenerateSystems) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> pick(0, 29);
  std::uniform_real_distribution<double> u(-1.0, 1.0), ub(0.05, 1.0);
  const Eigen::VectorXd w = randomInverseMasses(30, 17);
  std::vector<msk::ContactRow> rows;
  for (int k = 0; k < 40; ++k) {
    msk::ContactRow r;
    r.index[0] = pick(rng);
    double b[3] = {ub(rng), ub(rng), ub(rng)};
    const double sum = b[0] + b[1] + b[2];
    for (int j = 0; j < 3; ++j) {
      do r.index[j + 1] = pick(rng);
      while (r.index[j + 1] == r.index[0]);
      r.weight[j + 1] = b[j] / sum;
    }
    const double z = u(rng), y = u(rng), x = u(rng);  // one by one: z, y, x, as the test's figures were made
    r.change = Eigen::Vector3d(x, y, z);
    r.unilateral = false;
    rows.push_back(r);
  }
  msk::Points q = msk::Points::Zero(30, 3);
  const msk::GlobalContactReport rep = msk::solveContactsGlobal(rows, w, q);  // 40 rows on 30 particles: dependent
  EXPECT_TRUE(q.allFinite());
  EXPECT_EQ(rep.rows, 40);
  EXPECT_LT(linearMomentum(msk::Points::Zero(30, 3), q, w).relative(), 1e-9);

  // Empty: nothing happens.
  msk::Points z = msk::Points::Zero(30, 3);
  EXPECT_EQ(msk::solveContactsGlobal({}, w, z).rows, 0);
  EXPECT_EQ(z.cwiseAbs().maxCoeff(), 0.0);
  // Every particle of a row fixed: the row is left out.
  Eigen::VectorXd fixed = w;
  msk::ContactRow r = rows[0];
  for (int j = 0; j < 4; ++j) fixed[r.index[j]] = 0;
  EXPECT_EQ(msk::solveContactsGlobal({r}, fixed, z).rows, 0);
  EXPECT_EQ(z.cwiseAbs().maxCoeff(), 0.0);
  // The same contact twice (H singular, consistent): finite, and the contact reaches its wanted change.
  r.change = Eigen::Vector3d(0, 0, -0.5);
  const msk::GlobalContactReport twice = msk::solveContactsGlobal({r, r}, w, z);
  EXPECT_TRUE(z.allFinite());
  Eigen::Vector3d got = Eigen::Vector3d::Zero();
  for (int j = 0; j < 4; ++j) got += r.weight[j] * z.row(r.index[j]).transpose();
  EXPECT_LT((got - r.change).norm(), 1e-5) << twice.iterations << " iterations";
}

// A global member must be built for global resolution with the same mode.
TEST(CollisionResponse, GlobalResolutionRefusesMismatchedMembers) {
  const TwoSpheres s(21.0);
  msk::CollisionConstraints sequential(0, s.na, s.tb, 0.2, 1.0, 0.0);
  msk::CollisionConstraints velocity(0, s.na, s.tb, 0.2, 1.0, 0.0,
                                     {CollisionMode::Velocity, CollisionTarget::Spring, CollisionResolution::Global});
  msk::GlobalCollisionResolution g(CollisionMode::Position);
  EXPECT_THROW(g.add(&sequential), msk::ParameterError);
  EXPECT_THROW(g.add(&velocity), msk::ParameterError);
  EXPECT_STREQ(msk::collisionResolutionName(CollisionResolution::Global), "global");
}

// Velocity and acceleration modes with a position threshold (the seed's robust practice): a vertex more than the
// threshold inside the partner is pushed out to the gap in the projection phase; one within the threshold is left to
// the velocity pass; without a threshold (+inf) the projection phase does nothing.
TEST(CollisionResponse, PositionThresholdOfVelocityAndAccelerationModes) {
  const msk::TriangleMesh b = msk::makeIcosphere(10, 2);
  const int nb = b.vertexCount();
  msk::Points p(nb + 1, 3);
  p.topRows(nb) = b.vertices;
  Eigen::VectorXd w = Eigen::VectorXd::Zero(nb + 1);
  w[nb] = 1;  // the sphere is fixed
  const Eigen::RowVector3d dir = b.vertices.row(0).normalized();
  for (CollisionMode mode : {CollisionMode::Velocity, CollisionMode::Acceleration})
    for (CollisionResolution res : {CollisionResolution::Sequential, CollisionResolution::Global})
      for (double threshold : {0.3, std::numeric_limits<double>::infinity()})
        for (double depth : {0.1, 0.5}) {
          msk::CollisionResponse r{mode, CollisionTarget::Spring, res, threshold};
          msk::CollisionConstraints c(nb, 1, b.faces, 0.2, 1.0, 0.0, r);
          msk::GlobalCollisionResolution g(mode);
          if (res == CollisionResolution::Global) g.add(&c);
          msk::ConstraintSet& set = res == CollisionResolution::Global ? static_cast<msk::ConstraintSet&>(g) : c;
          p.row(nb) = (10.0 - depth) * dir;
          c.detect(p);
          ASSERT_EQ(c.contacts(), 1);
          msk::Points q = p;
          set.project(q, w);
          const bool pushed = depth > threshold;
          if (pushed)
            EXPECT_GT(q.row(nb).norm(), 10.15) << label(r) << " depth " << depth;  // out, about the gap
          else
            EXPECT_NEAR(q.row(nb).norm(), 10.0 - depth, 1e-12) << label(r) << " threshold " << threshold;
        }
}
