#include "msk/core/winding_number.h"

#include <random>

#include <gtest/gtest.h>

#include "msk/core/error.h"

namespace {
/// Two nested outward spheres in one mesh: points inside the inner one are covered twice.
msk::TriangleMesh nestedSpheres() {
  msk::TriangleMesh outer = msk::makeIcosphere(10, 3), inner = msk::makeIcosphere(5, 3, {1, 0, 0});
  msk::TriangleMesh m = outer;
  m.vertices.conservativeResize(outer.vertexCount() + inner.vertexCount(), 3);
  m.vertices.bottomRows(inner.vertexCount()) = inner.vertices;
  m.faces.conservativeResize(outer.faceCount() + inner.faceCount(), 3);
  m.faces.bottomRows(inner.faceCount()) = inner.faces.array() + outer.vertexCount();
  return m;
}
}  // namespace

// Far clusters replaced by dipoles keep the inside/outside answer of the exact sum everywhere but on the surface.
TEST(WindingNumber, ClusteredAgreesWithExactAwayFromTheSurface) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(10, 4, {3, -2, 1});
  const msk::WindingNumber wn(sphere.vertices, sphere.faces);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-16, 16);
  int inside = 0, n = 0;
  double worst = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d q(3 + u(rng), -2 + u(rng), 1 + u(rng));
    const double r = (q - Eigen::Vector3d(3, -2, 1)).norm();
    if (std::abs(r - 10) < 0.2) continue;  // the mesh is a polyhedron: skip the band it cuts
    ++n;
    const double approx = wn.at(q), exact = wn.exactAt(q);
    worst = std::max(worst, std::abs(approx - exact));
    EXPECT_EQ(approx > 0.5, r < 10) << "at radius " << r;
    EXPECT_NEAR(exact, r < 10 ? 1.0 : 0.0, 1e-9);
    inside += r < 10;
  }
  EXPECT_GT(inside, 100);
  EXPECT_LT(worst, 0.05) << "clustered winding number error over " << n << " points";
}

// Where a surface covers a point twice (as where a fold lies over the rest of the surface), the winding number counts
// the layers, and the clustered sum keeps the count.
TEST(WindingNumber, CountsLayers) {
  const msk::TriangleMesh m = nestedSpheres();
  const msk::WindingNumber wn(m.vertices, m.faces);
  for (const auto& [q, layers] : {std::pair{Eigen::Vector3d(1, 0, 0), 2.0}, std::pair{Eigen::Vector3d(1, 0, 3), 2.0},
                                  std::pair{Eigen::Vector3d(-8, 0, 0), 1.0}, std::pair{Eigen::Vector3d(0, 8, 0), 1.0},
                                  std::pair{Eigen::Vector3d(0, 0, 12), 0.0}, std::pair{Eigen::Vector3d(40, 3, 0), 0.0}}) {
    EXPECT_NEAR(wn.exactAt(q), layers, 1e-9) << q.transpose();
    EXPECT_NEAR(wn.at(q), layers, 0.05) << q.transpose();
  }
  EXPECT_THROW(msk::WindingNumber(m.vertices, m.faces, 0, 0.5), msk::ParameterError);
}

TEST(WindingNumber, SingleTriangleSolidAngle) {
  // A point on the axis of an equilateral triangle, very close: the triangle covers almost half the sphere of view.
  const Eigen::Vector3d a(1, 0, 0), b(-0.5, 0.866, 0), c(-0.5, -0.866, 0);
  EXPECT_NEAR(msk::triangleWindingNumber({0, 0, -1e-6}, a, b, c), 0.5, 1e-5);
  EXPECT_NEAR(msk::triangleWindingNumber({0, 0, 1e-6}, a, b, c), -0.5, 1e-5);
  EXPECT_NEAR(msk::triangleWindingNumber({0, 0, 1e6}, a, b, c), 0.0, 1e-9);
}
