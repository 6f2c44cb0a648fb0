#include "msk/core/pbd_solver.h"

#include <chrono>
#include <cmath>

#include <Eigen/Dense>

#include "msk/core/error.h"

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

void dampTowardRigidMotion(const Points& x, const Eigen::VectorXd& w, double damping, double drag, Points& v) {
  // Momentum-preserving damping (PBD survey §4.1.2, Müller et al. 2007): pull each velocity toward the rigid-body
  // velocity field vcm + ω × r of the whole system, which leaves linear and angular momentum unchanged.
  const int n = static_cast<int>(x.rows());
  if (damping > 0 && n > 0) {
    double msum = 0;
    Eigen::Vector3d xcm = Eigen::Vector3d::Zero(), vcm = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i) {
      if (w[i] <= 0) continue;
      const double m = 1.0 / w[i];
      msum += m;
      xcm += m * x.row(i).transpose();
      vcm += m * v.row(i).transpose();
    }
    if (msum > 0) {
      xcm /= msum;
      vcm /= msum;
      Eigen::Vector3d l = Eigen::Vector3d::Zero();
      Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
      for (int i = 0; i < n; ++i) {
        if (w[i] <= 0) continue;
        const double m = 1.0 / w[i];
        const Eigen::Vector3d r = x.row(i).transpose() - xcm;
        l += m * r.cross(v.row(i).transpose());
        inertia += m * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
      }
      Eigen::Vector3d omega = Eigen::Vector3d::Zero();
      Eigen::FullPivLU<Eigen::Matrix3d> lu(inertia);
      if (lu.isInvertible()) omega = lu.solve(l);
      for (int i = 0; i < n; ++i) {
        if (w[i] <= 0) continue;
        const Eigen::Vector3d r = x.row(i).transpose() - xcm;
        const Eigen::Vector3d rigid = vcm + omega.cross(r);
        v.row(i) += damping * (rigid.transpose() - v.row(i));
      }
    }
  }
  if (drag > 0) v *= (1.0 - drag);
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
  const double maxDisp = (p_ - x_).rowwise().norm().maxCoeff();
  v_ = (p_ - x_) / dt;
  x_.swap(p_);
  dampTowardRigidMotion(x_, w_, opts_.damping, opts_.drag, v_);
  for (ConstraintSet* s : sets) s->correctVelocities(x_, v_, w_, dt);  // velocity-mode collision response
  ++steps_;
  return maxDisp;
}

}  // namespace msk
