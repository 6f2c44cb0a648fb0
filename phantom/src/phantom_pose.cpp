#include "msk/phantom/phantom_pose.h"

#include <cmath>
#include <sstream>

#include "msk/core/error.h"
#include "msk/imaging/grid.h"

namespace msk {

Eigen::Vector3d phantomPoseCentre() { return Eigen::Vector3d::Zero(); }

Eigen::Matrix4d phantomPoseMatrix(const PhantomPose& pose) {
  const Eigen::Matrix3d a = pose.scale * Grid::rotationXYZ(pose.rotationDegrees);
  const Eigen::Vector3d c = phantomPoseCentre();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = a;
  m.topRightCorner<3, 1>() = c + pose.translationMm - a * c;
  return m;
}

Eigen::Matrix4d phantomPoseInverse(const PhantomPose& pose) {
  const Eigen::Matrix3d a = Grid::rotationXYZ(pose.rotationDegrees).transpose() / pose.scale;
  const Eigen::Vector3d c = phantomPoseCentre();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = a;
  m.topRightCorner<3, 1>() = c - a * (c + pose.translationMm);
  return m;
}

void checkPhantomPose(const PhantomPose& pose) {
  std::ostringstream value;
  value.precision(17);
  const Eigen::Vector3d& r = pose.rotationDegrees;
  const Eigen::Vector3d& t = pose.translationMm;
  value << r[0] << ',' << r[1] << ',' << r[2] << ',' << t[0] << ',' << t[1] << ',' << t[2] << ',' << pose.scale;
  if (!r.allFinite() || !t.allFinite() || !std::isfinite(pose.scale))
    throw ParameterError("--pose", value.str(), "every number must be finite");
  if (r.cwiseAbs().maxCoeff() > 180)
    throw ParameterError("--pose", value.str(), "rotation angles must be in [-180, 180] degrees");
  if (t.norm() > 1000) throw ParameterError("--pose", value.str(), "the translation must be at most 1000 mm long");
  if (pose.scale < 0.5 || pose.scale > 2) throw ParameterError("--pose", value.str(), "the scale must be in [0.5, 2]");
}

}  // namespace msk
