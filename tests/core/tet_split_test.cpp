#include "msk/core/tet_split.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <utility>

#include "msk/core/error.h"

namespace {

/// The boundary faces of a mesh as sorted node triples (orientation aside), to compare two meshes' boundaries.
std::set<std::array<int, 3>> faceSet(const msk::TetMesh& m) {
  const msk::Triangles f = msk::tetBoundaryFaces(m);
  std::set<std::array<int, 3>> s;
  for (Eigen::Index i = 0; i < f.rows(); ++i) {
    std::array<int, 3> k = {f(i, 0), f(i, 1), f(i, 2)};
    std::sort(k.begin(), k.end());
    s.insert(k);
  }
  return s;
}

}  // namespace

// Blocks of 1, 2 and 3 cubes a side: after the split no tet has all four nodes on the boundary, the mesh is valid, its
// volume and boundary faces are those of the input, and the input's nodes are kept.
TEST(TetSplit, EveryTetGetsAnInteriorNode) {
  for (int n : {1, 2, 3}) {
    SCOPED_TRACE(n);
    const msk::TetMesh cube = msk::makeCubeTets(n, 2.0);
    const int before = msk::boundaryOnlyTetCount(cube);
    EXPECT_GT(before, 0);
    int added = -1;
    const msk::TetMesh s = msk::splitBoundaryTets(cube, &added);
    EXPECT_EQ(msk::tetMeshProblem(s), "");
    EXPECT_EQ(msk::boundaryOnlyTetCount(s), 0);
    EXPECT_EQ(s.nodeCount(), cube.nodeCount() + added);
    EXPECT_GT(added, 0);
    EXPECT_TRUE(s.nodes.topRows(cube.nodeCount()) == cube.nodes);
    EXPECT_GT(msk::tetVolumes(s).minCoeff(), 0.0);
    EXPECT_NEAR(msk::totalVolume(s), msk::totalVolume(cube), 1e-9 * msk::totalVolume(cube));
    EXPECT_TRUE(faceSet(s) == faceSet(cube));
    // The Steiner nodes are inside, off the boundary.
    const std::vector<char> on = msk::boundaryNodeMask(s);
    for (int i = cube.nodeCount(); i < s.nodeCount(); ++i) EXPECT_EQ(on[static_cast<size_t>(i)], 0);
  }
}

// A single tet has no interior edge or face: refused. A mesh without boundary-only tets comes back unchanged.
TEST(TetSplit, SingleTetRefusedAndCleanMeshUnchanged) {
  msk::TetMesh one;
  one.nodes.resize(4, 3);
  one.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  one.tets.resize(1, 4);
  one.tets << 0, 1, 2, 3;
  EXPECT_THROW(msk::splitBoundaryTets(one), msk::Error);

  const msk::TetMesh s = msk::splitBoundaryTets(msk::makeCubeTets(2, 1.0));
  int added = -1;
  const msk::TetMesh again = msk::splitBoundaryTets(s, &added);
  EXPECT_EQ(added, 0);
  EXPECT_TRUE(again.tets == s.tets);
  EXPECT_TRUE(again.nodes == s.nodes);
}

// BoundarySplit::Bridges: no interior edge or face of the result has all its nodes on the boundary, and the boundary
// faces, volume and input nodes are kept.
TEST(TetSplit, BridgesLeaveNoEdgeOrFaceBetweenBoundaryNodesInside) {
  const msk::TetMesh cube = msk::makeCubeTets(3, 2.0);
  int added = 0;
  const msk::TetMesh s = msk::splitBoundaryTets(cube, &added, msk::BoundarySplit::Bridges);
  EXPECT_EQ(msk::tetMeshProblem(s), "");
  EXPECT_EQ(msk::boundaryOnlyTetCount(s), 0);
  EXPECT_TRUE(faceSet(s) == faceSet(cube));
  EXPECT_NEAR(msk::totalVolume(s), msk::totalVolume(cube), 1e-9 * msk::totalVolume(cube));
  EXPECT_GT(msk::tetVolumes(s).minCoeff(), 0.0);
  const std::vector<char> on = msk::boundaryNodeMask(s);
  std::set<std::pair<int, int>> boundaryEdges;
  const msk::Triangles bf = msk::tetBoundaryFaces(s);
  for (Eigen::Index f = 0; f < bf.rows(); ++f)
    for (int k = 0; k < 3; ++k) boundaryEdges.insert(std::minmax(bf(f, k), bf(f, (k + 1) % 3)));
  int bridges = 0, bridgeFaces = 0;
  const std::set<std::array<int, 3>> faces = faceSet(s);
  for (int t = 0; t < s.tetCount(); ++t) {
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const auto e = std::minmax(s.tets(t, i), s.tets(t, j));
        bridges += on[static_cast<size_t>(e.first)] && on[static_cast<size_t>(e.second)] && !boundaryEdges.count(e);
      }
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> k{};
      int c = 0;
      for (int i = 0; i < 4; ++i)
        if (i != skip) k[static_cast<size_t>(c++)] = s.tets(t, i);
      std::sort(k.begin(), k.end());
      bool all = true;
      for (int v : k) all = all && on[static_cast<size_t>(v)];
      bridgeFaces += all && !faces.count(k);
    }
  }
  EXPECT_EQ(bridges, 0);
  EXPECT_EQ(bridgeFaces, 0);
}
