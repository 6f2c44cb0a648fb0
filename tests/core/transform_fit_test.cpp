#include "msk/core/transform_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>
#include <utility>

#include "msk/test/shapes.h"

namespace {
using msk::test::uniformVector;
}  // namespace

TEST(FitTransform, RecoversRigidSimilarityAndAffine) {
  std::mt19937 rng(3);
  msk::Points from(50, 3);
  for (int i = 0; i < 50; ++i) from.row(i) = uniformVector(rng, 20).transpose();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(5, -3, 2);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(50);
  for (auto [kind, m] :
       {std::pair{msk::PriorTransform::Rigid, Eigen::Matrix3d(r)},
        std::pair{msk::PriorTransform::Similarity, Eigen::Matrix3d(1.07 * r)},
        std::pair{msk::PriorTransform::Affine, Eigen::Matrix3d(r * Eigen::Vector3d(1.1, 0.9, 1.2).asDiagonal())}}) {
    msk::Points to = (from * m.transpose()).rowwise() + t.transpose();
    const Eigen::Matrix4d fit = msk::fitTransform(from, to, w, kind);
    EXPECT_LT((fit.topLeftCorner<3, 3>() - m).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((fit.topRightCorner<3, 1>() - t).cwiseAbs().maxCoeff(), 1e-9);
  }
}
