#pragma once
/// The pose of a phantom's anatomy in world space: a similarity that moves the subject away from the mean-anatomy
/// templates, so that placing the templates needs registration.
#include <Eigen/Core>

namespace msk {

/// Similarity P(x) = c + t + s·R·(x − c) applied to a phantom's anatomy (image, labels, tissues, truth meshes; not
/// the templates), RAS mm. R = Grid::rotationXYZ(rotationDegrees): rotations about the world x, then y, then z axes
/// (R = Rz·Ry·Rx). The centre c of rotation and scaling is the RAS origin (0, 0, 0), the centre of every phantom's
/// un-posed field of view (the thigh phantom's mean femur axis passes within 10 mm of it).
struct PhantomPose {
  Eigen::Vector3d rotationDegrees = Eigen::Vector3d::Zero();  ///< about x, then y, then z, degrees, each in [−180, 180]
  Eigen::Vector3d translationMm = Eigen::Vector3d::Zero();    ///< t, mm, |t| ≤ 1000
  double scale = 1;                                           ///< s, in [0.5, 2]

  /// True for the identity pose (every number exactly 0, scale exactly 1).
  bool isIdentity() const { return rotationDegrees.isZero(0) && translationMm.isZero(0) && scale == 1; }
};

/// Centre c of a phantom pose's rotation and scaling, RAS mm.
Eigen::Vector3d phantomPoseCentre();

/// The 4×4 matrix of P (RAS mm, x_posed = P·x): exactly the identity for the identity pose.
Eigen::Matrix4d phantomPoseMatrix(const PhantomPose& pose);

/// The 4×4 matrix of P⁻¹, computed in closed form (transposed rotation, reciprocal scale).
Eigen::Matrix4d phantomPoseInverse(const PhantomPose& pose);

/// Throws ParameterError naming --pose (value "ax,ay,az,tx,ty,tz,s") unless every number is finite, every angle in
/// [−180, 180] degrees, |t| ≤ 1000 mm and the scale in [0.5, 2].
void checkPhantomPose(const PhantomPose& pose);

}  // namespace msk
