#include "msk/test/solver_scenarios.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>

#include "msk/core/collision_constraint.h"
#include "msk/test/shapes.h"

namespace msk::test {

SphereProblem sphereProblem(int subdivisions, bool consistent, double priorWeight) {
  SphereProblem s;
  s.mesh = simplexSphere(10.0, subdivisions);
  s.x0 = s.mesh.positions;
  const int n = s.mesh.vertexCount();
  s.w = Eigen::VectorXd::Ones(n);
  s.expected = 1.2 * s.x0;
  Points t = s.expected;
  if (!consistent)
    for (int i = 0; i < n; ++i)
      if (s.x0(i, 0) <= 0) t.row(i) = s.x0.row(i);
  Eigen::VectorXd weights(n);
  for (int i = 0; i < n; ++i) weights[i] = i % 2 == 0 ? 1.0 : 0.0;
  s.internal = std::make_unique<SimplexInternalConstraints>(s.mesh, 0.8);
  s.targets = std::make_unique<TargetConstraints>(0.5);
  s.targets->setTargets(t, weights);
  s.prior = std::make_unique<ShapeMatchingConstraint>(s.x0, PriorTransform::Similarity, priorWeight);
  return s;
}

SolverOptions sphereProblemOptions(Scheme scheme) {
  SolverOptions o;
  o.scheme = scheme;
  o.iterations = 4;
  switch (scheme) {
    case Scheme::Jacobi:
      o.omega = 1.5;
      break;
    case Scheme::Xpbd:
      o.stiffness = 1e6;
      break;
    case Scheme::Explicit:
      o.substeps = 4;
      break;
    default:
      break;
  }
  return o;
}

SphereRun runSphereProblem(const SolverOptions& o, const SphereProblem& s, int maxSteps, double tolMm,
                           const Points* expected) {
  SphereRun r;
  Solver solver(o);
  solver.prepare(s.x0, s.w);
  while (r.steps < maxSteps) {
    r.lastMove = solver.step(s.sets());
    ++r.steps;
    if (r.lastMove < tolMm) {
      r.converged = true;
      break;
    }
  }
  r.x = solver.positions();
  if (expected) r.error = (r.x - *expected).rowwise().norm().maxCoeff();
  return r;
}

std::vector<double> iterationDeviations(Scheme scheme, const std::vector<int>& iterations, double& movedMm) {
  const SphereProblem s = sphereProblem(2, false, 0.0);
  const std::vector<ConstraintSet*> sets = {s.internal.get(), s.targets.get()};
  std::vector<Points> results;
  for (int count : iterations) {
    SolverOptions o = sphereProblemOptions(scheme);
    o.iterations = count;
    o.stiffness = 1.0;
    Solver solver(o);
    solver.prepare(s.x0, s.w);
    for (int i = 0; i < 100; ++i) solver.step(sets);
    if (!solver.positions().allFinite()) return {};
    results.push_back(solver.positions());
  }
  const Points& ref = results.back();
  movedMm = (ref - s.x0).rowwise().norm().maxCoeff();
  std::vector<double> dev;
  for (const Points& x : results) dev.push_back((x - ref).rowwise().norm().maxCoeff() / movedMm);
  return dev;
}

MassRelativeXpbd massRelativeXpbdAgainstImplicit() {
  const SphereProblem s = sphereProblem(1, false, 0.0);
  const std::vector<ConstraintSet*> sets = {s.internal.get(), s.targets.get()};
  auto steady = [&](const SolverOptions& o, double massScale) {
    Solver solver(o);
    solver.prepare(s.x0, s.w / massScale);
    for (int i = 0; i < 600; ++i) solver.step(sets);
    return Points(solver.positions());
  };
  SolverOptions x = sphereProblemOptions(Scheme::Xpbd);
  x.xpbdStiffness = XpbdStiffness::MassRelative;
  x.stiffness = 1.0;
  x.iterations = 20;
  const Points xp = steady(x, 1.0), xpHeavy = steady(x, 1e6);
  const Points im = steady(sphereProblemOptions(Scheme::Implicit), 1.0);
  MassRelativeXpbd f;
  f.movedMm = (im - s.x0).rowwise().norm().maxCoeff();
  f.deviation = (xp - im).rowwise().norm().maxCoeff() / f.movedMm;
  f.heavierMm = (xp - xpHeavy).rowwise().norm().maxCoeff();
  return f;
}

namespace {
/// Angular momentum Σ m x × v about the origin and its scale Σ m |x| |v| (particles with w > 0).
void angularMomentum(const Points& x, const Points& v, const Eigen::VectorXd& w, Eigen::Vector3d& l, double& scale) {
  l.setZero();
  scale = 0;
  for (Eigen::Index i = 0; i < w.size(); ++i) {
    if (w[i] <= 0) continue;
    const Eigen::Vector3d xi = x.row(i).transpose(), vi = v.row(i).transpose();
    l += xi.cross(vi) / w[i];
    scale += xi.norm() * vi.norm() / w[i];
  }
}
}  // namespace

MomentumDrift momentumDrift(bool collide) {
  const SimplexMesh a = simplexSphere(10.0, 2), b = simplexSphere(10.0, 2, Eigen::Vector3d(18.5, 0, 0));
  const int na = a.vertexCount();
  Points p(2 * na, 3);
  p << perturbed(a.positions, 0.3, 3), perturbed(b.positions, 0.3, 4);
  const Eigen::RowVector3d center = p.colwise().mean();
  p.rowwise() -= center;
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(2 * na);
  SimplexInternalConstraints ia(a, 0.5), ib(b, 0.5);
  ib.setFirstParticle(na);
  CollisionConstraints ab(0, na, Triangles(simplexFanTriangles(b).array() + na), 0.5, 1.0, 0.0),
      ba(na, na, simplexFanTriangles(a), 0.5, 1.0, 0.0);
  std::vector<ConstraintSet*> sets = {&ia, &ib};
  if (collide) sets.insert(sets.end(), {&ab, &ba});
  SolverOptions o;
  o.damping = 0;
  o.drag = 0;
  Solver solver(o);
  solver.prepare(p, w);
  MomentumDrift d;
  Eigen::Vector3d lPrev = Eigen::Vector3d::Zero();
  for (int step = 0; step < 20; ++step) {
    if (collide) {
      ab.detect(solver.positions(), false);
      ba.detect(solver.positions(), false);
    }
    solver.step(sets);
    if (!solver.positions().allFinite()) {
      d.finite = false;
      return d;
    }
    Eigen::Vector3d l;
    double scale = 0;
    angularMomentum(solver.positions(), solver.velocities(), w, l, scale);
    const Eigen::Vector3d lin = solver.velocities().colwise().sum().transpose();
    const double linScale = solver.velocities().rowwise().norm().sum();
    if (scale > 0) d.angular = std::max(d.angular, (l - lPrev).norm() / scale);
    if (linScale > 0) d.linear = std::max(d.linear, lin.norm() / linScale);
    lPrev = l;
  }
  return d;
}

std::pair<double, double> internalSweepRadii(double gamma, double amplitude, int sweeps, int* skipped,
                                             InternalMode mode) {
  const SimplexMesh s = simplexSphere(10.0, 2);
  SimplexInternalConstraints c(s, gamma, mode);
  Points p = perturbed(s.positions, amplitude, 9);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(s.vertexCount());
  for (int i = 0; i < sweeps; ++i) c.project(p, w);
  if (skipped) *skipped = c.skipped();
  if (!p.allFinite()) return {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  const Eigen::VectorXd r = p.rowwise().norm();
  return {r.minCoeff(), r.maxCoeff()};
}

std::pair<double, double> smoothingSolverRadii(Scheme scheme, double gamma, double amplitude, int steps) {
  const SimplexMesh s = simplexSphere(10.0, 2);
  SimplexInternalConstraints c(s, gamma, InternalMode::Smoothing);
  SolverOptions o;
  o.scheme = scheme;
  if (scheme == Scheme::Explicit) o.substeps = 4;
  Solver solver(o);
  solver.prepare(perturbed(s.positions, amplitude, 9), Eigen::VectorXd::Ones(s.vertexCount()));
  for (int i = 0; i < steps; ++i) solver.step({&c});
  const Eigen::VectorXd r = solver.positions().rowwise().norm();
  return {r.minCoeff(), r.maxCoeff()};
}

}  // namespace msk::test
