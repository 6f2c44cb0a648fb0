#include "msk/core/shape_matching_constraint.h"

#include <Eigen/Dense>
#include <algorithm>

#include "msk/core/error.h"
#include "msk/core/target_constraint.h"

namespace msk {

ShapeMatchingConstraint::ShapeMatchingConstraint(const Points& reference, PriorTransform transform, double lambda)
    : ref_(reference), transform_(transform), lambda_(lambda) {
  checkUnitInterval("global prior weight", lambda);
}

void ShapeMatchingConstraint::setLambda(double lambda) {
  checkUnitInterval("global prior weight", lambda);
  lambda_ = lambda;
}

void ShapeMatchingConstraint::fit(const Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(ref_.rows());
  const Eigen::VectorXd w = wAll.segment(first_, n);
  // Mass weights: fixed particles (w = 0) weigh like a very heavy particle.
  const double wmax = w.maxCoeff();
  Eigen::VectorXd mass(w.size());
  for (int i = 0; i < w.size(); ++i) mass[i] = w[i] > 0 ? 1.0 / w[i] : 1e6 / std::max(wmax, 1e-300);
  // A non-finite particle takes no part in the fit (weight 0, and a finite stand-in, since 0 · NaN is NaN), so one
  // bad position cannot make every goal NaN; with no finite particle the last transform is kept.
  Points current = pAll.middleRows(first_, n);
  for (int i = 0; i < n; ++i)
    if (!current.row(i).allFinite()) {
      mass[i] = 0;
      current.row(i) = ref_.row(i);
    }
  if (mass.maxCoeff() > 0) last_ = fitTransform(ref_, current, mass, transform_);
}

int ShapeMatchingConstraint::rowParticles(int r, int index[kMaxRowParticles]) const {
  index[0] = first_ + r;
  return 1;
}

void ShapeMatchingConstraint::beginRows(const Points& pAll, const Eigen::VectorXd& wAll) {
  MSK_ASSERT(pAll.rows() >= first_ + ref_.rows() && wAll.size() == pAll.rows(), "global prior: size mismatch");
  if (lambda_ > 0) fit(pAll, wAll);
}

bool ShapeMatchingConstraint::row(int r, const Points& pAll, const Eigen::VectorXd& wAll, ConstraintRow& out) const {
  const int i = first_ + r;
  if (!(lambda_ > 0) || !(wAll[i] > 0)) return false;
  const Eigen::Matrix3d m = last_.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = last_.topRightCorner<3, 1>();
  const Eigen::Vector3d goal = m * ref_.row(r).transpose() + t;
  if (!targetRow(pAll.row(i).transpose(), goal, lambda_, out)) return false;
  out.index[0] = i;
  out.direction = false;
  return true;
}

}  // namespace msk
