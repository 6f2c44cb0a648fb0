#pragma once
/// Measures on particle states that the solver and constraint tests share: the linear momentum a correction carries,
/// and bitwise equality of two states.
#include <Eigen/Core>

#include "msk/core/triangle_mesh.h"

namespace msk::test {

/// The linear momentum of a correction: Σ m Δx over the particles with inverse mass w > 0 (m = 1/w), and its scale
/// Σ m |Δx|.
struct LinearMomentum {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double scale = 0;
  /// |sum| relative to the scale (0 if nothing moved).
  double relative() const { return scale > 0 ? sum.norm() / scale : 0.0; }
};

/// The linear momentum of the correction from `before` to `after` with inverse masses `w`.
LinearMomentum linearMomentum(const Points& before, const Points& after, const Eigen::VectorXd& w);

/// Whether `a` and `b` have the same size and bitwise the same coordinates.
bool bitwiseEqual(const Points& a, const Points& b);

}  // namespace msk::test
