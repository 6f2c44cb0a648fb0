#include "msk/core/winding_number.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "msk/core/error.h"
#include "msk/test/shapes.h"

namespace {
/// Two nested outward spheres in one mesh: points inside the inner one are covered twice.
msk::TriangleMesh nestedSpheres() {
  return msk::test::joinedMeshes(msk::makeIcosphere(10, 3), msk::makeIcosphere(5, 3, {1, 0, 0}));
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
    const double dz = u(rng), dy = u(rng), dx = u(rng);  // one by one: z, y, x, as the test's figures were made
    const Eigen::Vector3d q(3 + dx, -2 + dy, 1 + dz);
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
  for (const auto& [q, layers] :
       {std::pair{Eigen::Vector3d(1, 0, 0), 2.0}, std::pair{Eigen::Vector3d(1, 0, 3), 2.0},
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

// Queried with the surface's current positions, the winding number follows the nearby triangles however far they
// moved since it was built: a point the stale surface has inside is outside once that part of the surface has moved
// past it, and the far field (dipoles) keeps the answer elsewhere.
TEST(WindingNumber, LivePositionsFollowTheMovedSurface) {
  msk::TriangleMesh m = msk::makeIcosphere(10, 4);
  const msk::WindingNumber wn(m.vertices, m.faces);
  const Eigen::Vector3d q(9.7, 0, 0);
  EXPECT_TRUE(wn.inside(q));
  // Dent the sphere by 0.6 mm around +x (corrections move a partner by less than that per pass): q is now outside.
  msk::Points moved = m.vertices;
  for (int v = 0; v < moved.rows(); ++v) {
    const double x = moved(v, 0);
    if (x > 8) moved(v, 0) = x - 0.6 * (x - 8) / 2;
  }
  double exactMoved = 0;
  for (int t = 0; t < m.faceCount(); ++t)
    exactMoved +=
        msk::triangleWindingNumber(q, moved.row(m.faces(t, 0)).transpose(), moved.row(m.faces(t, 1)).transpose(),
                                   moved.row(m.faces(t, 2)).transpose());
  EXPECT_NEAR(exactMoved, 0.0, 1e-9);
  EXPECT_TRUE(wn.inside(q));          // the stale surface
  EXPECT_FALSE(wn.inside(q, moved));  // the moved one
  // The dipoles of the moved clusters near the dent are stale: about 0.1 off here, far from the ½ that decides.
  EXPECT_NEAR(wn.at(q, moved), 0.0, 0.15);
  EXPECT_NEAR(wn.at(Eigen::Vector3d(-5, 1, 0), moved), 1.0, 0.05);  // far from the dent: unchanged
  EXPECT_NEAR(wn.at(Eigen::Vector3d(-30, 1, 0), moved), 0.0, 0.05);
  // The faces may index a larger stacked array: live positions are read through the faces as given.
  msk::Points stacked(moved.rows() + 7, 3);
  stacked.setZero();
  msk::TriangleMesh shifted = m;
  shifted.faces.array() += 7;
  stacked.bottomRows(moved.rows()) = moved;
  msk::Points original(m.vertexCount() + 7, 3);
  original.setZero();
  original.bottomRows(m.vertexCount()) = m.vertices;
  const msk::WindingNumber wn2(original, shifted.faces);
  EXPECT_NEAR(wn2.at(q, stacked), wn.at(q, moved), 1e-12);
  EXPECT_THROW(wn2.at(q, moved), msk::Error);  // fewer rows than the array it was built on
}

// On a surface of 20 000 triangles with leaves of one edge (as collision surfaces build it), points half an edge in
// and out along the normal get the exact sum's answer, and the tree's value stays within 0.05 of it.
TEST(WindingNumber, TreeMatchesExactNearALargeSurface) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(50, 5, {4, -7, 2});
  const double edge = msk::meanEdgeLength(sphere);
  const msk::WindingNumber wn(sphere.vertices, sphere.faces, edge);
  const Eigen::Vector3d centre(4, -7, 2);
  double worst = 0;
  for (int v = 0; v < sphere.vertexCount(); v += 37) {
    const Eigen::Vector3d x = sphere.vertices.row(v).transpose(), n = (x - centre).normalized();
    for (double off : {-0.5 * edge, 0.5 * edge}) {
      const Eigen::Vector3d q = x + off * n;
      const double approx = wn.at(q), exact = wn.exactAt(q);
      EXPECT_NEAR(exact, off < 0 ? 1.0 : 0.0, 1e-9);
      EXPECT_EQ(approx > 0.5, off < 0) << "vertex " << v << " offset " << off;
      worst = std::max(worst, std::abs(approx - exact));
    }
  }
  EXPECT_LT(worst, 0.05);
}

// A point a hair's breadth from a face sees that face as almost half of its view (a solid angle near ±2π): the near
// triangles' angles, summed as one product, still give 1 just inside and 0 just outside.
TEST(WindingNumber, PointsAHairFromAFace) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(10, 3);
  const msk::WindingNumber wn(sphere.vertices, sphere.faces);
  for (int f = 0; f < sphere.faceCount(); f += 13) {
    const Eigen::Vector3d a = sphere.vertices.row(sphere.faces(f, 0)), b = sphere.vertices.row(sphere.faces(f, 1)),
                          c = sphere.vertices.row(sphere.faces(f, 2));
    const Eigen::Vector3d centroid = (a + b + c) / 3.0, n = (b - a).cross(c - a).normalized();
    for (double off : {1e-9, 1e-6, 1e-3}) {
      EXPECT_NEAR(wn.at(centroid - off * n), 1.0, 0.05) << "face " << f << " inside by " << off;
      EXPECT_NEAR(wn.at(centroid + off * n), 0.0, 0.05) << "face " << f << " outside by " << off;
    }
  }
}
