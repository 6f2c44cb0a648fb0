#include "msk/imaging/surface_extraction.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>

#include "msk/core/error.h"
#include "msk/test/volumes.h"

namespace {

// An oblique, anisotropic grid centred on `center`, covering a cube of side `extentMm`.
msk::Grid obliqueGrid(const Eigen::Vector3d& center, double extentMm, bool improper) {
  msk::Grid g;
  g.spacing = {0.8, 0.9, 1.5};
  g.direction = msk::Grid::rotationXYZ({25, -40, 65});
  if (improper) g.direction.col(1) *= -1;
  for (int a = 0; a < 3; ++a) g.dims[a] = static_cast<int>(std::ceil(extentMm / g.spacing[a])) + 1;
  g.origin = center - g.direction * g.spacing.cwiseProduct((g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2);
  return g;
}

double maxRadiusError(const msk::TriangleMesh& m, const Eigen::Vector3d& c, double r) {
  double e = 0;
  for (int i = 0; i < m.vertexCount(); ++i) e = std::max(e, std::fabs((m.vertices.row(i).transpose() - c).norm() - r));
  return e;
}

}  // namespace

TEST(Isosurface, SphereSdfOnObliqueAnisotropicGridIsClosedAndExact) {
  const Eigen::Vector3d c(12.5, -30.25, 7.0);
  const double r = 15;
  for (bool improper : {false, true}) {
    SCOPED_TRACE(improper ? "det -1" : "det +1");
    const msk::Grid g = obliqueGrid(c, 40, improper);
    ASSERT_EQ(g.problem(), "");
    EXPECT_NEAR(g.direction.determinant(), improper ? -1.0 : 1.0, 1e-12);
    const msk::ImageF sdf = msk::test::sphereSdf(g, c, r);
    msk::IsosurfaceOptions below;
    below.inside = msk::IsoInside::Below;
    const msk::TriangleMesh m = msk::isosurface(sdf, 0.0, below);
    ASSERT_EQ(msk::closedMeshProblem(m), "");
    const double exact = 4.0 / 3.0 * M_PI * r * r * r;
    EXPECT_GT(msk::enclosedVolume(m), 0);
    EXPECT_NEAR(msk::enclosedVolume(m), exact, 0.02 * exact);
    EXPECT_LT(maxRadiusError(m, c, r), 0.1);

    // The same object seen as {−sdf > 0}.
    msk::ImageF neg = sdf;
    for (float& v : neg.data) v = -v;
    const msk::TriangleMesh m2 = msk::isosurface(neg, 0.0);
    EXPECT_EQ(m2.vertexCount(), m.vertexCount());
    EXPECT_NEAR(msk::enclosedVolume(m2), msk::enclosedVolume(m), 1e-6 * exact);

    const msk::TriangleMesh d = msk::decimateMesh(m, 1000);
    ASSERT_EQ(msk::closedMeshProblem(d), "");
    EXPECT_LE(d.vertexCount(), 1100);
    EXPECT_GE(d.vertexCount(), 900);
    EXPECT_GT(msk::enclosedVolume(d), 0);
    EXPECT_LT(maxRadiusError(d, c, r), 0.5);
  }
}

TEST(Isosurface, ObjectTouchingTheBorderIsClosedByPadding) {
  msk::Grid g;
  g.dims = {20, 20, 20};
  const Eigen::Vector3d c(0, 0, 0);  // sphere centred on voxel (0,0,0): only one octant is inside the grid
  const msk::ImageF sdf = msk::test::sphereSdf(g, c, 8.0);
  msk::IsosurfaceOptions below;
  below.inside = msk::IsoInside::Below;
  const msk::TriangleMesh m = msk::isosurface(sdf, 0.0, below);
  ASSERT_EQ(msk::closedMeshProblem(m), "");
  // About one octant of the ball (plus up to one voxel of padding layer).
  const double octant = 4.0 / 3.0 * M_PI * 512 / 8;
  EXPECT_GT(msk::enclosedVolume(m), 0.8 * octant);
  EXPECT_LT(msk::enclosedVolume(m), 1.6 * octant);
}

TEST(Isosurface, LargestComponentOptionAndEmptyField) {
  msk::Grid g;
  g.dims = {60, 30, 30};
  msk::ImageF f(g);
  const Eigen::Vector3d a(14, 15, 15), b(44, 15, 15);
  for (int k = 0; k < 30; ++k)
    for (int j = 0; j < 30; ++j)
      for (int i = 0; i < 60; ++i) {
        Eigen::Vector3d p(i, j, k);
        f.at(i, j, k) = static_cast<float>(std::max(10 - (p - a).norm(), 6 - (p - b).norm()));  // > 0 inside
      }
  const msk::TriangleMesh both = msk::isosurface(f, 0.0);
  ASSERT_EQ(msk::closedMeshProblem(both), "");
  msk::IsosurfaceOptions opts;
  opts.largestComponentOnly = true;
  const msk::TriangleMesh big = msk::isosurface(f, 0.0, opts);
  ASSERT_EQ(msk::closedMeshProblem(big), "");
  EXPECT_LT(big.vertexCount(), both.vertexCount());
  EXPECT_NEAR(msk::enclosedVolume(big), 4.0 / 3.0 * M_PI * 1000, 0.03 * 4.0 / 3.0 * M_PI * 1000);
  for (int i = 0; i < big.vertexCount(); ++i) EXPECT_LT(big.vertices(i, 0), 29.0);

  msk::ImageF empty(g, -1.f);
  EXPECT_EQ(msk::isosurface(empty, 0.0).vertexCount(), 0);
}

TEST(Isosurface, ExactLevelValuesStillGiveAManifold) {
  // A box whose faces pass exactly through grid points: many samples equal the level.
  msk::Grid g;
  g.dims = {16, 16, 16};
  msk::ImageF f(g);
  for (int k = 0; k < 16; ++k)
    for (int j = 0; j < 16; ++j)
      for (int i = 0; i < 16; ++i)
        f.at(i, j, k) = static_cast<float>(std::max({std::abs(i - 8), std::abs(j - 8), std::abs(k - 8)}) - 4);
  msk::IsosurfaceOptions below;
  below.inside = msk::IsoInside::Below;
  const msk::TriangleMesh m = msk::isosurface(f, 0.0, below);
  ASSERT_EQ(msk::closedMeshProblem(m), "");
  // The 8 mm cube, less the marching-cubes chamfer of about half a voxel² along its edges.
  EXPECT_GT(msk::enclosedVolume(m), 0.85 * 512);
  EXPECT_LT(msk::enclosedVolume(m), 512.5);
}

TEST(DecimateMesh, KeepsTopologyUnderAggressiveReduction) {
  // A torus (genus 1) and a dumbbell with a thin neck: decimation must neither pinch nor close holes.
  msk::Grid g;
  g.dims = {70, 70, 40};
  g.spacing = {0.7, 0.7, 0.7};
  g.origin = {-24, -24, -14};
  msk::ImageF torus(g), dumbbell(g);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.toWorld(Eigen::Vector3d(i, j, k));
        const double ring = std::hypot(std::hypot(p[0], p[1]) - 15, p[2]) - 5;
        const double balls =
            std::min((p - Eigen::Vector3d(-12, 0, 0)).norm(), (p - Eigen::Vector3d(12, 0, 0)).norm()) - 8;
        const double neck = std::max(std::hypot(p[1], p[2]) - 1.2, std::fabs(p[0]) - 12);
        torus.at(i, j, k) = static_cast<float>(ring);
        dumbbell.at(i, j, k) = static_cast<float>(std::min(balls, neck));
      }
  msk::IsosurfaceOptions below;
  below.inside = msk::IsoInside::Below;
  auto euler = [](const msk::TriangleMesh& m) { return m.vertexCount() - m.faceCount() * 3 / 2 + m.faceCount(); };
  for (const msk::ImageF* f : {&torus, &dumbbell}) {
    const msk::TriangleMesh m = msk::isosurface(*f, 0.0, below);
    ASSERT_EQ(msk::closedMeshProblem(m), "");
    for (int target : {2000, 300, 40}) {
      SCOPED_TRACE(target);
      const msk::TriangleMesh d = msk::decimateMesh(m, target);
      ASSERT_EQ(msk::closedMeshProblem(d), "");
      EXPECT_EQ(euler(d), euler(m));
      EXPECT_GT(msk::enclosedVolume(d), 0);
      if (target >= 300) {
        EXPECT_LE(d.vertexCount(), target);
        EXPECT_NEAR(msk::enclosedVolume(d), msk::enclosedVolume(m), 0.05 * msk::enclosedVolume(m));
      }
    }
  }
  EXPECT_EQ(euler(msk::isosurface(torus, 0.0, below)), 0);
}

TEST(SmoothMesh, WindowedSincDoesNotShrinkAndRemovesNoise) {
  const Eigen::Vector3d c(1, 2, 3);
  msk::TriangleMesh s = msk::makeIcosphere(20, 4, c);
  msk::TriangleMesh noisy = s;
  uint32_t state = 12345;
  for (int i = 0; i < noisy.vertexCount(); ++i) {
    state = state * 1664525u + 1013904223u;
    const double t = (static_cast<double>(state >> 8) / (1 << 24) - 0.5) * 0.8;  // ±0.4 mm radial
    Eigen::Vector3d p = noisy.vertices.row(i).transpose() - c;
    noisy.vertices.row(i) = (c + p.normalized() * (20 + t)).transpose();
  }
  noisy.pointData["id"] = Eigen::VectorXd::LinSpaced(noisy.vertexCount(), 0, noisy.vertexCount() - 1);
  const msk::TriangleMesh sm = msk::smoothMesh(noisy, 20, 0.1);
  ASSERT_EQ(msk::closedMeshProblem(sm), "");
  EXPECT_EQ(sm.faces, noisy.faces);
  EXPECT_EQ(sm.pointData.at("id").size(), sm.vertexCount());
  double rmsNoisy = 0, rmsSmooth = 0, meanR = 0;
  for (int i = 0; i < sm.vertexCount(); ++i) {
    const double rn = (noisy.vertices.row(i).transpose() - c).norm(), rs = (sm.vertices.row(i).transpose() - c).norm();
    rmsNoisy += (rn - 20) * (rn - 20);
    rmsSmooth += (rs - 20) * (rs - 20);
    meanR += rs;
  }
  meanR /= sm.vertexCount();
  EXPECT_LT(rmsSmooth, 0.25 * rmsNoisy);
  EXPECT_NEAR(meanR, 20.0, 0.2);  // non-shrinking
  EXPECT_THROW(msk::smoothMesh(noisy, 10, 0.0), msk::ParameterError);
  EXPECT_THROW(msk::decimateMesh(noisy, 2), msk::ParameterError);
}
