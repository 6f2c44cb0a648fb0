#include "msk/core/target_constraint.h"

#include <gtest/gtest.h>

#include "msk/core/error.h"

TEST(TargetKernel, MovesFreeParticlesOnly) {
  Eigen::Vector3d dp;
  ASSERT_TRUE(msk::targetCorrection({0, 0, 0}, {2, 0, 0}, 1.0, 0.25, dp));
  EXPECT_NEAR(dp.x(), 0.5, 1e-15);
  EXPECT_FALSE(msk::targetCorrection({0, 0, 0}, {2, 0, 0}, 0.0, 0.25, dp));
}

TEST(TargetConstraints, RefusesNegativeStiffness) { EXPECT_THROW(msk::TargetConstraints(-0.1), msk::ParameterError); }
