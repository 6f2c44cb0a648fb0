// Isotropic remeshing of templates and the self-intersection count of surfaces (surface_quality.h).
#include "msk/segmentation/surface_quality.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/metrics.h"
#include "msk/test/files.h"

namespace {

/// The smallest angle of each triangle, degrees.
std::vector<double> smallestAngles(const msk::TriangleMesh& m) {
  std::vector<double> out;
  for (int f = 0; f < m.faceCount(); ++f) {
    double smallest = 180;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = m.vertices.row(m.faces(f, k)), b = m.vertices.row(m.faces(f, (k + 1) % 3)),
                            c = m.vertices.row(m.faces(f, (k + 2) % 3));
      const double cosine = (b - a).normalized().dot((c - a).normalized());
      smallest = std::min(smallest, std::acos(std::clamp(cosine, -1.0, 1.0)) * 180 / M_PI);
    }
    out.push_back(smallest);
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// A sphere of radius 10 mm stretched ×6 along z: an elongated surface of long thin triangles, as a decimated muscle.
msk::TriangleMesh stretchedSphere() {
  msk::TriangleMesh m = msk::makeIcosphere(10, 4);
  m.vertices.col(2) *= 6.0;
  return m;
}

}  // namespace

TEST(SurfaceQuality, RemeshingGivesWellShapedTrianglesOnTheSameSurface) {
  const msk::TriangleMesh in = stretchedSphere();
  const std::vector<double> before = smallestAngles(in);
  const msk::TriangleMesh out = msk::remeshIsotropic(in, 2000);
  const std::vector<double> after = smallestAngles(out);
  EXPECT_EQ(msk::closedMeshProblem(out), "");
  EXPECT_NEAR(out.vertexCount(), 2000, 200);
  EXPECT_LT(before[before.size() / 20], 15.0);  // the input is made of thin triangles
  EXPECT_GT(after[after.size() / 20], 30.0);    // the output is not
  EXPECT_NEAR(msk::enclosedVolume(out), msk::enclosedVolume(in), 0.01 * msk::enclosedVolume(in));  // outward, same
  // The same surface: the remeshed vertices lie on the input, so the two differ by chords: a small fraction of an edge
  // on average, at most about half an edge where the surface bends sharpest (the tips: radius of curvature 1.7 mm, less
  // than an edge; this is what a uniform remesh gives up, and why bones keep their templates' triangulation).
  const double edge = msk::meanEdgeLength(out);
  const msk::SegmentationMetrics d = msk::meshMetrics(out, in);
  EXPECT_LT(d.assd, 0.05 * edge);
  EXPECT_LT(d.hausdorff, 0.5 * edge);
  EXPECT_EQ(msk::selfIntersections(out), 0u);
  // Deterministic: the same template gives the same triangulation (outputs of a cohort stay in correspondence).
  const msk::TriangleMesh again = msk::remeshIsotropic(in, 2000);
  ASSERT_EQ(again.vertexCount(), out.vertexCount());
  EXPECT_EQ((again.vertices - out.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_TRUE((again.faces.array() == out.faces.array()).all());
}

TEST(SurfaceQuality, BadInputIsRefused) {
  EXPECT_THROW(msk::remeshIsotropic(msk::makeIcosphere(10, 1), 3), msk::ParameterError);
  msk::TriangleMesh open = msk::makeIcosphere(10, 1);
  open.faces.conservativeResize(open.faceCount() - 1, 3);
  EXPECT_THROW(msk::remeshIsotropic(open, 100), msk::Error);
  EXPECT_THROW(msk::selfIntersections(open), msk::Error);
}

TEST(SurfaceQuality, SelfIntersectionsAreCounted) {
  msk::TriangleMesh m = msk::makeIcosphere(10, 2);
  EXPECT_EQ(msk::selfIntersections(m), 0u);
  // One vertex pushed through the sphere: its fan crosses the faces on the far side.
  Eigen::Index top = 0;
  m.vertices.col(2).maxCoeff(&top);
  m.vertices.row(top) *= -1.5;
  EXPECT_GT(msk::selfIntersections(m), 0u);
}

// A local fold (one vertex dragged across its neighbours, its fan now crossing the faces beyond) is smoothed away, and
// only the vertices near it move.
TEST(SurfaceQuality, UnfoldingRemovesALocalFoldAndMovesOnlyItsNeighbourhood) {
  msk::TriangleMesh m = msk::makeIcosphere(10, 3);
  const double edge = msk::meanEdgeLength(m);
  const Eigen::Vector3d p = m.vertices.row(0), tangent = p.cross(Eigen::Vector3d::UnitZ()).normalized();
  m.vertices.row(0) = (p + 1.6 * edge * tangent).normalized().transpose() * 10.0;
  const msk::TriangleMesh folded = m;
  ASSERT_GT(msk::selfIntersections(m), 0u);
  const msk::UnfoldReport r = msk::unfoldSurface(m);
  EXPECT_EQ(r.before, msk::selfIntersections(folded));
  EXPECT_EQ(r.after, 0u);
  EXPECT_EQ(msk::selfIntersections(m), 0u);
  EXPECT_EQ(msk::closedMeshProblem(m), "");
  EXPECT_LT(r.verticesMoved, m.vertexCount() / 10);
  for (int v = 0; v < m.vertexCount(); ++v) {  // what moved lies near the fold
    if ((m.vertices.row(v) - folded.vertices.row(v)).norm() > 0) {
      EXPECT_LT((folded.vertices.row(v) - folded.vertices.row(0)).norm(), 5 * edge) << v;
    }
  }
  // An embedded surface is left alone.
  msk::TriangleMesh sphere = msk::makeIcosphere(10, 3);
  const msk::UnfoldReport none = msk::unfoldSurface(sphere);
  EXPECT_EQ(none.before, 0u);
  EXPECT_EQ(none.verticesMoved, 0);
  EXPECT_EQ((sphere.vertices - msk::makeIcosphere(10, 3).vertices).cwiseAbs().maxCoeff(), 0.0);
}

// However many rounds it is given, the crossing pairs an unfolding reports as left are those a full count finds on
// the surface it leaves (rounds after the first search only near the vertices smoothed).
TEST(SurfaceQuality, UnfoldingCountsWhatIsLeftAfterEachNumberOfRounds) {
  msk::TriangleMesh m = msk::makeIcosphere(10, 4);
  for (int v = 0; v < m.vertexCount(); ++v)  // a cap pushed in through the sphere's far side
    if (m.vertices(v, 2) > 8.0) m.vertices(v, 2) = 8.0 - 10.0 * (m.vertices(v, 2) - 8.0);
  const size_t before = msk::selfIntersections(m);
  ASSERT_GT(before, 0u);
  int roundsNeeded = 0;
  for (int rounds = 1; rounds <= 8; ++rounds) {
    msk::TriangleMesh u = m;
    const msk::UnfoldReport r = msk::unfoldSurface(u, rounds);
    EXPECT_EQ(r.before, before);
    EXPECT_EQ(r.after, msk::selfIntersections(u)) << rounds << " rounds";
    if (r.after == 0 && roundsNeeded == 0) roundsNeeded = r.rounds;
  }
  EXPECT_GE(roundsNeeded, 3) << "the fold should take several rounds";
}

// A remeshed surface counts as isotropic and is not remeshed again by segment; a decimated one (the thin triangles of a
// stretched sphere, the bundled phantom's decimated femur) does not.
TEST(SurfaceQuality, IsotropicTriangulationTellsARemeshedSurfaceFromADecimatedOne) {
  const msk::TriangleMesh stretched = stretchedSphere();
  EXPECT_FALSE(msk::isotropicTriangulation(stretched));
  EXPECT_TRUE(msk::isotropicTriangulation(msk::remeshIsotropic(stretched, 2000)));
  EXPECT_TRUE(msk::isotropicTriangulation(msk::makeIcosphere(10, 3)));
  const msk::TriangleMesh femur = msk::readMesh(msk::test::bundledSample() + "template_femur.vtk");
  EXPECT_FALSE(msk::isotropicTriangulation(femur));
  EXPECT_TRUE(msk::isotropicTriangulation(msk::remeshIsotropic(femur, femur.vertexCount())));
  EXPECT_FALSE(msk::isotropicTriangulation(msk::TriangleMesh()));
}
