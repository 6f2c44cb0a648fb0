// Evolution schemes over one constraint set (solver.h): agreement, momentum, iteration independence of XPBD,
// determinism with threads, and stability at the extremes of stiffness, time step and mass.
#include "msk/core/solver.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "msk/core/collision_constraint.h"
#include "msk/core/constraint_set.h"
#include "msk/core/error.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/target_constraint.h"
#include "msk/core/volume_simplex.h"
#include "msk/test/particles.h"
#include "msk/test/shapes.h"
#include "msk/test/solver_scenarios.h"

namespace {

using msk::Points;
using msk::Scheme;
using msk::SolverOptions;
using msk::test::bitwiseEqual;
using msk::test::runSphereProblem;
using msk::test::SphereProblem;
using msk::test::sphereProblem;
using msk::test::SphereRun;

SolverOptions optionsFor(Scheme scheme) { return msk::test::sphereProblemOptions(scheme); }

}  // namespace

TEST(SolverOptions, NamesParseAndBadValuesThrow) {
  for (Scheme s : msk::allSchemes()) EXPECT_EQ(msk::parseScheme(msk::schemeName(s)), s);
  EXPECT_EQ(msk::parseScheme("colored-gauss-seidel"), Scheme::ColouredGaussSeidel);
  EXPECT_THROW(msk::parseScheme("verlet"), msk::ParameterError);
  auto bad = [](auto change) {
    SolverOptions o;
    change(o);
    EXPECT_THROW(msk::Solver{o}, msk::ParameterError);
  };
  bad([](SolverOptions& o) { o.stiffness = -1; });
  bad([](SolverOptions& o) { o.stiffness = std::nan(""); });
  bad([](SolverOptions& o) { o.dt = 0; });
  bad([](SolverOptions& o) { o.dt = -1e-3; });
  bad([](SolverOptions& o) { o.substeps = 0; });
  bad([](SolverOptions& o) { o.iterations = 0; });
  bad([](SolverOptions& o) { o.omega = 0; });
  bad([](SolverOptions& o) { o.omega = 2; });
  bad([](SolverOptions& o) { o.damping = 1.5; });
  bad([](SolverOptions& o) { o.forceDamping = -0.1; });
  bad([](SolverOptions& o) { o.anisotropy = -0.1; });
  bad([](SolverOptions& o) { o.cgTolerance = 0; });
  bad([](SolverOptions& o) { o.threads = -1; });
  SolverOptions inf;
  inf.stiffness = std::numeric_limits<double>::infinity();  // hard constraints: allowed
  EXPECT_NO_THROW(msk::Solver{inf});
  // Negative set stiffness is refused where the sets are built.
  EXPECT_THROW(msk::TargetConstraints(-1e-12), msk::ParameterError);
}

// Sequential Gauss–Seidel is every set's project() in order, `iterations` times per step: from rest, one step lands
// where three sweeps by hand do, bit for bit.
TEST(SolverSchemes, GaussSeidelStepIsTheSetsProjectionsInOrder) {
  const SphereProblem s = sphereProblem(2);
  SolverOptions o;
  o.iterations = 3;
  msk::Solver solver(o);
  solver.prepare(s.x0, s.w);
  solver.step(s.sets());
  msk::Points p = s.x0;
  for (int it = 0; it < 3; ++it)
    for (msk::ConstraintSet* c : s.sets()) c->project(p, s.w);
  EXPECT_TRUE(bitwiseEqual(solver.positions(), p));
  EXPECT_EQ(solver.steps(), 1);
  EXPECT_GT(solver.secondsPerFamily().count("simplex-internal"), 0u);
}

// Every scheme reaches the unique answer of a consistent problem (the sphere scaled by 1.2 satisfies the shape memory,
// the targets and the similarity prior), to 0.01 mm on a 12 mm sphere.
TEST(SolverSchemes, EverySchemeConvergesToTheSameAnswer) {
  const SphereProblem s = sphereProblem(2);
  for (Scheme scheme : msk::allSchemes()) {
    const SphereRun r = runSphereProblem(optionsFor(scheme), s, 3000, 1e-7, &s.expected);
    EXPECT_TRUE(r.converged) << msk::schemeName(scheme) << " last move " << r.lastMove;
    EXPECT_LT(r.error, 0.01) << msk::schemeName(scheme);
  }
}

// Internal (2-simplex method 2) and collision corrections carry no linear momentum under every position-based
// scheme: two overlapping, perturbed spheres with random masses, one step without drag.
TEST(SolverSchemes, InternalAndCollisionCorrectionsConserveLinearMomentum) {
  const msk::SimplexMesh a = msk::test::simplexSphere(10.0), b = msk::test::simplexSphere(10.0, 2, {16, 0, 0});
  const int na = a.vertexCount(), nb = b.vertexCount();
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> jitter(-0.6, 0.6), mass(0.5, 2.0);
  Points x(na + nb, 3);
  x.topRows(na) = a.positions;
  x.bottomRows(nb) = b.positions;
  for (int i = 0; i < x.rows(); ++i)
    for (int d = 0; d < 3; ++d) x(i, d) += jitter(rng);
  Eigen::VectorXd w(na + nb);
  for (int i = 0; i < w.size(); ++i) w[i] = 1.0 / mass(rng);
  msk::SimplexInternalConstraints ia(a, 0.9), ib(b, 0.9);
  ib.setFirstParticle(na);
  msk::Triangles ta = msk::simplexFanTriangles(a), tb = msk::simplexFanTriangles(b);
  tb.array() += na;
  msk::CollisionConstraints cab(0, na, tb, 0.2, 1.0, 0.0), cba(na, nb, ta, 0.2, 1.0, 0.0);
  for (int variant = 0; variant < 5; ++variant) {
    const Scheme scheme = variant == 4 ? Scheme::Jacobi : msk::allSchemes()[static_cast<size_t>(variant)];
    SolverOptions o = optionsFor(scheme);
    if (variant == 4) o.rowless = msk::RowlessSets::Blend;  // collisions averaged with the rows
    o.drag = 0;
    o.damping = 0.5;  // rigid-motion damping keeps momentum too
    o.substeps = 2;
    o.stiffness = 10;
    msk::Solver solver(o);
    solver.prepare(x, w);
    cab.detect(x);
    cba.detect(x);
    ASSERT_GT(cab.contacts() + cba.contacts(), 20);
    solver.step({&ia, &ib, &cab, &cba});
    const Points& v = solver.velocities();
    Eigen::RowVector3d momentum = Eigen::RowVector3d::Zero();
    double scale = 0;
    for (int i = 0; i < v.rows(); ++i) {
      momentum += v.row(i) / w[i];
      scale += v.row(i).norm() / w[i];
    }
    ASSERT_GT(scale, 1.0) << msk::schemeName(scheme);
    EXPECT_LT(momentum.norm(), 1e-9 * scale) << msk::schemeName(scheme) << " relative " << momentum.norm() / scale;
  }
}

// XPBD: the stiffness, not the iteration count, sets the compromise between competing constraints (targets at 1.2×
// on one half of the sphere against the shape memory): the state after 100 steps is within 2 % of the displacement
// for 5 to 80 iterations per step.
TEST(SolverSchemes, XpbdWithinTwoPercentFrom5To80Iterations) {
  const std::vector<int> counts = {5, 10, 20, 40, 80};
  for (Scheme scheme : {Scheme::Xpbd, Scheme::GaussSeidel}) {
    double moved = 0;
    const std::vector<double> dev = msk::test::iterationDeviations(scheme, counts, moved);
    ASSERT_EQ(dev.size(), counts.size()) << msk::schemeName(scheme) << ": a result is not finite";
    ASSERT_GT(moved, 0.5);
    if (scheme != Scheme::Xpbd) continue;
    for (size_t i = 0; i < counts.size(); ++i) EXPECT_LT(dev[i], 0.02) << counts[i] << " iterations";
  }
}

// Coloured Gauss–Seidel, Jacobi and the conjugate-gradient solve give bitwise-identical results on rerun with 2
// threads, and the same bits as with 1 thread (the colouring, not the threads, fixes the order of every sum).
TEST(SolverSchemes, ParallelSchemesAreDeterministic) {
  const SphereProblem s = sphereProblem(4);  // 5120 rows: several hundred per colour, so the threads share the work
  for (Scheme scheme : {Scheme::ColouredGaussSeidel, Scheme::Jacobi, Scheme::Xpbd, Scheme::Implicit}) {
    std::vector<Points> out;
    for (int threads : {2, 2, 1}) {
      SolverOptions o = optionsFor(scheme);
      o.threads = threads;
      o.iterations = 2;
      msk::Solver solver(o);
      solver.prepare(s.x0, s.w);
      for (int i = 0; i < 4; ++i) solver.step(s.sets());
      out.push_back(solver.positions());
    }
    EXPECT_TRUE(bitwiseEqual(out[0], out[1])) << msk::schemeName(scheme) << ": 2 threads differ on rerun";
    EXPECT_TRUE(bitwiseEqual(out[0], out[2])) << msk::schemeName(scheme) << ": 1 and 2 threads differ";
    EXPECT_GT((out[0] - s.x0).norm(), 0.1);
  }
}

// XPBD stiffness from 0 to hard: k = 0 moves nothing, tiny k barely moves, k = 1e12 and +inf act as hard constraints.
TEST(SolverExtremes, XpbdStiffness) {
  const SphereProblem s = sphereProblem(2);
  for (double k : {0.0, 1e-12, 1.0, 1e12, std::numeric_limits<double>::infinity()}) {
    SolverOptions o = optionsFor(Scheme::Xpbd);
    o.stiffness = k;
    const SphereRun r = runSphereProblem(o, s, 800, 1e-7, &s.expected);
    ASSERT_TRUE(r.x.allFinite()) << "k " << k;
    const double moved = (r.x - s.x0).rowwise().norm().maxCoeff();
    EXPECT_LT(moved, 2.5) << "k " << k;  // targets are 2 mm away
    if (k == 0) {
      EXPECT_EQ(moved, 0.0);
    } else if (k == 1e-12) {
      EXPECT_LT(moved, 1e-6);
    } else if (k >= 1.0) {
      EXPECT_LT(r.error, 0.01) << "k " << k;
    }
  }
}

// dt from 1e-6 to 10: the position-based and force-based schemes (α = γ m̄ dt⁻²) give the same answer at any dt;
// XPBD (absolute stiffness) stays bounded.
TEST(SolverExtremes, TimeStep) {
  const SphereProblem s = sphereProblem(1);
  for (Scheme scheme : msk::allSchemes()) {
    for (double dt : {1e-6, 1e-3, 1.0, 10.0}) {
      SolverOptions o = optionsFor(scheme);
      o.dt = dt;
      const SphereRun r = runSphereProblem(o, s, 3000, 1e-7, &s.expected);
      ASSERT_TRUE(r.x.allFinite()) << msk::schemeName(scheme) << " dt " << dt;
      EXPECT_LT((r.x - s.x0).rowwise().norm().maxCoeff(), 2.5) << msk::schemeName(scheme) << " dt " << dt;
      if (scheme != Scheme::Xpbd) {
        EXPECT_LT(r.error, 0.01) << msk::schemeName(scheme) << " dt " << dt;
      }
    }
  }
}

// Masses from 1e-9 to 1e9 in one system, plus fixed particles: no NaN or Inf, displacement bounded, and the run
// either converges or stops with msk::Error.
TEST(SolverExtremes, MassesAndFixedParticles) {
  const SphereProblem s = sphereProblem(1);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> exponent(-9, 9);
  Eigen::VectorXd w(s.w.size());
  for (int i = 0; i < w.size(); ++i) w[i] = i % 7 == 3 ? 0.0 : std::pow(10.0, exponent(rng));
  for (Scheme scheme : msk::allSchemes()) {
    SolverOptions o = optionsFor(scheme);
    msk::Solver solver(o);
    solver.prepare(s.x0, w);
    try {
      double move = 1;
      for (int i = 0; i < 3000 && move > 1e-7; ++i) move = solver.step(s.sets());
      EXPECT_LT(move, 1e-3) << msk::schemeName(scheme) << " still moving";
    } catch (const msk::Error& e) {
      ADD_FAILURE() << msk::schemeName(scheme) << ": " << e.what();
    }
    const Points& x = solver.positions();
    ASSERT_TRUE(x.allFinite()) << msk::schemeName(scheme);
    // Bounded: the compromise of fixed vertices, 1e-9..1e9 masses and the targets distorts the 80-vertex sphere
    // (radius 10, targets at 12) to radii 3.4–15 mm, alike under every scheme, but nothing leaves its neighbourhood.
    EXPECT_LT(x.rowwise().norm().maxCoeff(), 20.0) << msk::schemeName(scheme);
    EXPECT_LT((x - s.x0).rowwise().norm().maxCoeff(), 26.0) << msk::schemeName(scheme);
    for (int i = 0; i < w.size(); ++i)
      if (w[i] == 0) {
        EXPECT_EQ((x.row(i) - s.x0.row(i)).norm(), 0.0) << msk::schemeName(scheme) << " fixed " << i;
      }
  }
  // Every particle fixed: nothing moves, nothing fails.
  for (Scheme scheme : msk::allSchemes()) {
    msk::Solver solver(optionsFor(scheme));
    solver.prepare(s.x0, Eigen::VectorXd::Zero(s.w.size()));
    EXPECT_EQ(solver.step(s.sets()), 0.0) << msk::schemeName(scheme);
  }
}

// A non-finite position produced by a set is reported as msk::Error and never kept.
TEST(SolverExtremes, NonFiniteResultIsReportedAndNotKept) {
  struct Poison : msk::ConstraintSet {
    std::string name() const override { return "poison"; }
    void project(Points& p, const Eigen::VectorXd&) override { p(0, 0) = std::nan(""); }
  } poison;
  const SphereProblem s = sphereProblem(1);
  for (Scheme scheme : msk::allSchemes()) {
    for (msk::RowlessSets mode : {msk::RowlessSets::Project, msk::RowlessSets::Blend}) {
      SolverOptions o = optionsFor(scheme);
      o.rowless = mode;
      msk::Solver solver(o);
      solver.prepare(s.x0, s.w);
      EXPECT_THROW(solver.step({s.internal.get(), &poison}), msk::Error) << msk::schemeName(scheme);
      EXPECT_TRUE(solver.positions().allFinite()) << msk::schemeName(scheme);
    }
  }
}

// A jittered volume model with its ghosts fixed returns to rest under every scheme (the unique answer).
TEST(SolverSchemes, VolumeModelReturnsToRestUnderEveryScheme) {
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(msk::makeCubeTets(2, 5.0));
  const int n = vm.vertexCount();
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> jitter(-0.8, 0.8);
  Points x0 = vm.simplex.positions;
  for (int i = 0; i < vm.tetCount(); ++i)
    for (int d = 0; d < 3; ++d) x0(i, d) += jitter(rng);
  Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  w.tail(vm.ghostCount()).setZero();
  msk::VolumeSimplexConstraints vol(vm, 1.0);
  for (Scheme scheme : msk::allSchemes()) {
    msk::Solver solver(optionsFor(scheme));
    solver.prepare(x0, w);
    double move = 1;
    for (int i = 0; i < 3000 && move > 1e-8; ++i) move = solver.step({&vol});
    const double err = (solver.positions() - vm.simplex.positions).rowwise().norm().maxCoeff();
    EXPECT_LT(err, 1e-4) << msk::schemeName(scheme);
  }
}

// XPBD with mass-relative stiffness k = 1 has the stiffness of the force-based schemes (α = γ m̄ dt⁻²), so its steady
// state under competing constraints is the implicit scheme's equilibrium; and it does not change with the mass scale.
TEST(SolverSchemes, MassRelativeXpbdSharesTheForceBasedEquilibrium) {
  const msk::test::MassRelativeXpbd f = msk::test::massRelativeXpbdAgainstImplicit();
  ASSERT_GT(f.movedMm, 0.5);
  EXPECT_LT(f.deviation, 0.02);
  EXPECT_LT(f.heavierMm, 1e-6 * f.movedMm);
}
