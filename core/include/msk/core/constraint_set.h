#pragma once
/// A family of constraints (ConstraintSet): the constraints of one kind over one object's particles, exposed one by
/// one as rows (constraint_row.h) so that every scheme of solver.h runs them alike.
#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "msk/core/constraint_row.h"
#include "msk/core/triangle_mesh.h"

namespace msk {

/// A family of constraints projected together. A set defines its constraints as rows (row(): the one definition of
/// each constraint); project() is then the sequential (Gauss–Seidel) loop over them, and the solvers run the same rows
/// in coloured, Jacobi, XPBD or force-based form. A set without rows (rowCount() = 0) overrides project(), which every
/// scheme then calls.
class ConstraintSet {
 public:
  virtual ~ConstraintSet() = default;
  /// Family name for reports ("simplex-internal", "image-targets", ...).
  virtual std::string name() const = 0;
  /// Projects every constraint once on positions `p` (#V×3) with inverse masses `w`: beginRows(), then each row's PBD
  /// correction (applyPbdRow()) in row order, each at the positions the rows before it left.
  virtual void project(Points& p, const Eigen::VectorXd& w);
  /// Index of the set's first particle in the solver's arrays (several objects are stacked in one system).
  void setFirstParticle(int first) {
    first_ = first;
    ++rowLayout_;
  }
  /// See setFirstParticle().
  int firstParticle() const { return first_; }

  /// Number of constraints exposed as rows; 0 = the set has only project().
  virtual int rowCount() const { return 0; }
  /// Global particle indices row `r` touches (at most kMaxRowParticles, written to `index`); returns their number.
  /// Must not depend on positions: solvers colour the rows with it. row() reads and writes no other particle.
  virtual int rowParticles(int r, int index[kMaxRowParticles]) const;
  /// Prepares a pass over the rows at positions `p` (e.g. the global fit, smoothing heights); called before row().
  virtual void beginRows(const Points& p, const Eigen::VectorXd& w);
  /// Linearises row `r` at positions `p`; false if it has nothing to do there or is degenerate (skipped).
  /// Thread-safe for rows that share no particle.
  virtual bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const;
  /// Velocity pass before the prediction of every substep of length `h` at positions `x` (#V×3): a set may change
  /// the velocities `v` (acceleration-mode collision response). Default: nothing. Every scheme calls it.
  virtual void correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h);
  /// Velocity pass after the velocity update of every substep of length `h` (after the damping on a step's last
  /// substep), at the new positions `x`: a set may change the velocities `v` (velocity-mode collision response).
  /// Default: nothing. Every scheme calls it.
  virtual void correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h);
  /// Rows the last project() left out (nothing to do, or degenerate).
  int skipped() const { return skipped_; }
  /// Changes whenever the particles of the rows change (a solver then recolours them).
  std::uint64_t rowLayout() const { return rowLayout_; }
  /// Identity of this set object (unique per construction), so solvers can cache its colouring.
  std::uint64_t uid() const { return uid_; }

 protected:
  /// Call when the rows' particles change (other than through setFirstParticle()).
  void rowLayoutChanged() { ++rowLayout_; }
  int first_ = 0;
  int skipped_ = 0;

 private:
  static std::uint64_t newUid();
  std::uint64_t rowLayout_ = 0;
  std::uint64_t uid_ = newUid();
};

}  // namespace msk
