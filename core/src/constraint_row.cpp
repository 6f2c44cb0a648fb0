#include "msk/core/constraint_row.h"

#include <Eigen/Dense>
#include <cmath>

namespace msk {

double rowInverseMass(const ConstraintRow& row, const Eigen::VectorXd& w) {
  double W = 0;
  for (int j = 0; j < row.count; ++j) W += row.grad[j] * row.react[j] * w[row.index[j]];
  return W;
}

bool pbdCorrections(const ConstraintRow& row, const double wj[], Eigen::Vector3d dp[]) {
  double W = 0;
  for (int j = 0; j < row.count; ++j) W += row.grad[j] * row.react[j] * wj[j];
  if (!(W > 0) || !std::isfinite(W) || !row.c.allFinite()) return false;
  if (row.count == 1) {
    dp[0] = (-row.gamma / row.grad[0]) * row.c;
    return dp[0].allFinite();
  }
  const double s = -row.gamma / W;
  for (int j = 0; j < row.count; ++j) dp[j] = (wj[j] * row.react[j] * s) * row.c;
  return true;
}

bool pbdCorrections(const ConstraintRow& row, double w, const double wi[], Eigen::Vector3d& dp, Eigen::Vector3d dpi[]) {
  double wj[kMaxRowParticles];
  Eigen::Vector3d d[kMaxRowParticles];
  wj[0] = w;
  for (int j = 1; j < row.count; ++j) wj[j] = wi[j - 1];
  if (!pbdCorrections(row, wj, d)) return false;
  dp = d[0];
  for (int j = 1; j < row.count; ++j) dpi[j - 1] = d[j];
  return true;
}

bool applyPbdRow(const ConstraintRow& row, const Eigen::VectorXd& w, Points& p) {
  double wj[kMaxRowParticles];
  Eigen::Vector3d dp[kMaxRowParticles];
  for (int j = 0; j < row.count; ++j) wj[j] = w[row.index[j]];
  if (!pbdCorrections(row, wj, dp)) return false;
  for (int j = 0; j < row.count; ++j) p.row(row.index[j]) += dp[j].transpose();
  return true;
}

}  // namespace msk
