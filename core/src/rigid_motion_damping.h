#pragma once
/// The momentum-preserving damping of the solvers (PBD survey §4.1.2, Müller et al. 2007: each velocity is pulled
/// toward the rigid-body velocity field vcm + ω × r of the whole system, which leaves linear and angular momentum
/// unchanged) split into its sums and its application, and the pass that closes a solver step (velocity update,
/// finiteness, largest displacement, the damping's sums), so that the solvers make as few passes over their particle
/// arrays as possible (private to msk_core). The loops take kLanes rows at a time (Lanes; lanes of the last block
/// beyond the rows are zero), each lane summing its own rows: the order of the additions depends on the row count only,
/// never on the data or the thread count.
#include <Eigen/Core>
#include <cmath>
#include <type_traits>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Consecutive rows of one coordinate column (two: one SSE2 register; four spill the damping's sixteen sums).
using Lanes = Eigen::Array2d;
/// Rows per Lanes.
constexpr int kLanes = Lanes::SizeAtCompileTime;

/// Rows [i, i + k) of column `col` (k ≤ kLanes); lanes from k on are zero.
inline Lanes loadLanes(const double* col, int i, int k) {
  if (k == kLanes) return Eigen::Map<const Lanes>(col + i);
  Lanes a = Lanes::Zero();
  for (int j = 0; j < k; ++j) a[j] = col[i + j];
  return a;
}

/// Writes lanes [0, k) of `a` to rows [i, i + k) of column `col`.
inline void storeLanes(const Lanes& a, double* col, int i, int k) {
  if (k == kLanes) {
    Eigen::Map<Lanes>(col + i) = a;
    return;
  }
  for (int j = 0; j < k; ++j) col[i + j] = a[j];
}

/// Calls body(i, k) for the blocks of kLanes rows [i, i + k) of [0, n): k is std::integral_constant<int, kLanes> for
/// the full blocks (loadLanes() and storeLanes() then compile to plain vector loads and stores), an int for a last
/// partial one.
template <class Body>
inline void forLaneBlocks(int n, Body&& body) {
  int i = 0;
  for (; i + kLanes <= n; i += kLanes) body(i, std::integral_constant<int, kLanes>());
  if (i < n) body(i, n - i);
}

/// Per-particle factors of the lane loops (a weights provider: masses() and freeFlags()), from the inverse masses w
/// (#V, ≥ 0): mass m = 1/w and free = 1 for free particles, both 0 for fixed ones (w = 0), so that loops weigh with
/// them instead of branching on w. With equal masses (the usual case) loops use `uniformMass` and skip reading both
/// arrays.
struct ParticleWeights {
  Eigen::VectorXd mass, free;  ///< per particle; empty with uniformMass
  double uniformMass = 0;      ///< the mass of every particle if all are free with equal w, else 0
  /// Computes the factors from `w`.
  void assign(const Eigen::VectorXd& w) {
    uniformMass = w.size() > 0 && w[0] > 0 && (w.array() == w[0]).all() ? 1.0 / w[0] : 0.0;
    if (uniformMass > 0) {  // the arrays are not read
      mass.resize(0);
      free.resize(0);
      return;
    }
    mass = (w.array() > 0).select(w.array().inverse(), 0.0);
    free = (w.array() > 0).cast<double>();
  }
  /// Masses of rows [i, i + k), 0 for fixed particles and lanes from k on.
  Lanes masses(int i, int k) const {
    return uniformMass > 0 ? firstLanes(uniformMass, k) : loadLanes(mass.data(), i, k);
  }
  /// Free flags of rows [i, i + k) (1 free, 0 fixed or lanes from k on).
  Lanes freeFlags(int i, int k) const { return uniformMass > 0 ? firstLanes(1.0, k) : loadLanes(free.data(), i, k); }
  /// `value` in lanes [0, k), 0 in the others.
  static Lanes firstLanes(double value, int k) {
    Lanes a = Lanes::Constant(value);
    for (int j = k; j < kLanes; ++j) a[j] = 0;
    return a;
  }
};

/// The weights provider of inverse masses read directly: the same values as ParticleWeights, computed per block.
struct InverseMasses {
  const Eigen::VectorXd& w;  ///< inverse masses (#V, ≥ 0)
  /// Masses 1/w of rows [i, i + k), 0 for fixed particles and lanes from k on.
  Lanes masses(int i, int k) const {
    const Lanes wl = loadLanes(w.data(), i, k);
    return (wl > 0).select(wl.inverse(), Lanes::Zero());
  }
  /// Free flags of rows [i, i + k).
  Lanes freeFlags(int i, int k) const { return (loadLanes(w.data(), i, k) > 0).select(Lanes::Ones(), Lanes::Zero()); }
};

/// The rigid-body velocity field vcm + ω × (x − xcm) of a particle system (PBD survey §4.1.2).
struct RigidMotion {
  Eigen::Vector3d xcm = Eigen::Vector3d::Zero();    ///< centre of mass, mm
  Eigen::Vector3d vcm = Eigen::Vector3d::Zero();    ///< velocity of the centre of mass, mm per unit of dt
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();  ///< angular velocity, rad per unit of dt (0 if I is singular)
};

/// Mass moments of the free particles about a reference point r0 (y = x − r0, near the particles so that the shift to
/// the centre of mass cancels no large coordinates): M = Σm, S = Σm y, P = Σm v, L = Σm y × v, Q = Σm y yᵀ.
class RigidMoments {
 public:
  /// Sums about `reference` (mm), all zero.
  explicit RigidMoments(const Eigen::Vector3d& reference) : ref_(reference) {}
  /// The reference point r0 (mm).
  const Eigen::Vector3d& reference() const { return ref_; }
  /// Adds kLanes rows: masses `m` (0 adds nothing: fixed particles, unused lanes), positions y = x − r0 and velocities
  /// v, one column each. (Hot loops add into a local copy, which the compiler keeps in registers.)
  EIGEN_ALWAYS_INLINE void add(const Lanes& m, const Lanes& y0, const Lanes& y1, const Lanes& y2, const Lanes& v0,
                               const Lanes& v1, const Lanes& v2) {
    const Lanes my0 = m * y0, my1 = m * y1, my2 = m * y2;
    m_ += m;
    s0_ += my0;
    s1_ += my1;
    s2_ += my2;
    p0_ += m * v0;
    p1_ += m * v1;
    p2_ += m * v2;
    l0_ += my1 * v2 - my2 * v1;
    l1_ += my2 * v0 - my0 * v2;
    l2_ += my0 * v1 - my1 * v0;
    q00_ += my0 * y0;
    q01_ += my0 * y1;
    q02_ += my0 * y2;
    q11_ += my1 * y1;
    q12_ += my1 * y2;
    q22_ += my2 * y2;
  }
  /// The rigid motion of the summed particles: xcm = r0 + S/M, vcm = P/M, ω = I⁻¹ L_cm with the parallel-axis shifts
  /// L_cm = L − (S/M) × P and I = tr(Q_cm) 1 − Q_cm, Q_cm = Q − S Sᵀ/M; false if the mass is zero.
  bool motion(RigidMotion& out) const;

 private:
  Eigen::Vector3d ref_;
  Lanes m_ = Lanes::Zero(), s0_ = Lanes::Zero(), s1_ = Lanes::Zero(), s2_ = Lanes::Zero(), p0_ = Lanes::Zero(),
        p1_ = Lanes::Zero(), p2_ = Lanes::Zero(), l0_ = Lanes::Zero(), l1_ = Lanes::Zero(), l2_ = Lanes::Zero(),
        q00_ = Lanes::Zero(), q01_ = Lanes::Zero(), q02_ = Lanes::Zero(), q11_ = Lanes::Zero(), q12_ = Lanes::Zero(),
        q22_ = Lanes::Zero();
};

/// Position of the first free particle (w > 0) of `x`, the zero vector if there is none: a reference for RigidMoments.
Eigen::Vector3d firstFreePosition(const Points& x, const Eigen::VectorXd& w);

/// Closes a step of the particles: one pass that, with `Update`, sets vel = (x1 − x0) / h (x1 = new positions,
/// x0 = `xBefore`, those before the step, finite), checks that x1 and vel are finite, puts the largest displacement
/// |x1 − x0| (mm) into `maxDisp` and, with `Moments`, adds the rigid motion's moments at (x1, vel) to `moments`,
/// weighing with `weights` (ParticleWeights or InverseMasses). False if a value is not finite (`maxDisp` and the
/// moments are then meaningless).
template <bool Update, bool Moments, class Weights>
bool closeStep(const Points& x1, const Points& xBefore, Points& vel, double h, const Weights& weights, double& maxDisp,
               RigidMoments& moments) {
  const int n = static_cast<int>(x1.rows());
  if (Update) vel.resize(n, 3);
  const double *a0 = x1.col(0).data(), *a1 = x1.col(1).data(), *a2 = x1.col(2).data();
  const double *b0 = xBefore.col(0).data(), *b1 = xBefore.col(1).data(), *b2 = xBefore.col(2).data();
  double *u0 = vel.col(0).data(), *u1 = vel.col(1).data(), *u2 = vel.col(2).data();
  const Eigen::Vector3d ref = moments.reference();
  // With h a power of two, 1/h is exact and d · (1/h) rounds the same real number as d / h: the same velocities.
  int exponent = 0;
  const double invH = 1.0 / h;
  const bool exact = std::frexp(h, &exponent) == 0.5 && std::isfinite(invH);
  RigidMoments sums = moments;                     // local: kept in registers
  Lanes bad = Lanes::Zero(), far = Lanes::Zero();  // Σ (a − a) over the checked values; largest |Δx|² per lane
  forLaneBlocks(n, [&](int i, auto k) {
    const Lanes x0 = loadLanes(a0, i, k), x1 = loadLanes(a1, i, k), x2 = loadLanes(a2, i, k);
    const Lanes d0 = x0 - loadLanes(b0, i, k), d1 = x1 - loadLanes(b1, i, k), d2 = x2 - loadLanes(b2, i, k);
    Lanes v0, v1, v2;
    if (Update) {  // (x1 − x0) / h, bitwise
      if (exact) {
        v0 = d0 * invH;
        v1 = d1 * invH;
        v2 = d2 * invH;
      } else {
        v0 = d0 / h;
        v1 = d1 / h;
        v2 = d2 / h;
      }
      storeLanes(v0, u0, i, k);
      storeLanes(v1, u1, i, k);
      storeLanes(v2, u2, i, k);
    } else {  // (with Update, a finite velocity implies a finite x1, x0 being finite)
      v0 = loadLanes(u0, i, k);
      v1 = loadLanes(u1, i, k);
      v2 = loadLanes(u2, i, k);
      bad += (x0 - x0) + (x1 - x1) + (x2 - x2);
    }
    bad += (v0 - v0) + (v1 - v1) + (v2 - v2);
    far = far.max(d0 * d0 + d1 * d1 + d2 * d2);
    if (Moments) sums.add(weights.masses(i, k), x0 - ref[0], x1 - ref[1], x2 - ref[2], v0, v1, v2);
  });
  moments = sums;
  maxDisp = std::sqrt(far.maxCoeff());
  return bad.sum() == 0;
}

/// What closeStepAndMoments() found.
struct ClosedStep {
  bool finite = false;   ///< every new position and velocity is finite
  double maxDispMm = 0;  ///< largest |x1 − x0|, mm
  bool moving = false;   ///< `motion` holds the damping's rigid motion (damping asked for, some free mass)
  RigidMotion motion;
};

/// closeStep() with, when `damp`, the damping's moments (about the first free particle of x1; `w` the inverse masses
/// `weights` came from) and their rigid motion: the closing pass both solvers make.
template <bool Update, class Weights>
ClosedStep closeStepAndMoments(const Points& x1, const Points& xBefore, Points& vel, double h, const Weights& weights,
                               const Eigen::VectorXd& w, bool damp) {
  ClosedStep out;
  RigidMoments moments(damp ? firstFreePosition(x1, w) : Eigen::Vector3d::Zero());
  out.finite = damp ? closeStep<Update, true>(x1, xBefore, vel, h, weights, out.maxDispMm, moments)
                    : closeStep<Update, false>(x1, xBefore, vel, h, weights, out.maxDispMm, moments);
  out.moving = damp && moments.motion(out.motion);
  return out;
}

/// The application pass of the momentum-preserving damping: v += damping (vcm + ω × (x − xcm) − v) on the free
/// particles (flags of `weights`; none when `motion` is null), then v *= 1 − drag on every particle (drag > 0).
template <class Weights>
void applyRigidDamping(const RigidMotion* motion, const Points& x, const Weights& weights, double damping, double drag,
                       Points& v) {
  if (!motion || !(damping > 0)) {
    if (drag > 0) v *= (1.0 - drag);
    return;
  }
  const double keep = drag > 0 ? 1.0 - drag : 1.0;  // × 1 changes nothing
  const Eigen::Vector3d xcm = motion->xcm, vcm = motion->vcm, om = motion->omega;
  const double *x0 = x.col(0).data(), *x1 = x.col(1).data(), *x2 = x.col(2).data();
  double *v0 = v.col(0).data(), *v1 = v.col(1).data(), *v2 = v.col(2).data();
  forLaneBlocks(static_cast<int>(x.rows()), [&](int i, auto k) {
    const Lanes share = damping * weights.freeFlags(i, k);  // 0 on fixed particles: v + 0 (…) = v
    const Lanes r0 = loadLanes(x0, i, k) - xcm[0], r1 = loadLanes(x1, i, k) - xcm[1], r2 = loadLanes(x2, i, k) - xcm[2];
    const Lanes u0 = loadLanes(v0, i, k), u1 = loadLanes(v1, i, k), u2 = loadLanes(v2, i, k);
    // vcm + ω × r, as Eigen's cross product
    const Lanes rigid0 = vcm[0] + (om[1] * r2 - om[2] * r1), rigid1 = vcm[1] + (om[2] * r0 - om[0] * r2),
                rigid2 = vcm[2] + (om[0] * r1 - om[1] * r0);
    storeLanes((u0 + share * (rigid0 - u0)) * keep, v0, i, k);
    storeLanes((u1 + share * (rigid1 - u1)) * keep, v1, i, k);
    storeLanes((u2 + share * (rigid2 - u2)) * keep, v2, i, k);
  });
}

/// Copies `a` into `b` (resized to it) in a pass that checks it: true if every coefficient is finite.
bool copyIfFinite(const Points& a, Points& b);

}  // namespace msk
