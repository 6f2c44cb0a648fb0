#include "msk/segmentation/tetrahedralize.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <set>
#include <utility>

#include "msk/core/error.h"
#include "msk/core/tet_split.h"
#include "msk/core/volume_simplex.h"
#include "msk/test/tet_surface.h"

using msk::test::volumeResiduals;

// A sphere of radius 20 mm: the tet mesh fills the surface's volume, is positively oriented and repeatable.
TEST(Tetrahedralize, SphereVolumeOrientationAndDeterminism) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(20.0, 3);
  const double surfaceVolume = msk::enclosedVolume(sphere);
  const msk::TetMesh a = msk::tetrahedralize(sphere);
  EXPECT_EQ(msk::tetMeshProblem(a), "");
  EXPECT_GT(a.tetCount(), 100);
  const Eigen::VectorXd vol = msk::tetVolumes(a);
  EXPECT_GT(vol.minCoeff(), 0.0);
  const double error = (vol.sum() - surfaceVolume) / surfaceVolume;
  EXPECT_LT(std::fabs(error), 0.03);
  // The boundary is a closed surface and its nodes stay near the sphere.
  const msk::TriangleMesh boundary = msk::tetBoundary(a);
  EXPECT_EQ(msk::closedMeshProblem(boundary), "");
  const double rmax = a.nodes.rowwise().norm().maxCoeff();
  EXPECT_LT(rmax, 20.5);

  for (int run = 0; run < 2; ++run) {
    const msk::TetMesh b = msk::tetrahedralize(sphere);
    ASSERT_EQ(a.tetCount(), b.tetCount());
    ASSERT_EQ(a.nodeCount(), b.nodeCount());
    EXPECT_TRUE(a.tets == b.tets);
    EXPECT_TRUE(a.nodes == b.nodes);
  }
}

// The tet mesh carries a 3-simplex volume model whose rest shape satisfies its constraints.
TEST(Tetrahedralize, FeedsVolumeSimplexModel) {
  const msk::TetMesh m = msk::tetrahedralize(msk::makeIcosphere(20.0, 3));
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(m);
  EXPECT_EQ(msk::simplexMeshProblem(vm.simplex), "");
  EXPECT_EQ(vm.tetCount(), m.tetCount());
  const msk::Points r = volumeResiduals(vm, vm.simplex.positions);
  EXPECT_LT(r.rowwise().norm().maxCoeff(), 1e-9);
  const double v = msk::volumeSimplexVolume(vm, vm.simplex.positions);
  EXPECT_NEAR(v, msk::totalVolume(m), 1e-6 * msk::totalVolume(m));
  EXPECT_EQ(vm.degenerate.head(vm.tetCount()).cwiseAbs().sum(), 0);

  // Unstructured interior scrambled by up to 10 % of the diagonal, ghosts fixed: the constraints restore it.
  const msk::Points rest = vm.simplex.positions;
  const double diag = (rest.colwise().maxCoeff() - rest.colwise().minCoeff()).norm();
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-0.1 * diag / std::sqrt(3.0), 0.1 * diag / std::sqrt(3.0));
  msk::Points p = rest;
  for (int i = 0; i < vm.tetCount(); ++i) {
    const double z = u(rng), y = u(rng), x = u(rng);  // one by one: z, y, x, as the test's figures were made
    p.row(i) += Eigen::RowVector3d(x, y, z);
  }
  Eigen::VectorXd w = Eigen::VectorXd::Ones(vm.vertexCount());
  w.tail(vm.ghostCount()).setZero();
  msk::VolumeSimplexConstraints c(vm, 1.0);
  for (int it = 0; it < 1000; ++it) c.project(p, w);
  const double posErr = (p - rest).rowwise().norm().maxCoeff() / diag;
  const double volErr = std::fabs(msk::volumeSimplexVolume(vm, p) - v) / v;
  EXPECT_LT(posErr, 0.01);
  EXPECT_LT(volErr, 0.02);
}

// Exudation removes slivers (same nodes, fewer and fuller tets); its tie-breaking is not repeatable, so only the
// geometry is checked.
TEST(Tetrahedralize, ExudationRemovesSlivers) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(20.0, 3);
  msk::TetOptions options;
  options.exude = true;
  const msk::TetMesh plain = msk::tetrahedralize(sphere), exuded = msk::tetrahedralize(sphere, options);
  EXPECT_EQ(msk::tetMeshProblem(exuded), "");
  EXPECT_NEAR(msk::totalVolume(exuded), msk::totalVolume(plain), 1e-6 * msk::totalVolume(plain));
  EXPECT_GT(msk::tetVolumes(exuded).minCoeff(), msk::tetVolumes(plain).minCoeff());
}

// ODT smoothing, perturbation and exudation (as the segmenter's volume models use them): no sliver left (smallest
// dihedral angle above 10°, none at all before), same volume, and the same mesh when run twice in one process.
TEST(Tetrahedralize, OptimisersRemoveSliversRepeatably) {
  const msk::TriangleMesh sphere = msk::makeIcosphere(20.0, 3);
  msk::TetOptions options;
  options.odt = options.perturb = options.exude = true;
  const msk::TetMesh plain = msk::tetrahedralize(sphere), a = msk::tetrahedralize(sphere, options),
                     b = msk::tetrahedralize(sphere, options);
  EXPECT_EQ(msk::tetMeshProblem(a), "");
  const double before = msk::tetMinDihedralAngles(plain).minCoeff(), after = msk::tetMinDihedralAngles(a).minCoeff();
  EXPECT_GT(after, 10.0);
  EXPECT_GT(after, before);
  EXPECT_NEAR(msk::totalVolume(a), msk::totalVolume(plain), 0.01 * msk::totalVolume(plain));
  EXPECT_TRUE(a.tets == b.tets);
  EXPECT_TRUE(a.nodes == b.nodes);
  msk::TetOptions bad;
  bad.sliverBoundDeg = 80;
  EXPECT_THROW(msk::tetrahedralize(sphere, bad), msk::ParameterError);
  bad = {};
  bad.optimiseIterations = 0;
  EXPECT_THROW(msk::tetrahedralize(sphere, bad), msk::ParameterError);
}

namespace {

/// Interior edges of a tet mesh whose two nodes both lie on the boundary ("bridges").
int bridgeEdgeCount(const msk::TetMesh& m) {
  const std::vector<char> on = msk::boundaryNodeMask(m);
  const msk::Triangles bf = msk::tetBoundaryFaces(m);
  std::set<std::pair<int, int>> boundaryEdges, bridges;
  for (Eigen::Index f = 0; f < bf.rows(); ++f)
    for (int k = 0; k < 3; ++k) boundaryEdges.insert(std::minmax(bf(f, k), bf(f, (k + 1) % 3)));
  for (int t = 0; t < m.tetCount(); ++t)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const auto e = std::minmax(m.tets(t, i), m.tets(t, j));
        if (on[static_cast<size_t>(e.first)] && on[static_cast<size_t>(e.second)] && !boundaryEdges.count(e))
          bridges.insert(e);
      }
  return static_cast<int>(bridges.size());
}

/// Triangles as node triples rotated to start at their smallest node (orientation kept), as a set.
std::set<std::array<int, 3>> orientedFaceSet(const msk::Triangles& f) {
  std::set<std::array<int, 3>> s;
  for (Eigen::Index i = 0; i < f.rows(); ++i) {
    std::array<int, 3> k = {f(i, 0), f(i, 1), f(i, 2)};
    std::rotate(k.begin(), std::min_element(k.begin(), k.end()), k.end());
    s.insert(k);
  }
  return s;
}

}  // namespace

// TetOptions::interiorNodes with the segmenter's sizes (facets of the surface's mean edge, cells 1.5 times that,
// optimisers on) on a flat ellipsoid (20 x 20 x 6 mm, about two tets thick, as thin muscles are): its mesh has tets
// with all four nodes on the surface and bridge edges between surface nodes; with the option none is left, the
// boundary faces and the mesher's nodes are the same, every tet is positive, the volume is unchanged, and runs repeat.
TEST(Tetrahedralize, InteriorNodesInEveryTet) {
  msk::TriangleMesh sphere = msk::makeIcosphere(20.0, 3);
  sphere.vertices.col(2) *= 0.3;
  msk::TetOptions options = msk::volumeModelTetOptions(sphere);
  options.interiorNodes = false;
  const msk::TetMesh plain = msk::tetrahedralize(sphere, options);
  options.interiorNodes = true;
  const msk::TetMesh a = msk::tetrahedralize(sphere, options), b = msk::tetrahedralize(sphere, options);
  options.interiorSplit = msk::BoundarySplit::Tets;
  const msk::TetMesh tetsOnly = msk::tetrahedralize(sphere, options);
  EXPECT_EQ(msk::tetMeshProblem(a), "");
  EXPECT_EQ(msk::tetMeshProblem(tetsOnly), "");
  const int before = msk::boundaryOnlyTetCount(plain), bridgesBefore = bridgeEdgeCount(plain);
  EXPECT_GT(before, 0);
  EXPECT_GT(bridgesBefore, 0);
  EXPECT_EQ(msk::boundaryOnlyTetCount(a), 0);
  EXPECT_EQ(bridgeEdgeCount(a), 0);
  EXPECT_EQ(msk::boundaryOnlyTetCount(tetsOnly), 0);
  ASSERT_GT(a.nodeCount(), plain.nodeCount());
  EXPECT_TRUE(a.nodes.topRows(plain.nodeCount()) == plain.nodes);
  // The same boundary faces over the same nodes, orientation included (they may come in another order).
  EXPECT_TRUE(orientedFaceSet(msk::tetBoundaryFaces(a)) == orientedFaceSet(msk::tetBoundaryFaces(plain)));
  EXPECT_NEAR(msk::totalVolume(a), msk::totalVolume(plain), 1e-9 * msk::totalVolume(plain));
  EXPECT_GT(msk::tetVolumes(a).minCoeff(), 0.0);
  EXPECT_TRUE(a.tets == b.tets);
  EXPECT_TRUE(a.nodes == b.nodes);
}

TEST(Tetrahedralize, RejectsOpenSurfacesAndBadOptions) {
  msk::TriangleMesh open = msk::makeIcosphere(10.0, 1);
  open.faces.conservativeResize(open.faceCount() - 1, 3);
  EXPECT_THROW(msk::tetrahedralize(open), msk::Error);
  msk::TriangleMesh inward = msk::makeIcosphere(10.0, 1);
  msk::flipFaces(inward);
  EXPECT_THROW(msk::tetrahedralize(inward), msk::Error);
  msk::TetOptions bad;
  bad.cellSizeMm = -1;
  EXPECT_THROW(msk::tetrahedralize(msk::makeIcosphere(10.0, 1), bad), msk::ParameterError);
  bad = {};
  bad.facetAngleDeg = 40;
  EXPECT_THROW(msk::tetrahedralize(msk::makeIcosphere(10.0, 1), bad), msk::ParameterError);
}
