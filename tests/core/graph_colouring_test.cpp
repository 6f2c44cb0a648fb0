#include "msk/core/graph_colouring.h"

#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "msk/core/constraint_row.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/test/shapes.h"

// The rows of a 2-simplex sphere's shape memory, coloured: rows of one colour share no particle.
TEST(GraphColouring, NoColourSharesAParticleAndEveryConstraintIsColouredOnce) {
  const msk::SimplexInternalConstraints set(msk::test::simplexSphere(10.0, 3), 0.8);
  const msk::Colouring c = msk::colourConstraints(set.rowCount(), msk::kMaxRowParticles,
                                                  [&](int r, int* out) { return set.rowParticles(r, out); });
  EXPECT_GE(c.colours(), 4);
  EXPECT_LE(c.colours(), 13);  // Δ + 1: a row shares particles with at most 12 others on a 2-simplex mesh
  std::vector<int> seen(static_cast<size_t>(set.rowCount()), 0);
  for (int k = 0; k < c.colours(); ++k) {
    std::set<int> used;
    for (int i = c.start[static_cast<size_t>(k)]; i < c.start[static_cast<size_t>(k) + 1]; ++i) {
      const int r = c.order[static_cast<size_t>(i)];
      ++seen[static_cast<size_t>(r)];
      int idx[msk::kMaxRowParticles];
      const int m = set.rowParticles(r, idx);
      for (int j = 0; j < m; ++j) EXPECT_TRUE(used.insert(idx[j]).second) << "colour " << k << " row " << r;
    }
  }
  for (int x : seen) EXPECT_EQ(x, 1);
}
