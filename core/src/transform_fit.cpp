#include "msk/core/transform_fit.h"

#include <Eigen/Dense>

#include "msk/core/error.h"

namespace msk {

Eigen::Matrix4d fitTransform(const Points& from, const Points& to, const Eigen::VectorXd& weights,
                             PriorTransform transform) {
  MSK_ASSERT(from.rows() == to.rows() && from.rows() == weights.size(), "fitTransform: size mismatch");
  const double wsum = weights.sum();
  MSK_ASSERT(wsum > 0, "fitTransform: weights sum to zero");
  const Eigen::RowVector3d cf = (weights.asDiagonal() * from).colwise().sum() / wsum;
  const Eigen::RowVector3d ct = (weights.asDiagonal() * to).colwise().sum() / wsum;
  const Eigen::MatrixX3d a = from.rowwise() - cf, b = to.rowwise() - ct;
  Eigen::Matrix3d m;
  if (transform == PriorTransform::Affine) {
    const Eigen::Matrix3d aa = a.transpose() * weights.asDiagonal() * a;
    const Eigen::Matrix3d ab = a.transpose() * weights.asDiagonal() * b;
    Eigen::FullPivLU<Eigen::Matrix3d> lu(aa);
    if (!lu.isInvertible())
      transform = PriorTransform::Similarity;  // planar or collinear input
    else
      m = (lu.solve(ab)).transpose();
  }
  if (transform != PriorTransform::Affine) {
    const Eigen::Matrix3d cov = b.transpose() * weights.asDiagonal() * a / wsum;  // Σ w (to)(from)ᵀ
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) s(2, 2) = -1;
    const Eigen::Matrix3d r = svd.matrixU() * s * svd.matrixV().transpose();
    double scale = 1.0;
    if (transform == PriorTransform::Similarity) {
      const double varFrom = (weights.asDiagonal() * a.rowwise().squaredNorm()).sum() / wsum;
      if (varFrom > 0) scale = (svd.singularValues().asDiagonal() * s).trace() / varFrom;
    }
    m = scale * r;
  }
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = m;
  t.topRightCorner<3, 1>() = ct.transpose() - m * cf.transpose();
  return t;
}

}  // namespace msk
