#pragma once
/// One entry point for every evolution scheme over the same constraint sets (DESIGN-NOTES §5, §6): position-based
/// (sequential or graph-coloured Gauss–Seidel, weighted-sum Jacobi, XPBD) and force-based (explicit symplectic Euler,
/// implicit Euler solved by conjugate gradient). Switch scheme by changing SolverOptions only:
///
///   SolverOptions o;
///   o.scheme = parseScheme("xpbd");   // or Scheme::Xpbd
///   Solver solver(o);
///   solver.prepare(x, invMass);
///   solver.step(sets);
///
/// Every set's constraints are rows (ConstraintRow): image targets, 2-simplex internal, global prior, radial,
/// 3-simplex and collision contacts alike. Sequential Gauss–Seidel runs each set's project() (its rows in order); the
/// coloured, Jacobi and XPBD schemes run the rows colour by colour or summed, the force-based ones turn them into
/// forces with their derivatives. A set without rows (axis centring, volume preservation, global contact resolution) is
/// run through project() by the position-based schemes, and by Jacobi and the force-based ones as
/// SolverOptions::rowless says. Every scheme calls each set's velocity passes: ConstraintSet::correctBeforePrediction()
/// at the start of every substep, and ConstraintSet::correctVelocities() after the velocity update of every substep
/// (after the damping on a step's last substep), which is where collision response in acceleration and velocity mode
/// acts (collision_response.h).
#include <Eigen/Core>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "msk/core/constraint_set.h"

namespace msk {

/// Evolution scheme.
enum class Scheme {
  GaussSeidel,          ///< "gauss-seidel": PBD, every set projected in its own sequential order
  ColouredGaussSeidel,  ///< "coloured-gauss-seidel": PBD, rows colour by colour (parallel, thread-count independent)
  Jacobi,               ///< "jacobi": PBD, weighted sum of all rows' corrections at the same positions, relaxation ω
  Xpbd,                 ///< "xpbd": extended PBD, compliance α̃ = 1/(k γ dt²), multipliers reset every substep
  Explicit,             ///< "explicit": forces, symplectic Euler
  Implicit              ///< "implicit": forces, implicit Euler (Baraff–Witkin), conjugate gradient on 3×3 blocks
};

/// Name of a scheme as parseScheme() reads it ("gauss-seidel", "coloured-gauss-seidel", "jacobi", "xpbd", "explicit",
/// "implicit").
std::string schemeName(Scheme scheme);
/// Scheme from its name (also "colored-gauss-seidel"); otherwise throws ParameterError naming `option` and the choices.
Scheme parseScheme(const std::string& name, const std::string& option = "scheme");
/// Every scheme, in declaration order.
std::vector<Scheme> allSchemes();

/// How Jacobi and the force-based schemes treat a set without rows.
enum class RowlessSets {
  Project,  ///< projected in order on the positions after each Jacobi iteration or force-based substep, the
            ///< velocities following the correction (collision response by position correction, DESIGN-NOTES §3)
  Blend  ///< Jacobi: averaged with the rows' corrections; force-based: forces M Δp dt⁻² of a projection on a copy
         ///< with the isotropic diagonal derivative −M dt⁻² I
};

/// What SolverOptions::stiffness means to XPBD.
enum class XpbdStiffness {
  Absolute,     ///< k in mass · time⁻²: row stiffness k γ, compliance α̃ = 1 / (k γ h²), h the substep
  MassRelative  ///< k dimensionless: row stiffness k times the force stiffness α = γ m̄ dt⁻² of DESIGN-NOTES §2, so
                ///< α̃ = W dt² / (k γ h²); k = 1 shares its stiffness (and equilibrium) with the force-based schemes,
                ///< and no mass or time scale enters
};

/// Settings of Solver (user input).
struct SolverOptions {
  Scheme scheme = Scheme::GaussSeidel;  ///< evolution scheme
  double dt = 1.0;         ///< time step of one step() (> 0); with α = γ m̄ dt⁻² it cancels from PBD corrections
  int substeps = 1;        ///< substeps per step (≥ 1), each of dt / substeps: predict, solve, update velocities
  int iterations = 1;      ///< position-based: projection sweeps per substep (≥ 1); unused by the force-based ones
  double damping = 0.5;    ///< ∈ [0, 1]: share of each velocity's deviation from the rigid motion removed per step
  double drag = 0.5;       ///< ∈ [0, 1]: share of the remaining velocity removed per step (1 = quasi-static)
  double omega = 1.0;      ///< Jacobi relaxation ω ∈ (0, 2): scales every averaged correction
  double stiffness = 1.0;  ///< XPBD stiffness k ≥ 0 (see xpbdStiffness; +inf = hard, 0 = off), times each row's γ
                           ///< (rows that are not ConstraintRow::compliant are always hard)
  XpbdStiffness xpbdStiffness = XpbdStiffness::Absolute;  ///< unit of `stiffness`
  double forceDamping =
      1.0;  ///< force-based: damping ratio ζ ≥ 0 of the projected damping F = −β (v·F̂) F̂, β = 2ζ√(α m̄)
  double anisotropy = 0.9;  ///< force-based: k ∈ [0, 1] of direction targets, ∂F/∂P ≈ −α (k I + (1 − k) uuᵀ)
  int cgIterations = 200;      ///< implicit: most conjugate-gradient iterations per substep (≥ 1)
  double cgTolerance = 1e-10;  ///< implicit: stop when the preconditioned residual falls below this share (> 0)
  int threads = 1;             ///< threads (≥ 1; 0 = all cores); results do not depend on it
  RowlessSets rowless = RowlessSets::Project;  ///< sets without rows under Jacobi and the force-based schemes
  bool batchKernels = true;  ///< coloured Gauss–Seidel (PBD) and Jacobi run a set's batch kernel where it has one
                             ///< (2-simplex internal, shape memory: SimplexInternalConstraints::batch()), which gives
                             ///< its rows' corrections up to rounding several rows at a time; false: row by row
};

/// Checks every field (ParameterError naming the field: dt ≤ 0 or non-finite, substeps/iterations/cgIterations < 1,
/// damping/drag/anisotropy outside [0, 1], ω outside (0, 2), negative or NaN stiffness, negative forceDamping,
/// cgTolerance ≤ 0, threads < 0).
void validateSolverOptions(const SolverOptions& opts);

/// Runs one scheme on one particle system (several objects stacked).
class Solver {
 public:
  /// Validates the options (validateSolverOptions()).
  explicit Solver(const SolverOptions& opts);
  ~Solver();
  Solver(const Solver&) = delete;
  Solver& operator=(const Solver&) = delete;
  /// Sets the initial positions (#V×3, mm) and inverse masses (#V, ≥ 0; 0 = fixed); velocities start at zero.
  void prepare(const Points& positions, const Eigen::VectorXd& inverseMass);
  /// Replaces the positions (e.g. after a change of resolution level), keeping zero velocity.
  void reset(const Points& positions, const Eigen::VectorXd& inverseMass);
  /// One step (all substeps) with the given constraint sets, in order, then the damping and the sets' velocity pass;
  /// returns the largest displacement (mm).
  /// Throws Error if a position becomes non-finite (the state is left as before the step).
  double step(const std::vector<ConstraintSet*>& sets);
  /// Current positions.
  const Points& positions() const;
  /// Current velocities (mm per unit of dt).
  const Points& velocities() const;
  /// Inverse masses.
  const Eigen::VectorXd& inverseMass() const;
  /// Steps taken since prepare().
  int steps() const;
  /// Seconds spent on each constraint family (by ConstraintSet::name()).
  const std::map<std::string, double>& secondsPerFamily() const;
  /// The options in use.
  const SolverOptions& options() const;
  /// Implicit scheme: conjugate-gradient iterations of the last step (all substeps), 0 otherwise.
  int lastCgIterations() const;
  /// Implicit scheme: largest relative preconditioned residual left by the last step's solves, 0 otherwise.
  double lastCgResidual() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace msk
