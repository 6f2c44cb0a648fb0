#include "msk/core/constraint_set.h"

#include <atomic>

namespace msk {

std::uint64_t ConstraintSet::newUid() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1);
}

void ConstraintSet::project(Points& p, const Eigen::VectorXd& w) {
  skipped_ = 0;
  beginRows(p, w);
  ConstraintRow r;
  for (int k = 0, n = rowCount(); k < n; ++k)
    if (!row(k, p, w, r) || !applyPbdRow(r, w, p)) ++skipped_;
}

int ConstraintSet::rowParticles(int, int[kMaxRowParticles]) const { return 0; }
void ConstraintSet::beginRows(const Points&, const Eigen::VectorXd&) {}
bool ConstraintSet::row(int, const Points&, const Eigen::VectorXd&, ConstraintRow&) const { return false; }
void ConstraintSet::correctBeforePrediction(const Points&, Points&, const Eigen::VectorXd&, double) {}
void ConstraintSet::correctVelocities(const Points&, Points&, const Eigen::VectorXd&, double) {}

}  // namespace msk
