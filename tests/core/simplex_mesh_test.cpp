#include "msk/core/simplex_mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "msk/core/error.h"
#include "msk/test/shapes.h"

namespace {

using Vec3 = Eigen::Vector3d;

/// Ellipsoid 40×20×15 mm (semi-axes 20, 10, 7.5) with a sinusoidal bump around its long axis.
msk::TriangleMesh bumpyEllipsoid(int subdivisions) {
  msk::TriangleMesh m = msk::makeIcosphere(1.0, subdivisions);
  for (int i = 0; i < m.vertexCount(); ++i) {
    const Vec3 u = m.vertices.row(i);
    const double bump = 1.0 + 0.12 * std::sin(4.0 * std::atan2(u.z(), u.y())) * std::sin(M_PI * u.x());
    m.vertices.row(i) << 20.0 * u.x(), 10.0 * u.y() * bump, 7.5 * u.z() * bump;
  }
  return m;
}

/// A torus (major radius 20 mm, minor 6 mm) of nu × nv quads split into outward triangles: genus 1.
msk::TriangleMesh torus(int nu, int nv) {
  msk::TriangleMesh m;
  m.vertices.resize(nu * nv, 3);
  m.faces.resize(2 * nu * nv, 3);
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      m.vertices.row(i * nv + j) << (20 + 6 * std::cos(v)) * std::cos(u), (20 + 6 * std::cos(v)) * std::sin(u),
          6 * std::sin(v);
      const int a = i * nv + j, b = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv,
                d = i * nv + (j + 1) % nv;
      m.faces.row(2 * (i * nv + j)) << a, b, c;
      m.faces.row(2 * (i * nv + j) + 1) << a, c, d;
    }
  if (msk::enclosedVolume(m) < 0) msk::flipFaces(m);
  return m;
}

/// Max vertex distance between two meshes with the same vertex order.
double maxDeviation(const msk::Points& a, const msk::Points& b) { return (a - b).rowwise().norm().maxCoeff(); }

/// Plain reconstruction: every triangle vertex at the centroid of its simplex face.
msk::Points faceCentroids(const msk::SimplexMesh& s) {
  msk::Points c(s.faceCount(), 3);
  for (int f = 0; f < s.faceCount(); ++f) {
    Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
    for (int i = s.faceOffsets[f]; i < s.faceOffsets[f + 1]; ++i) sum += s.positions.row(s.faceVertices[i]);
    c.row(f) = sum / static_cast<double>(s.faceOffsets[f + 1] - s.faceOffsets[f]);
  }
  return c;
}

/// Round trip triangles → simplex → triangles; returns corrected and plain errors relative to the mean edge length.
void roundTrip(const msk::TriangleMesh& m, const char* name, double& corrected, double& plain) {
  SCOPED_TRACE(name);
  const double edge = msk::meanEdgeLength(m);
  const msk::SimplexMesh s = msk::simplexFromTriangles(m);
  const msk::TriangleMesh back = msk::trianglesFromSimplex(s);
  ASSERT_EQ(back.vertexCount(), m.vertexCount());
  ASSERT_EQ(back.faces, m.faces);  // the dual of the dual is the same triangulation, same winding
  EXPECT_EQ(msk::closedMeshProblem(back), "");
  corrected = maxDeviation(back.vertices, m.vertices) / edge;
  plain = maxDeviation(faceCentroids(s), m.vertices) / edge;
}

}  // namespace

TEST(SimplexMesh, DualOfIcosphereHasOutwardNeighbourOrderAndCounterClockwiseFaces) {
  const msk::TriangleMesh m = msk::makeIcosphere(10.0, 2);
  const msk::SimplexMesh s = msk::simplexFromTriangles(m);
  EXPECT_EQ(msk::simplexMeshProblem(s), "");
  ASSERT_EQ(s.vertexCount(), m.faceCount());
  ASSERT_EQ(s.faceCount(), m.vertexCount());
  for (int t = 0; t < s.vertexCount(); ++t) {
    const Vec3 c = (m.vertices.row(m.faces(t, 0)) + m.vertices.row(m.faces(t, 1)) + m.vertices.row(m.faces(t, 2))) / 3;
    EXPECT_LT((Vec3(s.positions.row(t)) - c).norm(), 1e-12);
    const Vec3 p1 = s.positions.row(s.neighbors(t, 0)), p2 = s.positions.row(s.neighbors(t, 1)),
               p3 = s.positions.row(s.neighbors(t, 2));
    EXPECT_GT((p2 - p1).cross(p3 - p1).normalized().dot(c.normalized()), 0.9) << "vertex " << t;
  }
  // Face f is the ring around triangle-mesh vertex f, counter-clockwise seen from outside.
  for (int f = 0; f < s.faceCount(); ++f) {
    Vec3 area = Vec3::Zero();
    const int b = s.faceOffsets[f], e = s.faceOffsets[f + 1];
    EXPECT_GE(e - b, 5);
    for (int i = b; i < e; ++i) {
      const int t = s.faceVertices[i];
      EXPECT_TRUE((m.faces.row(t).array() == f).any());
      area += Vec3(s.positions.row(t)).cross(Vec3(s.positions.row(s.faceVertices[i + 1 == e ? b : i + 1])));
    }
    EXPECT_GT(area.normalized().dot(Vec3(m.vertices.row(f)).normalized()), 0.99);
  }
}

TEST(SimplexMesh, PointDataIsAveragedBothWays) {
  msk::TriangleMesh m = msk::makeIcosphere(5.0, 1);
  m.pointData["x"] = m.vertices.col(0);
  const msk::SimplexMesh s = msk::simplexFromTriangles(m);
  ASSERT_EQ(s.pointData.at("x").size(), s.vertexCount());
  for (int t = 0; t < s.vertexCount(); ++t) EXPECT_NEAR(s.pointData.at("x")[t], s.positions(t, 0), 1e-12);
  const msk::TriangleMesh back = msk::trianglesFromSimplex(s);
  const msk::Points c = faceCentroids(s);
  for (int v = 0; v < back.vertexCount(); ++v) EXPECT_NEAR(back.pointData.at("x")[v], c(v, 0), 1e-12);
}

TEST(SimplexMesh, OpenOrNonManifoldTrianglesAreRejected) {
  msk::TriangleMesh open = msk::makeIcosphere(5.0, 1);
  open.faces.conservativeResize(open.faceCount() - 1, 3);
  const std::string why = msk::closedMeshProblem(open);
  ASSERT_NE(why, "");
  try {
    msk::simplexFromTriangles(open);
    FAIL() << "no exception";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
  }
  // Two spheres touching at one vertex: closed and oriented, but that vertex has two fans.
  const msk::TriangleMesh a = msk::makeIcosphere(1.0, 0), b = msk::makeIcosphere(1.0, 0, Vec3(2, 0, 0));
  msk::TriangleMesh pinch;
  pinch.vertices.resize(a.vertexCount() + b.vertexCount(), 3);
  pinch.vertices << a.vertices, b.vertices;
  pinch.faces.resize(a.faceCount() + b.faceCount(), 3);
  pinch.faces << a.faces, (b.faces.array() + a.vertexCount()).matrix();
  pinch.faces = (pinch.faces.array() == a.vertexCount() + 1).select(0, pinch.faces);  // glue b's vertex 1 to a's 0
  ASSERT_EQ(msk::closedMeshProblem(pinch), "");
  try {
    msk::simplexFromTriangles(pinch);
    FAIL() << "no exception";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("non-manifold"), std::string::npos) << e.what();
  }
}

TEST(SimplexMesh, ProblemChecksTablesForK1K2K3) {
  // k = 1: a closed polygon.
  msk::SimplexMesh curve;
  curve.k = 1;
  const int n = 8;
  curve.positions.resize(n, 3);
  curve.neighbors.resize(n, 2);
  for (int i = 0; i < n; ++i) {
    curve.positions.row(i) << std::cos(i * 2 * M_PI / n), std::sin(i * 2 * M_PI / n), 0;
    curve.neighbors.row(i) << (i + n - 1) % n, (i + 1) % n;
  }
  EXPECT_EQ(msk::simplexMeshProblem(curve), "");
  msk::SimplexMesh bad = curve;
  bad.neighbors(2, 1) = 5;  // 5 does not list 2
  EXPECT_NE(msk::simplexMeshProblem(bad).find("not symmetric"), std::string::npos);
  bad = curve;
  bad.neighbors(2, 1) = 2;
  EXPECT_NE(msk::simplexMeshProblem(bad).find("its own"), std::string::npos);
  bad = curve;
  bad.neighbors(2, 1) = 1;
  EXPECT_NE(msk::simplexMeshProblem(bad).find("twice"), std::string::npos);
  bad = curve;
  bad.neighbors(2, 1) = n;
  EXPECT_NE(msk::simplexMeshProblem(bad).find("out of range"), std::string::npos);
  bad = curve;
  bad.neighbors.resize(n, 3);
  EXPECT_NE(msk::simplexMeshProblem(bad).find("expected"), std::string::npos);

  // k = 3: the complete graph K5 (4 distinct neighbours each, the boundary of a 4-simplex).
  msk::SimplexMesh vol;
  vol.k = 3;
  vol.positions = msk::Points::Random(5, 3);
  vol.neighbors.resize(5, 4);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 4; ++j) vol.neighbors(i, j) = (i + 1 + j) % 5;
  EXPECT_EQ(msk::simplexMeshProblem(vol), "");
  bad = vol;
  bad.neighbors(0, 3) = 1;
  EXPECT_NE(msk::simplexMeshProblem(bad).find("twice"), std::string::npos);
  bad = vol;
  bad.positions(3, 1) = NAN;
  EXPECT_NE(msk::simplexMeshProblem(bad).find("non-finite"), std::string::npos);
  bad = vol;
  bad.pointData["w"] = Eigen::VectorXd::Zero(4);
  EXPECT_NE(msk::simplexMeshProblem(bad).find("'w'"), std::string::npos);
  bad = vol;
  bad.k = 4;
  EXPECT_NE(msk::simplexMeshProblem(bad), "");

  // k = 2: a valid dual, then broken neighbour order and broken faces.
  const msk::SimplexMesh s = msk::simplexFromTriangles(msk::makeIcosphere(3.0, 1));
  EXPECT_EQ(msk::simplexMeshProblem(s), "");
  bad = s;
  std::swap(bad.neighbors(4, 1), bad.neighbors(4, 2));  // reversed orientation at one vertex
  EXPECT_NE(msk::simplexMeshProblem(bad).find("neighbour order"), std::string::npos);
  bad = s;
  bad.faceOffsets.back() -= 1;
  EXPECT_NE(msk::simplexMeshProblem(bad), "");
  bad = s;
  std::swap(bad.faceVertices[0], bad.faceVertices[1]);
  EXPECT_NE(msk::simplexMeshProblem(bad), "");
  // Faces can be rebuilt from the neighbour table alone.
  msk::SimplexMesh bare = s;
  bare.faceOffsets.clear();
  bare.faceVertices.clear();
  EXPECT_EQ(msk::simplexMeshProblem(bare), "");
  msk::buildSimplexFaces(bare);
  EXPECT_EQ(msk::simplexMeshProblem(bare), "");
  EXPECT_EQ(bare.faceCount(), s.faceCount());
  EXPECT_EQ(msk::trianglesFromSimplex(bare).vertexCount(), s.faceCount());
}

TEST(SimplexMesh, RoundTripRestoresIcosphere) {
  double corrected = 0, plain = 0;
  roundTrip(msk::makeIcosphere(20.0, 3), "icosphere R=20 s=3", corrected, plain);
  EXPECT_LE(corrected, 0.02);
  EXPECT_LT(corrected, plain);
  roundTrip(msk::makeIcosphere(20.0, 0), "icosahedron R=20", corrected, plain);
  EXPECT_LE(corrected, 0.02);
  EXPECT_LT(corrected, plain);
}

TEST(SimplexMesh, RoundTripRestoresBumpyEllipsoid) {
  double corrected = 0, plain = 0;
  roundTrip(bumpyEllipsoid(4), "bumpy ellipsoid 40x20x15", corrected, plain);
  EXPECT_LE(corrected, 0.02);
  EXPECT_LT(corrected, plain);
}

TEST(SimplexMesh, RoundTripDoesNotShrinkTheVolume) {
  const msk::TriangleMesh m = bumpyEllipsoid(3);
  const msk::SimplexMesh s = msk::simplexFromTriangles(m);
  msk::TriangleMesh plain = msk::trianglesFromSimplex(s);
  const double v0 = msk::enclosedVolume(m), v1 = msk::enclosedVolume(plain);
  plain.vertices = faceCentroids(s);
  const double v2 = msk::enclosedVolume(plain);
  EXPECT_NEAR(v1, v0, 1e-3 * v0);
  EXPECT_LT(v2, v0 * 0.99);
}

TEST(SimplexMesh, RoundTripRestoresTorus) {
  double corrected = 0, plain = 0;
  roundTrip(torus(48, 24), "torus 20/6", corrected, plain);
  EXPECT_LE(corrected, 0.02);
  EXPECT_LT(corrected, plain);
}

// The round trip at about 10⁴ and 2·10⁴ simplex vertices (BM_SimplexConversion in bench/mesh_bench.cpp times it on
// spheres of those sizes).
TEST(SimplexMesh, RoundTripAtTenAndTwentyThousandVertices) {
  for (const msk::TriangleMesh& m : {torus(72, 70), bumpyEllipsoid(5)}) {
    const msk::TriangleMesh back = msk::trianglesFromSimplex(msk::simplexFromTriangles(m));
    EXPECT_LE(maxDeviation(back.vertices, m.vertices) / msk::meanEdgeLength(m), 0.02);
  }
}

TEST(SimplexMesh, VertexNormalsPointOutward) {
  const msk::SimplexMesh s = msk::simplexFromTriangles(msk::makeIcosphere(8.0, 3));
  const msk::Points n = msk::simplexVertexNormals(s);
  for (int v = 0; v < s.vertexCount(); ++v) {
    EXPECT_NEAR(n.row(v).norm(), 1.0, 1e-12);
    EXPECT_GT(n.row(v).dot(s.positions.row(v).normalized()), 0.995);
  }
}

// The per-step normals of a mesh known valid are those of the checked call, bit for bit, at moved positions too; a
// non-finite position is still an error, and a mesh without its face table gets the full check.
TEST(SimplexMesh, NormalsOfAValidMeshSkipOnlyTheTableChecks) {
  msk::SimplexMesh s = msk::simplexFromTriangles(msk::makeIcosphere(8.0, 3));
  std::mt19937 rng(2);
  std::normal_distribution<double> g(0, 0.3);
  for (int v = 0; v < s.vertexCount(); ++v) s.positions.row(v) += Eigen::RowVector3d(g(rng), g(rng), g(rng));
  const msk::Points checked = msk::simplexVertexNormals(s), valid = msk::validSimplexVertexNormals(s);
  EXPECT_TRUE((checked.array() == valid.array()).all());
  msk::SimplexMesh broken = s;
  broken.positions(5, 1) = std::nan("");
  EXPECT_THROW(msk::validSimplexVertexNormals(broken), msk::Error);
  msk::SimplexMesh bare = s;
  bare.faceOffsets.clear();
  bare.faceVertices.clear();
  bare.neighbors(0, 0) = bare.neighbors(0, 1);  // a vertex listing one neighbour twice
  EXPECT_THROW(msk::validSimplexVertexNormals(bare), msk::Error);
}

TEST(ClosestPoint, EveryVoronoiRegion) {
  const Vec3 a(0, 0, 0), b(2, 0, 0), c(0, 2, 0);
  struct Case {
    Vec3 p, q, bary;
  };
  const Case cases[] = {
      {{-1, -1, 1}, {0, 0, 0}, {1, 0, 0}},                 // vertex a
      {{3, -1, -2}, {2, 0, 0}, {0, 1, 0}},                 // vertex b
      {{-1, 3, 0.5}, {0, 2, 0}, {0, 0, 1}},                // vertex c
      {{1, -1, 2}, {1, 0, 0}, {0.5, 0.5, 0}},              // edge ab
      {{-1, 0.5, 0}, {0, 0.5, 0}, {0.75, 0, 0.25}},        // edge ca
      {{2, 2, 1}, {1, 1, 0}, {0, 0.5, 0.5}},               // edge bc
      {{0.5, 0.5, -3}, {0.5, 0.5, 0}, {0.5, 0.25, 0.25}},  // face
  };
  for (const Case& k : cases) {
    Vec3 bary;
    const Vec3 q = msk::closestPointOnTriangle(k.p, a, b, c, &bary);
    EXPECT_LT((q - k.q).norm(), 1e-14) << k.p.transpose();
    EXPECT_LT((bary - k.bary).norm(), 1e-14) << k.p.transpose();
  }
  // Random triangles: the result is at least as close as any sampled point of the triangle, and its barycentric
  // weights rebuild it.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    // One by one, z, y, x within each vector (the order of a call's arguments is unspecified).
    auto draw = [&](double scale) {
      const double z = u(rng), y = u(rng), x = u(rng);
      return Vec3(scale * x, scale * y, scale * z);
    };
    const Vec3 ta = draw(1), tb = draw(1), tc = draw(1);
    const Vec3 p = draw(2);
    Vec3 bary;
    const Vec3 q = msk::closestPointOnTriangle(p, ta, tb, tc, &bary);
    EXPECT_LT((bary[0] * ta + bary[1] * tb + bary[2] * tc - q).norm(), 1e-12);
    EXPECT_NEAR(bary.sum(), 1.0, 1e-12);
    EXPECT_GE(bary.minCoeff(), -1e-12);
    double sampled = 1e300;
    for (int i = 0; i <= 40; ++i)
      for (int j = 0; i + j <= 40; ++j)
        sampled = std::min(sampled, (p - (ta + (i / 40.0) * (tb - ta) + (j / 40.0) * (tc - ta))).norm());
    EXPECT_LE((q - p).norm(), sampled + 1e-12);
  }
  // Degenerate triangles give finite answers on the segment.
  Vec3 bary;
  const Vec3 q = msk::closestPointOnTriangle(Vec3(1, 1, 0), a, b, Vec3(1, 0, 0), &bary);
  EXPECT_LT((q - Vec3(1, 0, 0)).norm(), 1e-14);
  EXPECT_TRUE(bary.allFinite());
  const Vec3 q2 = msk::closestPointOnTriangle(Vec3(1, 1, 0), a, a, a, &bary);
  EXPECT_LT(q2.norm(), 1e-14);
}

TEST(SurfaceTransfer, GridSearchMatchesBruteForce) {
  msk::TriangleMesh m = msk::makeIcosphere(10.0, 3);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < m.vertexCount(); ++i) m.vertices.row(i) *= 1.0 + 0.15 * u(rng);  // random-ish radii
  m.vertices.col(0) *= 2.5;
  msk::Points targets(3000, 3);
  for (int i = 0; i < targets.rows(); ++i) targets.row(i) << 40 * u(rng), 20 * u(rng), 20 * u(rng);
  targets.row(0) << 1e3, -5e2, 2e2;  // far outside the grid
  targets.row(1) << 0, 0, 0;         // deep inside
  const msk::SurfaceTransfer transfer(m, targets);
  const Eigen::MatrixXd q = transfer.apply(m.vertices);
  for (int i = 0; i < targets.rows(); ++i) {
    const Vec3 p = targets.row(i);
    double best = 1e300;
    for (int t = 0; t < m.faceCount(); ++t) {
      const Vec3 a = m.vertices.row(m.faces(t, 0)), b = m.vertices.row(m.faces(t, 1)),
                 c = m.vertices.row(m.faces(t, 2));
      best = std::min(best, (msk::closestPointOnTriangle(p, a, b, c) - p).norm());
    }
    EXPECT_NEAR(transfer.distances()[i], best, 1e-12) << i;
    EXPECT_NEAR((Vec3(q.row(i)) - p).norm(), best, 1e-9) << i;
  }
}

TEST(SurfaceTransfer, LinearFunctionCarriesAcrossResolutions) {
  const double r = 20.0;
  const msk::TriangleMesh coarse = msk::makeIcosphere(r, 3);
  const msk::TriangleMesh finer = msk::makeIcosphere(r, 5);
  const msk::Points targets = 0.98 * finer.vertices;
  const Vec3 a(0.3, -1.2, 0.7);
  const double b = 4.0;
  const Eigen::VectorXd f = coarse.vertices * a + Eigen::VectorXd::Constant(coarse.vertexCount(), b);
  const msk::SurfaceTransfer transfer(coarse, targets);
  const Eigen::VectorXd g = transfer.apply(f);
  const Eigen::MatrixXd bound = transfer.apply(coarse.vertices);  // the bound points themselves
  double worstExact = 0, worst = 0;
  for (int i = 0; i < targets.rows(); ++i) {
    worstExact = std::max(worstExact, std::fabs(g[i] - (bound.row(i).dot(a) + b)));
    worst = std::max(worst, std::fabs(g[i] - (finer.vertices.row(i).dot(a) + b)));  // vs f on the finer sphere
  }
  const double edge = msk::meanEdgeLength(coarse);
  EXPECT_LT(worstExact, 1e-10);
  EXPECT_LT(worst, 0.05 * a.norm() * edge);
  EXPECT_THROW(transfer.apply(Eigen::MatrixXd::Zero(3, 1)), msk::Error);
  EXPECT_THROW(msk::SurfaceTransfer(msk::TriangleMesh(), targets), msk::Error);
}

// 50 000 points within ±10 % of a sphere's radius bind within 2.5 mm of its 5120 triangles (BM_SurfaceTransfer in
// bench/mesh_bench.cpp times it).
TEST(SurfaceTransfer, FiftyThousandPointsNearASphereBindWithinReach) {
  const msk::TriangleMesh source = msk::makeIcosphere(20.0, 4);
  const msk::SurfaceTransfer transfer(source, msk::test::pointsNearSphere(50000, 20.0, 0.1, 5));
  EXPECT_LT(transfer.distances().maxCoeff(), 2.5);
}
