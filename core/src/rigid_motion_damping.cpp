#include "rigid_motion_damping.h"

#include <Eigen/Dense>

namespace msk {

bool RigidMoments::motion(RigidMotion& out) const {
  const double mass = m_.sum();
  if (!(mass > 0)) return false;
  const Eigen::Vector3d s(s0_.sum(), s1_.sum(), s2_.sum()), p(p0_.sum(), p1_.sum(), p2_.sum()),
      l(l0_.sum(), l1_.sum(), l2_.sum());
  Eigen::Matrix3d q;
  q << q00_.sum(), q01_.sum(), q02_.sum(),  //
      q01_.sum(), q11_.sum(), q12_.sum(),   //
      q02_.sum(), q12_.sum(), q22_.sum();
  const Eigen::Vector3d c = s / mass;  // centre of mass relative to the reference
  out.xcm = ref_ + c;
  out.vcm = p / mass;
  // Parallel-axis theorem: moments about the centre of mass from those about the reference.
  const Eigen::Vector3d lcm = l - c.cross(p);
  const Eigen::Matrix3d qcm = q - (s * s.transpose()) / mass;
  const Eigen::Matrix3d inertia = qcm.trace() * Eigen::Matrix3d::Identity() - qcm;
  out.omega.setZero();
  Eigen::FullPivLU<Eigen::Matrix3d> lu(inertia);
  if (lu.isInvertible()) out.omega = lu.solve(lcm);
  return true;
}

Eigen::Vector3d firstFreePosition(const Points& x, const Eigen::VectorXd& w) {
  for (int i = 0; i < w.size(); ++i)
    if (w[i] > 0) return x.row(i).transpose();
  return Eigen::Vector3d::Zero();
}

bool copyIfFinite(const Points& a, Points& b) {
  // x − x is 0 for finite x and NaN for ±∞ or NaN, so the sum stays 0 exactly when every coefficient is finite.
  b.resize(a.rows(), 3);
  const double* from = a.data();
  double* to = b.data();
  Lanes acc = Lanes::Zero();
  forLaneBlocks(static_cast<int>(a.size()), [&](int i, auto k) {
    const Lanes l = loadLanes(from, i, k);
    storeLanes(l, to, i, k);
    acc += l - l;
  });
  return acc.sum() == 0;
}

}  // namespace msk
