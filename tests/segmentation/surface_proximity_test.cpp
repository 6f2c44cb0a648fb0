#include "msk/segmentation/surface_proximity.h"

#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "msk/core/error.h"

namespace {

using msk::makeIcosphere;
using V = Eigen::Vector3d;

}  // namespace

TEST(SurfaceProximity, SeparationOfSpheresApartIsTheirGap) {
  // Radius 10 spheres 1 mm and 20 mm apart. The vertex-to-surface bound can only over-estimate, by at most the
  // angular offset of the nearest vertex (~0.1 mm at 642 vertices).
  const msk::TriangleMesh a = makeIcosphere(10, 3);
  for (double gap : {1.0, 20.0}) {
    const double d = msk::surfaceSeparationMm(a, makeIcosphere(10, 3, V(20 + gap, 0, 0)));
    EXPECT_GE(d, gap - 0.06) << gap;  // faces lie inside the sphere by their sagitta (< 0.06 mm here)
    EXPECT_LE(d, gap + 0.2) << gap;
    EXPECT_EQ(msk::surfaceSeparationMm(makeIcosphere(10, 3, V(20 + gap, 0, 0)), a), d);
  }
}

TEST(SurfaceProximity, OverlapAndNestingAreZero) {
  const msk::TriangleMesh big = makeIcosphere(10, 3);
  // Crossing surfaces.
  EXPECT_EQ(msk::surfaceSeparationMm(big, makeIcosphere(10, 3, V(15, 0, 0))), 0.0);
  // One wholly inside the other, far from its surface (6 mm), in both argument orders.
  const msk::TriangleMesh small = makeIcosphere(3, 2, V(1, 0, 0));
  EXPECT_EQ(msk::surfaceSeparationMm(big, small), 0.0);
  EXPECT_EQ(msk::surfaceSeparationMm(small, big), 0.0);
  // The same small sphere outside: its true gap.
  EXPECT_NEAR(msk::surfaceSeparationMm(big, makeIcosphere(3, 2, V(0, 0, 20))), 7.0, 0.25);
}

TEST(SurfaceProximity, PairsWithinADistance) {
  const msk::TriangleMesh s0 = makeIcosphere(10, 3), s1 = makeIcosphere(10, 3, V(0, 40, 0)),
                          s2 = makeIcosphere(10, 3, V(21, 0, 0)), s3 = makeIcosphere(2, 2, V(0, 40, 1)),
                          s4 = makeIcosphere(10, 3, V(100, 100, 100));
  const std::vector<const msk::TriangleMesh*> all = {&s0, &s1, &s2, &s3, &s4};
  // s0–s2 1 mm apart, s1 holds s3, s0–s1 20 mm apart, s1–s2 25.2 mm, s0–s3 28 mm, s4 far from everything.
  const std::vector<std::pair<int, int>> near = {{0, 2}, {1, 3}};
  EXPECT_EQ(msk::surfacesWithin(all, 2.0), near);
  const std::vector<std::pair<int, int>> at21 = {{0, 1}, {0, 2}, {1, 3}};
  EXPECT_EQ(msk::surfacesWithin(all, 21.0), at21);
  EXPECT_TRUE(msk::surfacesWithin(all, 0.5).size() == 1u);  // only the nested pair
  EXPECT_TRUE(msk::surfacesWithin({&s0}, 5.0).empty());
  EXPECT_THROW(msk::surfacesWithin(all, -1.0), msk::ParameterError);
}
