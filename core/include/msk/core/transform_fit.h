#pragma once
/// Best-fitting rigid, similarity or affine transform between two point sets (shape matching, DESIGN-NOTES §1).
#include <Eigen/Core>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Kind of transform a fit (and a global shape prior) uses.
enum class PriorTransform { Rigid, Similarity, Affine };

/// Best transform mapping `from` onto `to` (rows are points), weighted by `weights` (#V, ≥ 0, not all zero).
/// Rigid and similarity fits are Umeyama's (proper rotations only); affine is weighted least squares (a similarity
/// where the points are planar or collinear).
Eigen::Matrix4d fitTransform(const Points& from, const Points& to, const Eigen::VectorXd& weights,
                             PriorTransform transform);

}  // namespace msk
