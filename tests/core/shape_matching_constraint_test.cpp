#include "msk/core/shape_matching_constraint.h"

#include <gtest/gtest.h>

#include <random>

#include "msk/core/error.h"
#include "msk/test/shapes.h"

namespace {
using msk::test::uniformVector;
}  // namespace

TEST(ShapeMatching, PullsTowardTheFittedReferenceWithoutNetMomentum) {
  std::mt19937 rng(5);
  msk::Points ref(40, 3);
  for (int i = 0; i < 40; ++i) ref.row(i) = uniformVector(rng, 10).transpose();
  msk::Points p = ref;
  p.col(0) *= 1.3;  // a non-rigid stretch
  p.rowwise() += Eigen::RowVector3d(3, 4, 5);
  const msk::Points before = p;
  msk::ShapeMatchingConstraint c(ref, msk::PriorTransform::Rigid, 0.5);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(40);
  c.project(p, w);
  EXPECT_LT((p - before).colwise().sum().norm(), 1e-9);  // linear momentum
  // Projecting to λ = 1 gives a rigid copy of the reference.
  c.setLambda(1.0);
  c.project(p, w);
  for (int i = 0; i < 40; ++i)
    for (int j = i + 1; j < 40; j += 7)
      EXPECT_NEAR((p.row(i) - p.row(j)).norm(), (ref.row(i) - ref.row(j)).norm(), 1e-9);
  EXPECT_THROW(c.setLambda(1.5), msk::ParameterError);
}
