#include "rigid_motion_damping.h"

#include <Eigen/Dense>

#include "msk/core/pbd_solver.h"

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

void dampTowardRigidMotion(const Points& x, const Eigen::VectorXd& w, double damping, double drag, Points& v) {
  // Momentum-preserving damping (PBD survey §4.1.2, Müller et al. 2007): pull each velocity toward the rigid-body
  // velocity field vcm + ω × r of the whole system, which leaves linear and angular momentum unchanged. One pass
  // sums the moments (about the first free particle), one applies the damping and the drag.
  const int n = static_cast<int>(x.rows());
  const InverseMasses weights{w};
  RigidMotion motion;
  bool moving = false;
  if (damping > 0 && n > 0) {
    const Eigen::Vector3d ref = firstFreePosition(x, w);
    RigidMoments moments(ref);
    const double *x0 = x.col(0).data(), *x1 = x.col(1).data(), *x2 = x.col(2).data();
    const double *v0 = v.col(0).data(), *v1 = v.col(1).data(), *v2 = v.col(2).data();
    forLaneBlocks(n, [&](int i, auto k) {
      moments.add(weights.masses(i, k), loadLanes(x0, i, k) - ref[0], loadLanes(x1, i, k) - ref[1],
                  loadLanes(x2, i, k) - ref[2], loadLanes(v0, i, k), loadLanes(v1, i, k), loadLanes(v2, i, k));
    });
    moving = moments.motion(motion);
  }
  applyRigidDamping(moving ? &motion : nullptr, x, weights, damping, drag, v);
}

}  // namespace msk
