#include "msk/core/tet_untangle.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "msk/core/error.h"
#include "msk/core/tet_split.h"

namespace {

/// 1 for the nodes off the boundary.
std::vector<char> interiorOf(const msk::TetMesh& m) {
  std::vector<char> in = msk::boundaryNodeMask(m);
  for (char& c : in) c = !c;
  return in;
}

int inverted(const msk::TetMesh& m) { return static_cast<int>((msk::tetVolumes(m).array() <= 0).count()); }

/// `rest` with each node flagged in `movable` moved by up to ± `amplitude` per axis (uniform, seeded).
msk::TetMesh scrambled(const msk::TetMesh& rest, const std::vector<char>& movable, unsigned seed, double amplitude) {
  msk::TetMesh m = rest;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  for (int i = 0; i < m.nodeCount(); ++i)
    if (movable[static_cast<size_t>(i)]) {
      // Drawn one by one (the order of a call's arguments is unspecified): z, y, x, as the suite's figures were made.
      const double z = u(rng), y = u(rng), x = u(rng);
      m.nodes.row(i) += Eigen::RowVector3d(x, y, z);
    }
  return m;
}

}  // namespace

// Interior nodes of a 4^3 block scrambled by up to 0.9 of the cube edge (many tets inverted): the untangler moves
// only the interior nodes and leaves no tet inverted; the total volume is unchanged (the boundary did not move).
TEST(TetUntangle, ScrambledInteriorIsUntangled) {
  const msk::TetMesh rest = msk::makeCubeTets(4, 1.0);
  const std::vector<char> movable = interiorOf(rest);
  msk::TetMesh m = scrambled(rest, movable, 5, 0.9);
  const int before = inverted(m);
  ASSERT_GT(before, 10);
  const Eigen::VectorXd ref = msk::tetVolumes(rest);
  const msk::TetUntangleReport rep = msk::untangleTets(m, movable, ref);
  EXPECT_EQ(rep.invertedBefore, before);
  EXPECT_EQ(rep.invertedAfter, 0);
  EXPECT_EQ(inverted(m), 0);
  EXPECT_GT(rep.minRelativeVolumeAfter, 0.0);
  EXPECT_NEAR(msk::totalVolume(m), msk::totalVolume(rest), 1e-9);
  for (int i = 0; i < m.nodeCount(); ++i) {
    if (!movable[static_cast<size_t>(i)]) {
      EXPECT_TRUE(m.nodes.row(i) == rest.nodes.row(i));
    }
  }
}

// A convex edge of a block folded into a valley (its nodes, ends aside, moved inwards by 0.7 of the cube edge along the
// diagonal, past the plane of their neighbours, as a deformed surface would). Tets with all four nodes on the surface
// invert there and stay inverted whatever the interior does. Splitting only those tets (BoundarySplit::Tets) is not
// enough: bridge triangles between surface nodes across the ridge now lie outside the block. With the bridges split
// (BoundarySplit::Bridges) every edge and face inside has an interior node and the untangler leaves no tet inverted.
TEST(TetUntangle, FoldedRidgeNeedsInteriorNodes) {
  const double edge = 1.0;
  const int n = 3;
  auto fold = [&](msk::TetMesh& m) {
    for (int i = 0; i < m.nodeCount(); ++i) {
      const Eigen::RowVector3d p = m.nodes.row(i);
      if (std::fabs(p.y()) < 1e-9 && std::fabs(p.z() - n * edge) < 1e-9 && p.x() > 0.5 * edge &&
          p.x() < (n - 0.5) * edge)
        m.nodes.row(i) += Eigen::RowVector3d(0, 0.7, -0.7) * edge;
    }
  };
  const msk::TetMesh plain = msk::makeCubeTets(n, edge);
  int before[3], after[3];
  for (int variant = 0; variant < 3; ++variant) {
    const msk::TetMesh rest = variant == 0   ? plain
                              : variant == 1 ? msk::splitBoundaryTets(plain, nullptr, msk::BoundarySplit::Tets)
                                             : msk::splitBoundaryTets(plain, nullptr, msk::BoundarySplit::Bridges);
    msk::TetMesh m = rest;
    fold(m);
    before[variant] = inverted(m);
    const double folded = msk::totalVolume(m);
    const msk::TetUntangleReport r = msk::untangleTets(m, interiorOf(rest), msk::tetVolumes(rest));
    after[variant] = r.invertedAfter;
    EXPECT_EQ(r.invertedAfter, inverted(m));
    EXPECT_NEAR(msk::totalVolume(m), folded, 1e-9);  // only interior nodes moved
  }
  EXPECT_GT(before[0], 0);
  EXPECT_EQ(after[0], before[0]);  // no interior node in those tets
  EXPECT_GT(after[1], 0);
  EXPECT_GT(before[2], 0);
  EXPECT_EQ(after[2], 0);
}

// Sizes are checked.
TEST(TetUntangle, RejectsMismatchedInput) {
  msk::TetMesh m = msk::makeCubeTets(1, 1.0);
  EXPECT_THROW(msk::untangleTets(m, std::vector<char>(3, 1)), msk::ParameterError);
  EXPECT_THROW(msk::untangleTets(m, std::vector<char>(static_cast<size_t>(m.nodeCount()), 1), Eigen::VectorXd::Ones(2)),
               msk::ParameterError);
  EXPECT_THROW(msk::untangleTets(m, std::vector<char>(static_cast<size_t>(m.nodeCount()), 1),
                                 -Eigen::VectorXd::Ones(m.tetCount())),
               msk::ParameterError);
}

// Shape smoothing: Steiner nodes of a split block pulled towards a corner of their star (still valid, poorly shaped)
// get their quality back; every tet stays positive and the other nodes stay.
TEST(TetUntangle, ShapeSmoothingRaisesTheWorstQuality) {
  const msk::TetMesh cube = msk::makeCubeTets(3, 1.0);
  const msk::TetMesh split = msk::splitBoundaryTets(cube, nullptr, msk::BoundarySplit::Bridges);
  std::vector<char> steiner(static_cast<size_t>(split.nodeCount()), 0);
  std::fill(steiner.begin() + cube.nodeCount(), steiner.end(), 1);
  msk::TetMesh m = split;
  for (int i = cube.nodeCount(); i < m.nodeCount(); ++i) m.nodes.row(i) += Eigen::RowVector3d(0.05, 0.03, 0.02);
  ASSERT_GT(msk::tetVolumes(m).minCoeff(), 0.0);
  const double before = msk::tetShapeQualities(m).minCoeff();
  const double after = msk::improveTetShapes(m, steiner);
  EXPECT_GT(after, before);
  EXPECT_NEAR(after, msk::tetShapeQualities(m).minCoeff(), 1e-12);
  EXPECT_GT(msk::tetVolumes(m).minCoeff(), 0.0);
  EXPECT_TRUE(m.nodes.topRows(cube.nodeCount()) == cube.nodes);
  EXPECT_NEAR(msk::tetShapeQualities(cube).maxCoeff(), msk::tetShapeQualities(cube).minCoeff(), 1e-12);
}

// untangleTetMesh(): without interior nodes in the folded tets (the plain folded block) the interior pass can do
// nothing; the boundary pass moves the surface nodes near them, no further than the reach, and the total volume
// changes only through those moves. With bridges split, the interior pass alone is enough.
TEST(TetUntangle, BoundaryPassStaysWithinReach) {
  const msk::TetMesh plain = msk::makeCubeTets(3, 1.0);
  auto fold = [](msk::TetMesh& m) {
    for (int i = 0; i < m.nodeCount(); ++i) {
      const Eigen::RowVector3d p = m.nodes.row(i);
      if (std::fabs(p.y()) < 1e-9 && std::fabs(p.z() - 3.0) < 1e-9 && p.x() > 0.5 && p.x() < 2.5)
        m.nodes.row(i) += Eigen::RowVector3d(0, 0.7, -0.7);
    }
  };
  msk::TetMesh m = plain;
  fold(m);
  const msk::Points folded = m.nodes;
  const msk::TetMeshUntangleReport r = msk::untangleTetMesh(m, msk::tetVolumes(plain), 0.2);
  EXPECT_GT(r.interior.invertedAfter, 0);
  EXPECT_LE(r.invertedAfter, r.interior.invertedAfter);
  EXPECT_GT(r.boundaryNodesMoved, 0);
  EXPECT_LE(r.largestBoundaryMoveMm, 0.2 + 1e-12);
  const std::vector<char> interior = interiorOf(plain);
  double largest = 0;
  for (int i = 0; i < m.nodeCount(); ++i)
    if (!interior[static_cast<size_t>(i)]) largest = std::max(largest, (m.nodes.row(i) - folded.row(i)).norm());
  EXPECT_NEAR(largest, r.largestBoundaryMoveMm, 1e-12);

  const msk::TetMesh split = msk::splitBoundaryTets(plain, nullptr, msk::BoundarySplit::Bridges);
  msk::TetMesh b = split;
  fold(b);
  const msk::TetMeshUntangleReport rb = msk::untangleTetMesh(b, msk::tetVolumes(split), 0.2);
  EXPECT_EQ(rb.invertedAfter, 0);
  EXPECT_EQ(rb.boundaryNodesMoved, 0);
}

// improveWorstTetShapes(): interior nodes of a block scrambled a little (still valid) are moved only around the badly
// shaped tets; the worst quality rises, the boundary and the total volume stay, every tet stays positive.
TEST(TetUntangle, WorstShapesImprovedInside) {
  const msk::TetMesh rest = msk::makeCubeTets(4, 1.0);
  const std::vector<char> movable = interiorOf(rest);
  msk::TetMesh m = scrambled(rest, movable, 8, 0.3);
  ASSERT_GT(msk::tetVolumes(m).minCoeff(), 0.0);
  const double before = msk::tetShapeQualities(m).minCoeff();
  const double after = msk::improveWorstTetShapes(m, 0.3);
  EXPECT_GT(after, before);
  EXPECT_GT(msk::tetVolumes(m).minCoeff(), 0.0);
  EXPECT_NEAR(msk::totalVolume(m), msk::totalVolume(rest), 1e-9);
  for (int i = 0; i < m.nodeCount(); ++i) {
    if (!movable[static_cast<size_t>(i)]) {
      EXPECT_TRUE(m.nodes.row(i) == rest.nodes.row(i));
    }
  }
  EXPECT_THROW(msk::improveWorstTetShapes(m, std::nan("")), msk::ParameterError);
}
