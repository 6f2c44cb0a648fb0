#pragma once
/// Position-based evolution (PBD survey seed 001, Algorithm 1): predict, project the constraint sets, update
/// velocities from the corrected positions, then momentum-preserving damping (§4.1.2).
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "msk/core/constraints.h"

namespace msk {

/// Settings of the position-based scheme (user input).
struct PbdOptions {
  double dt = 1.0;          ///< time step (nominal: with α = m̄ dt⁻² it cancels from the corrections)
  int iterations = 1;       ///< projection sweeps per step
  double damping = 0.5;     ///< k ∈ [0,1]: share of each velocity's deviation from the rigid motion removed per step
  double drag = 0.5;        ///< ∈ [0,1]: share of the remaining velocity removed per step (1 = quasi-static)
};

/// Runs the position-based scheme on one particle system (sequential Gauss–Seidel; solver.h offers every scheme).
class PbdSolver {
 public:
  /// Validates the options (ParameterError for dt ≤ 0, iterations < 1, damping/drag outside [0, 1]).
  explicit PbdSolver(const PbdOptions& opts);
  /// Sets the initial positions (#V×3, mm) and inverse masses (#V, ≥ 0; 0 = fixed); velocities start at zero.
  void prepare(const Points& positions, const Eigen::VectorXd& inverseMass);
  /// Replaces the positions (e.g. after a change of resolution level), keeping zero velocity.
  void reset(const Points& positions, const Eigen::VectorXd& inverseMass);
  /// One step with the given constraint sets: their velocity pass before the prediction
  /// (ConstraintSet::correctBeforePrediction()), projections in order, velocity update, damping, then their velocity
  /// pass (ConstraintSet::correctVelocities()); returns the largest displacement (mm).
  /// Throws Error if a position becomes non-finite (the state is left as before the step).
  double step(const std::vector<ConstraintSet*>& sets);
  /// Current positions.
  const Points& positions() const { return x_; }
  /// Current velocities (mm per step).
  const Points& velocities() const { return v_; }
  /// Inverse masses.
  const Eigen::VectorXd& inverseMass() const { return w_; }
  /// Steps taken since prepare().
  int steps() const { return steps_; }
  /// Seconds spent projecting each constraint family (by ConstraintSet::name()).
  const std::map<std::string, double>& secondsPerFamily() const { return seconds_; }

 private:
  PbdOptions opts_;
  Points x_, v_, p_;
  Eigen::VectorXd w_;
  int steps_ = 0;
  std::map<std::string, double> seconds_;
};

}  // namespace msk
