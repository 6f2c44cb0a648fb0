#include "msk/core/target_constraint.h"

#include "msk/core/error.h"

namespace msk {

bool targetRow(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double gamma, ConstraintRow& row) {
  row.count = 1;
  row.index[0] = 0;
  row.grad[0] = 1.0;
  row.react[0] = 1.0;
  row.c = p - target;
  row.gamma = gamma;
  row.direction = true;
  row.compliant = true;
  return row.c.allFinite();
}

bool targetCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double w, double gamma,
                      Eigen::Vector3d& dp) {
  ConstraintRow row;
  return targetRow(p, target, gamma, row) && pbdCorrections(row, &w, &dp);
}

TargetConstraints::TargetConstraints(double gamma) : gamma_(gamma) { checkUnitInterval("image stiffness", gamma); }

void TargetConstraints::setTargets(const Points& targets, const Eigen::VectorXd& weights) {
  MSK_ASSERT(targets.rows() == weights.size(), "targets and weights differ in size");
  if (targets.rows() != targets_.rows()) rowLayoutChanged();
  targets_ = targets;
  weights_ = weights.cwiseMax(0.0).cwiseMin(1.0);
}

int TargetConstraints::rowParticles(int r, int index[kMaxRowParticles]) const {
  index[0] = first_ + r;
  return 1;
}

void TargetConstraints::beginRows(const Points& pAll, const Eigen::VectorXd& wAll) {
  MSK_ASSERT(pAll.rows() >= first_ + targets_.rows() && wAll.size() == pAll.rows(), "targets: size mismatch");
}

bool TargetConstraints::row(int r, const Points& pAll, const Eigen::VectorXd& wAll, ConstraintRow& out) const {
  const int i = first_ + r;
  if (!(weights_[r] > 0) || !(wAll[i] > 0)) return false;
  if (!targetRow(pAll.row(i).transpose(), targets_.row(r).transpose(), gamma_ * weights_[r], out)) return false;
  out.index[0] = i;
  return true;
}

}  // namespace msk
