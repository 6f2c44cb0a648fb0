#include "msk/imaging/grid.h"

#include <Eigen/Geometry>
#include <cmath>

namespace msk {

Eigen::Matrix4d Grid::voxelToWorld() const {
  Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
  a.topLeftCorner<3, 3>() = direction * spacing.asDiagonal();
  a.topRightCorner<3, 1>() = origin;
  return a;
}

Eigen::Matrix4d Grid::worldToVoxel() const {
  Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
  a.topLeftCorner<3, 3>() = spacing.cwiseInverse().asDiagonal() * direction.transpose();
  a.topRightCorner<3, 1>() = -a.topLeftCorner<3, 3>() * origin;
  return a;
}

std::array<Eigen::Vector3d, 2> Grid::worldBounds() const {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = Eigen::Vector3d::Constant(-INFINITY);
  for (int c = 0; c < 8; ++c) {
    Eigen::Vector3d ijk((c & 1) ? dims[0] - 1 : 0, (c & 2) ? dims[1] - 1 : 0, (c & 4) ? dims[2] - 1 : 0);
    Eigen::Vector3d w = toWorld(ijk);
    lo = lo.cwiseMin(w);
    hi = hi.cwiseMax(w);
  }
  return {lo, hi};
}

bool Grid::sameGeometry(const Grid& o, double tol) const {
  return dims == o.dims && (voxelToWorld() - o.voxelToWorld()).cwiseAbs().maxCoeff() <= tol;
}

std::string Grid::problem() const {
  if ((dims.array() <= 0).any())
    return "dimensions must be positive (" + std::to_string(dims[0]) + "×" + std::to_string(dims[1]) + "×" +
           std::to_string(dims[2]) + ")";
  if (!spacing.allFinite() || (spacing.array() <= 0).any()) return "voxel spacing must be positive and finite";
  if (!direction.allFinite() || !origin.allFinite()) return "non-finite direction or origin";
  if ((direction.transpose() * direction - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-4)
    return "direction matrix is not orthonormal";
  return "";
}

bool Grid::fromAffine(const Eigen::Vector3i& dims, const Eigen::Matrix4d& affine, Grid& out, double tolDegrees) {
  if (!affine.allFinite()) return false;
  Eigen::Matrix3d m = affine.topLeftCorner<3, 3>();
  Eigen::Vector3d s = m.colwise().norm().transpose();
  if ((s.array() <= 0).any()) return false;
  Eigen::Matrix3d d = m * s.cwiseInverse().asDiagonal();
  const double maxCos = std::sin(tolDegrees * M_PI / 180.0);
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      if (std::fabs(d.col(a).dot(d.col(b))) > maxCos) return false;
  // Re-orthonormalise (polar decomposition) so round-off does not accumulate.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(d, Eigen::ComputeFullU | Eigen::ComputeFullV);
  out.dims = dims;
  out.spacing = s;
  out.direction = svd.matrixU() * svd.matrixV().transpose();
  out.origin = affine.topRightCorner<3, 1>();
  return true;
}

Eigen::Matrix3d Grid::rotationXYZ(const Eigen::Vector3d& deg) {
  const double k = M_PI / 180.0;
  return (Eigen::AngleAxisd(deg[2] * k, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(deg[1] * k, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(deg[0] * k, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace msk
