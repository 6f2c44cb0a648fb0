#include "msk/core/pbd_solver.h"

#include <chrono>
#include <cmath>

#include <Eigen/Dense>

#include "msk/core/error.h"
#include "rigid_motion_damping.h"

namespace msk {

PbdSolver::PbdSolver(const PbdOptions& o) : opts_(o) {
  if (!(o.dt > 0) || !std::isfinite(o.dt)) throw ParameterError("dt", std::to_string(o.dt), "must be positive");
  if (o.iterations < 1) throw ParameterError("iterations", std::to_string(o.iterations), "must be at least 1");
  checkUnitInterval("damping", o.damping);
  checkUnitInterval("drag", o.drag);
}

void PbdSolver::prepare(const Points& positions, const Eigen::VectorXd& inverseMass) {
  reset(positions, inverseMass);
  steps_ = 0;
  seconds_.clear();
}

void PbdSolver::reset(const Points& positions, const Eigen::VectorXd& inverseMass) {
  if (positions.rows() != inverseMass.size()) throw Error("PBD: positions and inverse masses differ in size");
  if (!positions.allFinite()) throw Error("PBD: non-finite initial positions");
  if ((inverseMass.array() < 0).any() || !inverseMass.allFinite())
    throw Error("PBD: inverse masses must be finite and non-negative");
  x_ = positions;
  w_ = inverseMass;
  v_ = Points::Zero(positions.rows(), 3);
}

double PbdSolver::step(const std::vector<ConstraintSet*>& sets) {
  const double dt = opts_.dt;
  for (ConstraintSet* s : sets) s->correctBeforePrediction(x_, v_, w_, dt);  // acceleration-mode collision response
  // Predict (no external forces: image forces enter as target constraints).
  p_ = x_ + dt * v_;
  for (int i = 0; i < w_.size(); ++i)
    if (w_[i] <= 0) p_.row(i) = x_.row(i);
  for (int it = 0; it < opts_.iterations; ++it) {
    for (ConstraintSet* s : sets) {
      const auto t0 = std::chrono::steady_clock::now();
      s->project(p_, w_);
      seconds_[s->name()] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
  }
  if (!p_.allFinite()) throw Error("numerical failure: non-finite position after PBD step " + std::to_string(steps_ + 1));
  // One pass: velocity update, largest displacement and the damping's moments (as Solver::step(), bit for bit).
  const InverseMasses weights{w_};
  const ClosedStep closed =
      closeStepAndMoments<true>(p_, x_, v_, dt, weights, w_, opts_.damping > 0 && w_.size() > 0);
  x_.swap(p_);
  applyRigidDamping(closed.moving ? &closed.motion : nullptr, x_, weights, opts_.damping, opts_.drag, v_);
  for (ConstraintSet* s : sets) s->correctVelocities(x_, v_, w_, dt);  // velocity-mode collision response
  ++steps_;
  return closed.maxDispMm;
}

}  // namespace msk
