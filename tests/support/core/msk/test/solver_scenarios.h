#pragma once
/// Solver scenarios on simplex spheres, shared by the core tests (which assert on them) and bench/solver_bench.cpp
/// (which reports their figures): every scheme on one problem, XPBD's iteration independence, the mass-relative
/// stiffness, momentum drift through whole steps, and the smoothing mode of the internal constraint left alone.
#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

#include "msk/core/constraint_set.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/solver.h"
#include "msk/core/target_constraint.h"

namespace msk::test {

/// A 2-simplex sphere (radius 10 mm) with shape memory (γ = 0.8), image-like targets on every other vertex (γ = 0.5)
/// and a similarity prior. Consistent: targets on the sphere scaled by 1.2 (every constraint holds there, the unique
/// answer `expected`); otherwise targets at 1.2× on the x > 0 half and 1× elsewhere (a compromise that depends on the
/// stiffnesses).
struct SphereProblem {
  SimplexMesh mesh;
  Points x0, expected;
  Eigen::VectorXd w;  ///< inverse masses, all 1
  std::unique_ptr<SimplexInternalConstraints> internal;
  std::unique_ptr<TargetConstraints> targets;
  std::unique_ptr<ShapeMatchingConstraint> prior;

  /// Shape memory, targets and prior, in that order.
  std::vector<ConstraintSet*> sets() const { return {internal.get(), targets.get(), prior.get()}; }
};

/// The problem on a sphere of 20·4^subdivisions vertices, the prior's weight `priorWeight`.
SphereProblem sphereProblem(int subdivisions, bool consistent = true, double priorWeight = 0.1);

/// The settings each scheme runs the problem with: 4 iterations; Jacobi ω = 1.5, XPBD stiffness 1e6, explicit 4
/// substeps.
SolverOptions sphereProblemOptions(Scheme scheme);

/// A run of the problem until no vertex moves more than the tolerance.
struct SphereRun {
  int steps = 0;
  bool converged = false;
  double error = 0;     ///< largest distance to the expected answer, mm (0 without one)
  double lastMove = 0;  ///< the last step's largest displacement, mm
  Points x;
};

/// Steps from x0 until no vertex moves more than `tolMm` (or `maxSteps`); error against `expected` if given.
SphereRun runSphereProblem(const SolverOptions& o, const SphereProblem& s, int maxSteps, double tolMm,
                           const Points* expected);

/// XPBD's iteration independence: the inconsistent problem without prior, 100 steps of `scheme` (stiffness 1) at each
/// iteration count in `iterations`; each result's largest vertex distance to the last one's, as a share of `movedMm`,
/// the last result's largest displacement from x0 (mm). Empty if a result is not finite.
std::vector<double> iterationDeviations(Scheme scheme, const std::vector<int>& iterations, double& movedMm);

/// XPBD with mass-relative stiffness k = 1 against the implicit scheme at their steady states (600 steps of the
/// inconsistent problem without prior, 80 vertices).
struct MassRelativeXpbd {
  double movedMm = 0;    ///< the implicit result's largest displacement from x0
  double deviation = 0;  ///< largest XPBD − implicit distance, as a share of movedMm
  double heavierMm = 0;  ///< largest XPBD difference between unit masses and masses × 1e6
};
MassRelativeXpbd massRelativeXpbdAgainstImplicit();

/// Momentum through whole position-based steps: two overlapping perturbed spheres (unit masses, no damping, no drag, no
/// image targets), 20 steps under their internal sets and, if `collide`, the collision sets of both directions.
struct MomentumDrift {
  double angular = 0;  ///< largest per-step change of Σ m x × v, relative to Σ m |x| |v|
  double linear = 0;   ///< largest |Σ m v| relative to Σ m |v|
  bool finite = true;  ///< every step's positions finite
};
MomentumDrift momentumDrift(bool collide);

/// Smallest and largest distance from the origin (mm) after `sweeps` projections of the internal set alone in `mode`
/// (stiffness `gamma`) on a sphere of radius 10 mm perturbed by ±amplitude; {∞, ∞} if not finite. The rest shape is
/// the sphere itself. `skipped`, if given, receives the set's skipped rows of the last sweep.
std::pair<double, double> internalSweepRadii(double gamma, double amplitude, int sweeps, int* skipped = nullptr,
                                             InternalMode mode = InternalMode::Smoothing);

/// The same through the rows: `steps` steps of `scheme` with the smoothing set alone.
std::pair<double, double> smoothingSolverRadii(Scheme scheme, double gamma, double amplitude, int steps);

}  // namespace msk::test
