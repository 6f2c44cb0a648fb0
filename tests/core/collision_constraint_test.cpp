#include "msk/core/collision_constraint.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <limits>
#include <random>

#include "msk/core/collision_surface.h"
#include "msk/core/error.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/triangle_grid.h"
#include "msk/core/triangle_mesh.h"
#include "msk/test/shapes.h"

namespace {
using msk::test::uniformVector;

/// The distance from `q` to the nearest triangle of `m`, every triangle tried (the reference the grid queries are
/// checked against).
double nearestTriangleDistance(const msk::TriangleMesh& m, const Eigen::Vector3d& q) {
  double nearest = std::numeric_limits<double>::infinity();
  for (int t = 0; t < m.faceCount(); ++t)
    nearest = std::min(nearest, (msk::closestPointOnTriangle(q, m.vertices.row(m.faces(t, 0)).transpose(),
                                                             m.vertices.row(m.faces(t, 1)).transpose(),
                                                             m.vertices.row(m.faces(t, 2)).transpose()) -
                                 q)
                                    .norm());
  return nearest;
}
}  // namespace

// Collision position correction (Table 4.23, spring): reaches the gap, conserves linear momentum.
TEST(CollisionKernel, PushesOutToTheGapAndConservesLinearMomentum) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> um(0.2, 5.0), ub(0.05, 1.0);
  for (int t = 0; t < 500; ++t) {
    const Eigen::Vector3d pi[3] = {Eigen::Vector3d(0, 0, 0) + uniformVector(rng, 0.3),
                                   Eigen::Vector3d(4, 0, 0) + uniformVector(rng, 0.3),
                                   Eigen::Vector3d(0, 4, 0) + uniformVector(rng, 0.3)};
    double b[3] = {ub(rng), ub(rng), ub(rng)};
    const double sum = b[0] + b[1] + b[2];
    for (double& x : b) x /= sum;
    const Eigen::Vector3d n = (pi[1] - pi[0]).cross(pi[2] - pi[0]).normalized();
    const Eigen::Vector3d pbar = b[0] * pi[0] + b[1] * pi[1] + b[2] * pi[2];
    const Eigen::Vector3d p = pbar - 0.7 * n + uniformVector(rng, 0.2);  // 0.7 mm inside the partner
    const double w = 1.0 / um(rng), wi[3] = {1.0 / um(rng), 1.0 / um(rng), 1.0 / um(rng)};
    Eigen::Vector3d dp, dpi[3];
    ASSERT_TRUE(msk::collisionCorrection(p, pi, b, n, 0.5, 0.0, w, wi, dp, dpi));
    const Eigen::Vector3d lin = dp / w + dpi[0] / wi[0] + dpi[1] / wi[1] + dpi[2] / wi[2];
    EXPECT_LT(lin.norm(), 1e-9 * (1 + dp.norm() / w));
    // After the correction (same normal, linearised), P sits exactly `gap` outside along n.
    const Eigen::Vector3d newBar = b[0] * (pi[0] + dpi[0]) + b[1] * (pi[1] + dpi[1]) + b[2] * (pi[2] + dpi[2]);
    EXPECT_NEAR(((p + dp) - newBar).dot(n), 0.5, 1e-9);
  }
  // Already outside by more than the gap: nothing.
  const Eigen::Vector3d pi[3] = {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}};
  const double b[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3}, wi[3] = {1, 1, 1};
  Eigen::Vector3d dp, dpi[3];
  EXPECT_FALSE(
      msk::collisionCorrection(Eigen::Vector3d(1, 1, 2), pi, b, Eigen::Vector3d::UnitZ(), 0.5, 0.0, 1, wi, dp, dpi));
}

// Two overlapping spheres stacked in one particle system separate under the collision sets of both directions.
TEST(CollisionConstraints, OverlappingSpheresSeparate) {
  const msk::TriangleMesh a = msk::makeIcosphere(10, 3, {0, 0, 0}), b = msk::makeIcosphere(10, 3, {18, 0, 0});
  const int na = a.vertexCount(), nb = b.vertexCount();
  msk::Points p(na + nb, 3);
  p.topRows(na) = a.vertices;
  p.bottomRows(nb) = b.vertices;
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(na + nb);
  msk::Triangles ta = a.faces, tb = b.faces.array() + na;
  msk::CollisionConstraints ab(0, na, tb, 0.0, 3.0, 0.0), ba(na, nb, ta, 0.0, 3.0, 0.0);
  const Eigen::RowVector3d momentumBefore = p.colwise().sum();
  for (int it = 0; it < 30; ++it) {
    ab.detect(p);
    ba.detect(p);
    ab.project(p, w);
    ba.project(p, w);
  }
  ab.detect(p);
  ba.detect(p);
  EXPECT_LT(ab.maxPenetration(p), 0.1);
  EXPECT_LT(ba.maxPenetration(p), 0.1);
  EXPECT_LT((p.colwise().sum() - momentumBefore).norm(), 1e-8 * p.rows());
  EXPECT_THROW(msk::CollisionConstraints(0, na, tb, -1.0, 3.0, 0.0), msk::ParameterError);
}

// Without the inside test a vertex is taken to be outside the partner: a contact can keep it `gap` away but never
// pushes it through the surface; with the test, a vertex inside is pushed out along the partner's outward normal.
TEST(CollisionConstraints, InsideTestDecidesTheSideAndTheOutsideAssumptionNeverPushesThrough) {
  const msk::TriangleMesh b = msk::makeIcosphere(10, 3);
  const int nb = b.vertexCount();
  for (const double start : {9.5, 10.1}) {  // 0.5 mm inside, 0.1 mm outside (within the 0.2 mm gap)
    for (const bool insideTest : {true, false}) {
      msk::Points p(nb + 1, 3);
      p.topRows(nb) = b.vertices;
      p.row(nb) = Eigen::RowVector3d(start, 0.01, 0.02);
      msk::Triangles tb = b.faces;
      msk::CollisionConstraints c(nb, 1, tb, 0.2, 1.0, 0.0);
      const Eigen::VectorXd w = Eigen::VectorXd::Ones(nb + 1);
      const double r0 = p.row(nb).norm();
      c.detect(p, insideTest);
      ASSERT_EQ(c.contacts(), 1);
      c.project(p, w);
      const double r = p.row(nb).norm();
      if (start > 10 || insideTest) {
        EXPECT_GT(r, r0 + 0.02) << "start " << start << " insideTest " << insideTest;  // moved outward
      } else {
        EXPECT_LE(r, r0 + 1e-12) << "an assumed-outside vertex is pushed away from the surface it faces, inward";
        EXPECT_GT(r, 9.5 - 0.25);  // ... by at most the gap: never through
      }
    }
  }
}

namespace {

/// A sphere of radius 10 mm about (2, 1, −3) (icosphere, 3 subdivisions), each vertex moved by up to 0.3 mm.
msk::TriangleMesh jitteredSphere(std::mt19937& rng) {
  msk::TriangleMesh m = msk::makeIcosphere(10, 3, {2, 1, -3});
  for (int v = 0; v < m.vertexCount(); ++v) m.vertices.row(v) += 0.3 * uniformVector(rng).transpose();
  return m;
}

/// A grid of `cell` mm over `m`'s box grown by `margin` below and by `pad` cells and more above.
msk::TriangleGrid gridAround(const msk::TriangleMesh& m, double margin, double cell, double pad) {
  msk::TriangleGrid grid;
  msk::TriangleGrid::Layout layout;
  layout.lo = (m.vertices.colwise().minCoeff().array() - margin).transpose();
  layout.cell = cell;
  layout.dims = ((m.vertices.colwise().maxCoeff().transpose() - layout.lo).array() / cell + pad).ceil().cast<int>();
  grid.build(layout, m.vertices, m.faces);
  return grid;
}

}  // namespace

// When nothing lies within the radius, the clearance a grid query reports is a distance that no triangle is nearer
// than (the exact distances, by brute force), and at least the radius.
TEST(TriangleGrid, ClearanceIsALowerBoundOfEveryTriangleDistance) {
  std::mt19937 rng(5);
  const msk::TriangleMesh m = jitteredSphere(rng);
  const double radius = 1.2;
  const msk::TriangleGrid grid = gridAround(m, radius, 1.7, radius);
  std::uniform_real_distribution<double> u(-14, 14);
  int empty = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d q = Eigen::Vector3d(2, 1, -3) + Eigen::Vector3d(u(rng), u(rng), u(rng));
    double clearance = -1;
    const msk::SurfacePoint s = grid.closestWithin(m.vertices, m.faces, q, radius, -1, &clearance);
    const double nearest = nearestTriangleDistance(m, q);
    if (s.triangle >= 0) {
      EXPECT_NEAR(s.distance, nearest, 1e-12);
      continue;
    }
    ++empty;
    EXPECT_GT(nearest, radius);
    EXPECT_GE(clearance, radius);
    EXPECT_LE(clearance, nearest * (1 + 1e-12)) << "query " << q.transpose();
  }
  EXPECT_GT(empty, 1000);
}

// A grid query examines each triangle once however many scanned cells list it, and its answer, ties included, does
// not depend on the hint: points just off the mesh's vertices (whose incident triangles are equally close) and random
// points near the surface, against the exact closest distance by brute force, with and without each incident
// triangle as the hint.
TEST(TriangleGrid, TiesAndHintsGiveOneAnswer) {
  std::mt19937 rng(11);
  const msk::TriangleMesh m = jitteredSphere(rng);
  const double radius = 1.5;
  const msk::TriangleGrid grid = gridAround(m, radius, 1.5, 2);
  std::vector<std::vector<int>> incident(static_cast<size_t>(m.vertexCount()));
  for (int t = 0; t < m.faceCount(); ++t)
    for (int k = 0; k < 3; ++k) incident[static_cast<size_t>(m.faces(t, k))].push_back(t);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  int ties = 0;
  for (int v = 0; v < m.vertexCount(); ++v) {
    const Eigen::Vector3d corner = m.vertices.row(v).transpose();
    const Eigen::Vector3d outward = (corner - Eigen::Vector3d(2, 1, -3)).normalized();
    for (const Eigen::Vector3d& q :
         {Eigen::Vector3d(corner + 0.4 * outward), Eigen::Vector3d(corner + Eigen::Vector3d(u(rng), u(rng), u(rng)))}) {
      double nearest = std::numeric_limits<double>::infinity();
      int closeOnes = 0;
      for (int t = 0; t < m.faceCount(); ++t) {
        const double d = (msk::closestPointOnTriangle(q, m.vertices.row(m.faces(t, 0)).transpose(),
                                                      m.vertices.row(m.faces(t, 1)).transpose(),
                                                      m.vertices.row(m.faces(t, 2)).transpose()) -
                          q)
                             .norm();
        if (d < nearest) {
          nearest = d;
          closeOnes = 1;
        } else if (d == nearest) {
          ++closeOnes;
        }
      }
      const msk::SurfacePoint plain = grid.closestWithin(m.vertices, m.faces, q, radius);
      if (!(nearest < radius)) {
        EXPECT_LT(plain.triangle, 0);
        continue;
      }
      ASSERT_GE(plain.triangle, 0) << "vertex " << v;
      EXPECT_EQ(plain.distance, nearest) << "vertex " << v;
      ties += closeOnes > 1;
      for (int hint : incident[static_cast<size_t>(v)]) {
        const msk::SurfacePoint hinted = grid.closestWithin(m.vertices, m.faces, q, radius, hint);
        EXPECT_EQ(hinted.triangle, plain.triangle) << "vertex " << v << " hint " << hint;
        EXPECT_EQ(hinted.distance, plain.distance);
      }
    }
  }
  EXPECT_GT(ties, m.vertexCount() / 2) << "the points off the vertices should meet equally close triangles";
}

// A set that skips the queries of vertices known to be out of reach (their clearance, less their own move and the
// partner's travel since, beyond the reach), and whose vertices in contact follow their triangle's neighbours between
// side tests, finds at every step the contacts of a set built afresh (a convex partner: no nearer part of it lies
// outside a walk's patch).
TEST(CollisionConstraints, SkippedQueriesFindWhatAFreshSetFinds) {
  // Triangles about 1.6 mm across (the grid is scanned every step), then 0.4 mm (less than half the reach of 1.2 mm:
  // between side tests the vertices in contact walk).
  for (int subdivisions : {3, 5}) {
    const msk::TriangleMesh a = msk::makeIcosphere(10, subdivisions, {0, 0, 0}),
                            b = msk::makeIcosphere(10, subdivisions, {21.5, 0, 0});
    const msk::TriangleMesh both = msk::test::joinedMeshes(a, b);  // A's particles first, then B's
    const int na = a.vertexCount(), nb = b.vertexCount();
    msk::Points p = both.vertices;
    const msk::Triangles tb = both.faces.bottomRows(b.faceCount());
    msk::CollisionConstraints kept(0, na, tb, 0.2, 1.0, 0.0);
    msk::CollisionSurface partner(tb, 1.2);
    partner.update(p);
    const bool walks = subdivisions == 5;
    EXPECT_EQ(partner.walkPays(), walks);
    double worst = 0;  // the largest difference of a correction's size between the walk and the grid, mm
    int differing = 0;
    std::mt19937 rng(9);
    int compared = 0;
    for (int step = 0; step < 60; ++step) {
      // B comes toward A and goes back, both surfaces jitter; some steps leave B where it was.
      if (step % 7 != 3) {
        const double dx = step < 30 ? -0.12 : 0.12;
        for (int v = na; v < na + nb; ++v)
          p.row(v) += Eigen::RowVector3d(dx, 0, 0) + 0.05 * uniformVector(rng).transpose();
      }
      for (int v = 0; v < na; ++v) p.row(v) += 0.08 * uniformVector(rng).transpose();
      kept.detect(p, step % 5 == 0, 1, true);
      msk::CollisionConstraints fresh(0, na, tb, 0.2, 1.0, 0.0);
      fresh.detect(p, step % 5 == 0);
      ASSERT_EQ(kept.contacts(), fresh.contacts()) << "step " << step;
      ASSERT_EQ(kept.rowCount(), fresh.rowCount());
      if (!walks) {
        for (int r = 0; r < kept.rowCount(); ++r) {
          int ik[msk::kMaxRowParticles], jf[msk::kMaxRowParticles];
          ASSERT_EQ(kept.rowParticles(r, ik), fresh.rowParticles(r, jf));
          for (int k = 0; k < 4; ++k) EXPECT_EQ(ik[k], jf[k]) << "step " << step << " row " << r;
        }
        EXPECT_EQ(kept.maxPenetration(p), fresh.maxPenetration(p));
      } else {
        // A walk ends at a nearest point of the part of B around the last triangle: on these jittered spheres (their
        // vertices wander by tenths of a millimetre, over triangles 0.4 mm across) sometimes at a local one.
        const Eigen::VectorXd w = Eigen::VectorXd::Ones(p.rows());
        for (int r = 0; r < kept.rowCount(); ++r) {
          msk::ConstraintRow rk, rf;  // a row with nothing to correct counts as a correction of 0
          const Eigen::Vector3d ck = kept.row(r, p, w, rk) ? rk.c : Eigen::Vector3d::Zero();
          const Eigen::Vector3d cf = fresh.row(r, p, w, rf) ? rf.c : Eigen::Vector3d::Zero();
          worst = std::max(worst, std::abs(ck.norm() - cf.norm()));
          differing += (ck - cf).norm() > 1e-9;
        }
        EXPECT_NEAR(kept.maxPenetration(p), fresh.maxPenetration(p), 0.25);
      }
      compared += kept.contacts();
    }
    EXPECT_GT(compared, 500);
    EXPECT_LT(worst, 0.25);
    EXPECT_LT(differing, compared / 500) << "of " << compared;
    std::printf("triangles of %d subdivisions: %d contacts compared, %d with another correction, at most %.4f mm\n",
                subdivisions, compared, differing, worst);
  }
}

// A set that carries its vertices' sides from one side test to the next decides every side as a fresh set does (which
// takes each from B's winding number), while its vertices cross B in and out between the side tests.
TEST(CollisionConstraints, SidesCarriedBetweenSideTestsAreTheWindingNumbers) {
  const msk::TriangleMesh a = msk::makeIcosphere(10, 3), b = msk::makeIcosphere(10, 3, {0.3, -0.2, 0.1});
  const msk::TriangleMesh both = msk::test::joinedMeshes(a, b);  // A's particles first, then B's
  const int na = a.vertexCount(), nb = b.vertexCount();
  const msk::Triangles tb = both.faces.bottomRows(b.faceCount());
  msk::CollisionConstraints kept(0, na, tb, 0.2, 1.0, 0.0);
  std::mt19937 rng(4);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(na + nb);
  int compared = 0, inward = 0;
  for (int step = 0; step < 80; ++step) {
    // A swells and shrinks through B (radius 10 ± 0.8 mm, a few tenths of a millimetre per step); both jitter.
    msk::Points p = both.vertices;
    const double scale = 1.0 + 0.08 * std::sin(0.35 * step);
    p.topRows(na) *= scale;
    for (int v = 0; v < na + nb; ++v) p.row(v) += 0.03 * uniformVector(rng).transpose();
    const bool sideTest = step % 4 == 0;
    kept.detect(p, sideTest, 1, true);
    msk::CollisionConstraints fresh(0, na, tb, 0.2, 1.0, 0.0);
    fresh.detect(p, sideTest);
    ASSERT_EQ(kept.contacts(), fresh.contacts()) << "step " << step;
    for (int r = 0; r < kept.rowCount(); ++r) {
      msk::ConstraintRow rk, rf;
      const bool hk = kept.row(r, p, w, rk), hf = fresh.row(r, p, w, rf);
      ASSERT_EQ(hk, hf) << "step " << step << " row " << r;
      if (!hk) continue;
      EXPECT_EQ(rk.c, rf.c) << "step " << step << " row " << r;
      ++compared;
      const Eigen::Vector3d centreB(0.3, -0.2, 0.1);
      if (sideTest) inward += (p.row(rk.index[0]).transpose() - centreB).norm() < 9.8;  // a vertex well inside B
    }
  }
  EXPECT_GT(compared, 1000);
  EXPECT_GT(inward, 100);  // vertices found inside B at side tests, after crossing it in between
}

// The walk over the triangles around the last one found: on a convex surface it ends at the closest point of the whole
// surface after the query point has moved; on a surface folded back on itself (two sheets 1 mm apart) it stays on the
// sheet it started from, which the grid's scan does not.
TEST(CollisionSurface, WalkFindsTheClosestPointOfAConvexSurfaceAndStaysOnItsSheet) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(10, 3, {0, 0, 0});
  msk::CollisionSurface s(sphere.faces, 2.0);
  s.update(sphere.vertices);
  std::mt19937 rng(4);
  int walked = 0;
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d dir = uniformVector(rng).normalized();
    const Eigen::Vector3d q0 = (10.6 + 0.2 * i / 500.0) * dir;
    const msk::SurfacePoint first = s.closest(sphere.vertices, q0, 2.0);
    ASSERT_GE(first.triangle, 0);
    const Eigen::Vector3d q = q0 + 0.6 * uniformVector(rng);
    const msk::SurfacePoint grid = s.closest(sphere.vertices, q, 2.0);
    const msk::SurfacePoint walk = s.closestAround(sphere.vertices, q, first.triangle, 2.0);
    ASSERT_EQ(walk.triangle >= 0, grid.triangle >= 0) << "query " << i;
    if (grid.triangle < 0) continue;
    EXPECT_NEAR(walk.distance, grid.distance, 1e-12) << "query " << i;
    EXPECT_LT((walk.point - grid.point).norm(), 1e-9) << "query " << i;
    walked += walk.triangle != first.triangle;
  }
  EXPECT_GT(walked, 100);  // the walk left its first triangle

  // A flat ellipsoid, 40 mm wide and 1 mm thick at its centre: a point 0.3 mm above its top that found the top keeps
  // it after moving 1 mm down (inside, now nearer the bottom).
  msk::TriangleMesh slab = msk::makeIcosphere(20, 4);
  slab.vertices.col(2) *= 0.5 / 20;
  msk::CollisionSurface t(slab.faces, 2.0);
  t.update(slab.vertices);
  const msk::SurfacePoint top = t.closest(slab.vertices, Eigen::Vector3d(0.3, 0.2, 0.8), 2.0);
  ASSERT_GE(top.triangle, 0);
  EXPECT_GT(top.point.z(), 0.45);
  const Eigen::Vector3d below(0.3, 0.2, -0.2);
  EXPECT_LT(t.closest(slab.vertices, below, 2.0).point.z(), -0.45);
  const msk::SurfacePoint kept = t.closestAround(slab.vertices, below, top.triangle, 2.0);
  ASSERT_GE(kept.triangle, 0);
  EXPECT_GT(kept.point.z(), 0.45);
}

// The grid's cell width (in mean edges) changes which cells a query scans, not what it finds: the same distance and
// point for every query, within the reach and beyond it, and a clearance that still bounds every triangle's distance.
TEST(CollisionSurface, WiderCellsFindTheSameClosestPoints) {
  msk::TriangleMesh sphere = msk::makeIcosphere(10, 3, {2, 1, -3});
  std::mt19937 rng(21);
  for (int v = 0; v < sphere.vertexCount(); ++v) sphere.vertices.row(v) += 0.3 * uniformVector(rng).transpose();
  msk::CollisionSurface narrow(sphere.faces, 1.5), wide(sphere.faces, 1.5, 2.5), widest(sphere.faces, 1.5, 8);
  for (msk::CollisionSurface* s : {&narrow, &wide, &widest}) s->update(sphere.vertices);
  EXPECT_THROW(msk::CollisionSurface(sphere.faces, 1.5, 0.0), msk::ParameterError);
  int found = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d q = Eigen::Vector3d(2, 1, -3) + (7.5 + 5.0 * i / 2000.0) * uniformVector(rng).normalized();
    const msk::SurfacePoint a = narrow.closest(sphere.vertices, q, 1.5);
    for (const msk::CollisionSurface* s : {&wide, &widest}) {
      double clearance = 0;
      const msk::SurfacePoint b = s->closest(sphere.vertices, q, 1.5, -1, &clearance);
      ASSERT_EQ(a.triangle >= 0, b.triangle >= 0) << "query " << i;
      if (a.triangle >= 0) {
        EXPECT_EQ(a.distance, b.distance) << "query " << i;
        EXPECT_LT((a.point - b.point).norm(), 1e-12) << "query " << i;
        continue;
      }
      EXPECT_LE(clearance, nearestTriangleDistance(sphere, q)) << "query " << i;
    }
    found += a.triangle >= 0;
  }
  EXPECT_GT(found, 400);
  EXPECT_LT(found, 1600);
}

// A point outside the partner's bounding box grown by the reach finds nothing, and its clearance is its distance to
// that box: above zero, and no farther than the nearest triangle (so that the sets skip its next queries while it
// and the partner have moved less than that, less the reach).
TEST(CollisionSurface, PointsOutsideTheBoxGetTheBoxDistanceAsClearance) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(10, 3, {2, 1, -3});
  msk::CollisionSurface s(sphere.faces, 1.5, 2.5);
  s.update(sphere.vertices);
  std::mt19937 rng(5);
  int outside = 0;
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d q = Eigen::Vector3d(2, 1, -3) + (12.0 + 20.0 * i / 500.0) * uniformVector(rng).normalized();
    double clearance = -1;
    const msk::SurfacePoint p = s.closest(sphere.vertices, q, 1.5, -1, &clearance);
    EXPECT_LT(p.triangle, 0) << "query " << i;
    const Eigen::Vector3d lo = sphere.vertices.colwise().minCoeff(), hi = sphere.vertices.colwise().maxCoeff();
    const double box = (lo - q).cwiseMax(q - hi).cwiseMax(0.0).norm();
    EXPECT_LE(clearance, nearestTriangleDistance(sphere, q)) << "query " << i;
    if (((lo.array() - 1.5 - q.array()).maxCoeff() > 1e-9) || ((q.array() - hi.array() - 1.5).maxCoeff() > 1e-9)) {
      EXPECT_NEAR(clearance, box, 1e-9) << "query " << i;
      EXPECT_GT(clearance, 1.5) << "query " << i;
      ++outside;
    } else {  // within the grown box: the grid's clearance
      EXPECT_GE(clearance, 1.5) << "query " << i;
    }
  }
  EXPECT_GT(outside, 200);
}
