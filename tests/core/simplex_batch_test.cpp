// Batch 2-simplex internal kernel (simplex_batch.h) against the Solver's per-row path (solver.h over
// SimplexInternalConstraints rows): coloured Gauss–Seidel and Jacobi sweeps agree to 1e-12 relative on perturbed
// spheres with mixed, extreme and fixed masses and degenerate neighbourhoods, and the same rows are skipped.
#include "msk/core/simplex_batch.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>

#include "msk/core/constraint_row.h"
#include "msk/core/error.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/solver.h"
#include "msk/core/triangle_mesh.h"
#include "msk/test/particles.h"
#include "msk/test/shapes.h"

namespace {

using msk::Points;
using msk::test::bitwiseEqual;

/// Every instruction set of the sweeps (each falls back to the widest narrower one the processor has).
constexpr msk::BatchLanes kAllLanes[] = {msk::BatchLanes::Sse2, msk::BatchLanes::Avx2, msk::BatchLanes::Avx512};

/// A perturbed simplex sphere (radius 50 mm) stacked after `offset` unconstrained particles, with random inverse masses
/// spread over `massDecades` decades around 1, a fixed neighbourhood (vertex 7 and its neighbours), a few other fixed
/// vertices, and vertex 100's first two neighbours made coincident (a degenerate neighbourhood).
struct Problem {
  msk::SimplexMesh reference;
  Points p0;
  Eigen::VectorXd w;
  int offset = 0;
};

Problem makeProblem(int subdivisions, double perturbation, double massDecades, int offset, unsigned seed,
                    bool defects = true) {
  Problem pr;
  pr.reference = msk::test::simplexSphere(50.0, subdivisions);
  const int n = pr.reference.vertexCount();
  pr.offset = offset;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double edge = 0;
  for (int v = 0; v < n; ++v)
    edge += (pr.reference.positions.row(v) - pr.reference.positions.row(pr.reference.neighbors(v, 0))).norm();
  edge /= n;
  pr.p0 = Points::Zero(offset + n, 3);
  pr.w = Eigen::VectorXd::Ones(offset + n);
  for (int i = 0; i < offset; ++i) pr.p0.row(i) << 100.0 + i, 0, 0;
  for (int v = 0; v < n; ++v) {
    pr.p0.row(offset + v) = pr.reference.positions.row(v);
    for (int c = 0; c < 3; ++c) pr.p0(offset + v, c) += perturbation * edge * u(rng);
    pr.w[offset + v] = std::pow(10.0, 0.5 * massDecades * u(rng));
  }
  if (!defects) return pr;
  pr.w[offset + 7] = 0;
  for (int j = 0; j < 3; ++j) pr.w[offset + pr.reference.neighbors(7, j)] = 0;
  for (int v = 31; v < n; v += 97) pr.w[offset + v] = 0;
  pr.p0.row(offset + pr.reference.neighbors(100, 1)) = pr.p0.row(offset + pr.reference.neighbors(100, 0));
  return pr;
}

/// Positions after `iterations` sweeps of the Solver's scheme over the set's rows (one step from rest): row by row
/// (the reference), or with the set's batch kernel as the Solver runs it by default, on `threads` threads.
Points solverSweeps(const Problem& pr, msk::Scheme scheme, int iterations, double gamma, double omega,
                    bool batch = false, int threads = 1) {
  msk::SimplexInternalConstraints set(pr.reference, gamma);
  set.setFirstParticle(pr.offset);
  msk::SolverOptions o;
  o.scheme = scheme;
  o.iterations = iterations;
  o.omega = omega;
  o.threads = threads;
  o.batchKernels = batch;
  msk::Solver solver(o);
  solver.prepare(pr.p0, pr.w);
  solver.step({&set});
  return solver.positions();
}

/// Largest difference between a and b relative to the largest correction b − p0.
double relativeDifference(const Points& a, const Points& b, const Points& p0) {
  const double scale = (b - p0).cwiseAbs().maxCoeff();
  EXPECT_GT(scale, 0);
  return (a - b).cwiseAbs().maxCoeff() / scale;
}

/// Rows the per-row path skips at p0 (row() false, or W ≤ 0 / non-finite as the Solver tests it).
int rowPathSkips(const Problem& pr, double gamma) {
  msk::SimplexInternalConstraints set(pr.reference, gamma);
  set.setFirstParticle(pr.offset);
  set.beginRows(pr.p0, pr.w);
  int skipped = 0;
  for (int r = 0; r < set.rowCount(); ++r) {
    msk::ConstraintRow row;
    if (!set.row(r, pr.p0, pr.w, row)) {
      ++skipped;
      continue;
    }
    double W = 0;
    for (int j = 0; j < row.count; ++j) W += row.grad[j] * row.react[j] * pr.w[row.index[j]];
    if (!(W > 0) || !std::isfinite(W)) ++skipped;
  }
  return skipped;
}

struct Case {
  double perturbation, massDecades, gamma;
};

class SimplexBatchAgreement : public ::testing::TestWithParam<Case> {};

TEST_P(SimplexBatchAgreement, ColouredSweepsMatchTheSolver) {
  const Case c = GetParam();
  const Problem pr = makeProblem(3, c.perturbation, c.massDecades, 5, 11);
  const Points expected = solverSweeps(pr, msk::Scheme::ColouredGaussSeidel, 3, c.gamma, 1.0);
  for (msk::BatchLanes lanes : kAllLanes) {  // 2 rows at a time (SSE2), 8 (AVX2), 16 (AVX-512) where available
    msk::SimplexInternalBatch batch(pr.reference, c.gamma);
    batch.setFirstParticle(pr.offset);
    batch.useLanes(lanes);
    Points p = pr.p0;
    for (int it = 0; it < 3; ++it) batch.colouredSweep(p, pr.w);
    EXPECT_LT(relativeDifference(p, expected, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
    EXPECT_TRUE(p.topRows(pr.offset) == pr.p0.topRows(pr.offset));  // particles outside the set untouched
  }
}

TEST_P(SimplexBatchAgreement, JacobiSweepsMatchTheSolver) {
  const Case c = GetParam();
  const Problem pr = makeProblem(3, c.perturbation, c.massDecades, 5, 12);
  const double omega = 1.5;
  const Points expected = solverSweeps(pr, msk::Scheme::Jacobi, 3, c.gamma, omega);
  for (msk::BatchLanes lanes : kAllLanes) {
    msk::SimplexInternalBatch batch(pr.reference, c.gamma);
    batch.setFirstParticle(pr.offset);
    batch.useLanes(lanes);
    Points p = pr.p0;
    for (int it = 0; it < 3; ++it) batch.jacobiSweep(p, pr.w, omega);
    EXPECT_LT(relativeDifference(p, expected, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
  }
}

TEST_P(SimplexBatchAgreement, JacobiWithoutSkipsOrFixedParticlesMatchesTheSolver) {
  // Every row kept and every particle free: jacobiSweep() takes its shortcut (every share ω/4).
  const Case c = GetParam();
  const Problem pr = makeProblem(3, std::min(c.perturbation, 0.5), c.massDecades, 5, 15, false);
  const Points expected = solverSweeps(pr, msk::Scheme::Jacobi, 3, c.gamma, 1.5);
  for (msk::BatchLanes lanes : kAllLanes) {
    msk::SimplexInternalBatch batch(pr.reference, c.gamma);
    batch.setFirstParticle(pr.offset);
    batch.useLanes(lanes);
    Points p = pr.p0;
    for (int it = 0; it < 3; ++it) EXPECT_EQ(batch.jacobiSweep(p, pr.w, 1.5), 0);
    EXPECT_LT(relativeDifference(p, expected, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
  }
}

TEST_P(SimplexBatchAgreement, SkipsTheRowsThePerRowPathSkips) {
  const Case c = GetParam();
  const Problem pr = makeProblem(3, c.perturbation, c.massDecades, 5, 13);
  const int expected = rowPathSkips(pr, c.gamma);
  EXPECT_GE(expected, 2);  // the fixed neighbourhood and the degenerate one at least
  for (msk::BatchLanes lanes : kAllLanes) {
    msk::SimplexInternalBatch batch(pr.reference, c.gamma);
    batch.setFirstParticle(pr.offset);
    batch.useLanes(lanes);
    batch.loadRange(pr.p0, pr.w, 0, batch.size());
    EXPECT_EQ(batch.computeRange(0, batch.size()), expected);
    Points p = pr.p0;
    EXPECT_GE(batch.colouredSweep(p, pr.w), 1);  // the fixed neighbourhood stays fixed
  }
}

INSTANTIATE_TEST_SUITE_P(Spheres, SimplexBatchAgreement,
                         ::testing::Values(Case{0.2, 0.0, 0.5},    // the benchmark's setting, unit masses
                                           Case{0.2, 2.0, 1.0},    // masses over two decades, full stiffness
                                           Case{0.8, 6.0, 0.7},    // rough surface, masses over six decades
                                           Case{2.0, 1.0, 1.0}));  // neighbourhoods folded over

TEST(SimplexBatch, SmallMeshesWithPartialPacksMatchTheSolver) {
  // 20 vertices: every sweep ends on a partial pack (16, 8 or 2 rows at a time), in the rows and in the particles.
  for (int offset : {0, 3}) {
    const Problem pr = makeProblem(0, 0.3, 1.0, offset, 16, false);
    const Points coloured = solverSweeps(pr, msk::Scheme::ColouredGaussSeidel, 2, 0.9, 1.0);
    const Points jacobi = solverSweeps(pr, msk::Scheme::Jacobi, 2, 0.9, 1.3);
    for (msk::BatchLanes lanes : kAllLanes) {
      msk::SimplexInternalBatch batch(pr.reference, 0.9);
      batch.setFirstParticle(offset);
      batch.useLanes(lanes);
      Points p = pr.p0, q = pr.p0;
      for (int it = 0; it < 2; ++it) {
        batch.colouredSweep(p, pr.w);
        batch.jacobiSweep(q, pr.w, 1.3);
      }
      EXPECT_LT(relativeDifference(p, coloured, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
      EXPECT_LT(relativeDifference(q, jacobi, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
    }
  }
}

TEST(SimplexBatch, IrregularNeighbourTablesTakeTheGeneralJacobiPathAndMatchTheSolver) {
  // One neighbour redirected: particles no longer sit in exactly 4 rows, so counts and the apply take the CSR path.
  Problem pr = makeProblem(2, 0.3, 1.0, 4, 18, false);
  pr.reference.neighbors(0, 2) = pr.reference.vertexCount() / 2;
  const Points expected = solverSweeps(pr, msk::Scheme::Jacobi, 2, 0.9, 1.5);
  const Points colouredExpected = solverSweeps(pr, msk::Scheme::ColouredGaussSeidel, 2, 0.9, 1.0);
  for (msk::BatchLanes lanes : kAllLanes) {
    msk::SimplexInternalBatch batch(pr.reference, 0.9);
    batch.setFirstParticle(pr.offset);
    batch.useLanes(lanes);
    Points p = pr.p0, q = pr.p0;
    for (int it = 0; it < 2; ++it) {
      batch.jacobiSweep(p, pr.w, 1.5);
      batch.colouredSweep(q, pr.w);
    }
    EXPECT_LT(relativeDifference(p, expected, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
    EXPECT_LT(relativeDifference(q, colouredExpected, pr.p0), 1e-12) << "lanes " << static_cast<int>(batch.lanes());
  }
}

TEST(SimplexBatch, EveryLaneWidthGivesBitwiseTheSameSweeps) {
  // SSE2 (2 rows at a time) against AVX2 (8) and AVX-512 (16), where the processor has them (else the same path again).
  const Problem pr = makeProblem(4, 0.8, 2.0, 2, 17);
  for (bool jacobi : {false, true})
    for (msk::BatchLanes lanes : {msk::BatchLanes::Avx2, msk::BatchLanes::Avx512}) {
      msk::SimplexInternalBatch two(pr.reference, 0.8), wide(pr.reference, 0.8);
      two.setFirstParticle(pr.offset);
      wide.setFirstParticle(pr.offset);
      two.useLanes(msk::BatchLanes::Sse2);
      wide.useLanes(lanes);
      Points a = pr.p0, b = pr.p0;
      for (int it = 0; it < 10; ++it) {
        if (jacobi) {
          two.jacobiSweep(a, pr.w, 1.4);
          wide.jacobiSweep(b, pr.w, 1.4);
        } else {
          two.colouredSweep(a, pr.w);
          wide.colouredSweep(b, pr.w);
        }
      }
      EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())), 0)
          << (jacobi ? "jacobi" : "coloured") << " on lanes " << static_cast<int>(wide.lanes())
          << ", largest difference " << (a - b).cwiseAbs().maxCoeff();
    }
}

TEST(SimplexBatch, ColoursShareNoParticleAndCoverEveryRowOnce) {
  const msk::SimplexMesh m = msk::test::simplexSphere(10.0);
  const msk::SimplexInternalBatch batch(m, 1.0);
  ASSERT_EQ(batch.colourBegin(batch.colours()), m.vertexCount());
  std::vector<int> seen(static_cast<size_t>(m.vertexCount()), 0);
  for (int k = 0; k < batch.colours(); ++k) {
    std::vector<int> used(static_cast<size_t>(m.vertexCount()), 0);
    for (int r = batch.colourBegin(k); r < batch.colourBegin(k + 1); ++r) {
      const int v = batch.colourOrder(r);
      ++seen[static_cast<size_t>(v)];
      for (int j : {v, m.neighbors(v, 0), m.neighbors(v, 1), m.neighbors(v, 2)}) {
        EXPECT_EQ(used[static_cast<size_t>(j)], 0) << "colour " << k << " particle " << j;
        used[static_cast<size_t>(j)] = 1;
      }
    }
  }
  for (int s : seen) EXPECT_EQ(s, 1);
}

/// `pr` with its simplex vertices relabelled at random (neighbour table, positions and masses alike).
Problem shuffledProblem(const Problem& pr, unsigned seed) {
  const int n = pr.reference.vertexCount();
  std::vector<int> to(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) to[static_cast<size_t>(v)] = v;
  std::mt19937 rng(seed);
  std::shuffle(to.begin(), to.end(), rng);
  Problem out = pr;
  out.reference.faceOffsets.clear();
  out.reference.faceVertices.clear();
  for (int v = 0; v < n; ++v) {
    const int t = to[static_cast<size_t>(v)];
    out.reference.positions.row(t) = pr.reference.positions.row(v);
    for (int j = 0; j < 3; ++j) out.reference.neighbors(t, j) = to[static_cast<size_t>(pr.reference.neighbors(v, j))];
    out.p0.row(pr.offset + t) = pr.p0.row(pr.offset + v);
    out.w[pr.offset + t] = pr.w[pr.offset + v];
  }
  return out;
}

// The locality order (breadth-first places, each colour's rows in place order, the one-thread coloured wavefront)
// against the mesh's own order on a randomly relabelled sphere of 81 920 vertices (many wavefront chunks), with fixed
// particles, mixed masses and a degenerate row, and without them: every sweep gives bitwise the same positions.
TEST(SimplexBatch, LocalityOrderGivesBitwiseTheMeshOrderSweepsOnAShuffledMesh) {
  for (bool defects : {true, false}) {
    const Problem pr = shuffledProblem(makeProblem(6, 0.4, defects ? 2.0 : 0.0, 3, 23, defects), 5);
    const int n = pr.reference.vertexCount();
    msk::SimplexInternalBatch mesh(pr.reference, 0.8, msk::BatchOrder::Mesh), local(pr.reference, 0.8);
    ASSERT_EQ(local.order(), msk::BatchOrder::Locality);
    mesh.setFirstParticle(pr.offset);
    local.setFirstParticle(pr.offset);
    // A permutation whose neighbours sit close together (the shuffled numbering puts them ~n/3 apart).
    std::vector<int> place(static_cast<size_t>(n), -1);
    for (int i = 0; i < n; ++i) place[static_cast<size_t>(local.vertexAt(i))] = i;
    int reach = 0;
    for (int v = 0; v < n; ++v) {
      ASSERT_GE(place[static_cast<size_t>(v)], 0);
      for (int j = 0; j < 3; ++j)
        reach = std::max(
            reach, std::abs(place[static_cast<size_t>(v)] - place[static_cast<size_t>(pr.reference.neighbors(v, j))]));
    }
    EXPECT_LT(reach, 4 * static_cast<int>(std::sqrt(n)));
    // Coloured: the wavefront (colouredSweep) and colour by colour, against the mesh order colour by colour.
    Points a = pr.p0, b = pr.p0, c = pr.p0;
    for (int it = 0; it < 3; ++it) {
      mesh.loadRange(a, pr.w, 0, n);
      for (int k = 0; k < mesh.colours(); ++k) mesh.projectRange(mesh.colourBegin(k), mesh.colourBegin(k + 1));
      mesh.storeRange(a, 0, n);
      local.colouredSweep(b, pr.w);
      local.loadRange(c, pr.w, 0, n / 3);
      local.loadRange(c, pr.w, n / 3, n);
      for (int k = 0; k < local.colours(); ++k) local.projectRange(local.colourBegin(k), local.colourBegin(k + 1));
      local.storeRange(c, 0, n);
    }
    EXPECT_TRUE(bitwiseEqual(a, b)) << "wavefront, largest difference " << (a - b).cwiseAbs().maxCoeff();
    EXPECT_TRUE(bitwiseEqual(a, c)) << "colour by colour, largest difference " << (a - c).cwiseAbs().maxCoeff();
    EXPECT_GT((a - pr.p0).cwiseAbs().maxCoeff(), 0.0);
    // Jacobi: the set alone (equal shares where they hold), and the four steps with ranges split unevenly.
    a = pr.p0;
    b = pr.p0;
    for (int it = 0; it < 3; ++it) {
      mesh.jacobiSweep(a, pr.w, 1.4);
      local.jacobiSweep(b, pr.w, 1.4);
    }
    EXPECT_TRUE(bitwiseEqual(a, b)) << "jacobi, largest difference " << (a - b).cwiseAbs().maxCoeff();
    Points q[2] = {pr.p0, pr.p0};
    msk::SimplexInternalBatch* batches[2] = {&mesh, &local};
    for (int k = 0; k < 2; ++k) {
      msk::SimplexInternalBatch& bt = *batches[k];
      Eigen::VectorXi counts = Eigen::VectorXi::Zero(pr.w.size());
      bt.loadRange(q[k], pr.w, 0, n);
      bt.computeRange(0, n / 2);
      bt.computeRange(n / 2, n);
      bt.addCounts(pr.w, counts);
      bt.scaleRange(counts, 1.2, 0, n / 3);
      bt.scaleRange(counts, 1.2, n / 3, n);
      bt.applyRange(q[k], 0, n / 5);
      bt.applyRange(q[k], n / 5, n);
    }
    EXPECT_TRUE(bitwiseEqual(q[0], q[1]))
        << "counted jacobi, largest difference " << (q[0] - q[1]).cwiseAbs().maxCoeff();
    // The Solver: one thread (wavefront) and two (colour by colour, split) agree bitwise, in both schemes.
    for (msk::Scheme scheme : {msk::Scheme::ColouredGaussSeidel, msk::Scheme::Jacobi})
      EXPECT_TRUE(
          bitwiseEqual(solverSweeps(pr, scheme, 3, 0.8, 1.5, true, 1), solverSweeps(pr, scheme, 3, 0.8, 1.5, true, 2)))
          << msk::schemeName(scheme);
  }
}

TEST(SimplexBatch, JacobiConservesLinearMomentum) {
  Problem pr = makeProblem(3, 0.5, 2.0, 0, 14);
  pr.w = pr.w.cwiseMax(1e-3);  // every particle free
  msk::SimplexInternalBatch batch(pr.reference, 1.0);
  Points p = pr.p0;
  batch.jacobiSweep(p, pr.w, 1.2);
  Eigen::RowVector3d momentum = Eigen::RowVector3d::Zero();
  double scale = 0;
  for (int i = 0; i < p.rows(); ++i) {
    momentum += (p.row(i) - pr.p0.row(i)) / pr.w[i];
    scale += (p.row(i) - pr.p0.row(i)).norm() / pr.w[i];
  }
  ASSERT_GT(scale, 0);
  EXPECT_LT(momentum.norm() / scale, 1e-12);
}

TEST(SimplexBatch, RefusesBadStiffnessAndSizes) {
  const msk::SimplexMesh m = msk::test::simplexSphere(10.0, 1);
  EXPECT_THROW(msk::SimplexInternalBatch(m, 1.5), msk::ParameterError);
  EXPECT_THROW(msk::SimplexInternalBatch(m, -0.1), msk::ParameterError);
  msk::SimplexInternalBatch batch(m, 1.0);
  Points p = m.positions;
  EXPECT_THROW(batch.colouredSweep(p, Eigen::VectorXd::Ones(m.vertexCount() - 1)), msk::Error);
  batch.setFirstParticle(3);
  EXPECT_THROW(batch.jacobiSweep(p, Eigen::VectorXd::Ones(m.vertexCount()), 1.0), msk::Error);
}

/// Four Solver sweeps of `pr` in coloured Gauss–Seidel and in Jacobi: with the batch kernel on one and on two threads
/// they agree with the rows to 1e-12 and with each other bitwise, and they move something.
void expectSolverBatchMatchesRows(const Problem& pr) {
  for (msk::Scheme scheme : {msk::Scheme::ColouredGaussSeidel, msk::Scheme::Jacobi}) {
    const Points rows = solverSweeps(pr, scheme, 4, 0.8, 1.5, false, 1);
    const Points one = solverSweeps(pr, scheme, 4, 0.8, 1.5, true, 1);
    const Points two = solverSweeps(pr, scheme, 4, 0.8, 1.5, true, 2);
    EXPECT_LT(relativeDifference(one, rows, pr.p0), 1e-12) << msk::schemeName(scheme);
    EXPECT_TRUE(one == two) << msk::schemeName(scheme) << ": thread count changed the result";
    EXPECT_GT((one - pr.p0).cwiseAbs().maxCoeff(), 0.0);
  }
}

}  // namespace

// The Solver's coloured Gauss–Seidel and Jacobi schemes run the set's batch kernel by default: the same positions as
// row by row up to rounding, and bitwise the same on one and two threads (a colour's rows, or the Jacobi rows and
// particles, split between threads).
TEST(SimplexBatch, SolverRunsTheBatchWithTheRowsResultOnAnyThreadCount) {
  const Problem pr = makeProblem(4, 0.3, 2.0, 3, 17);
  expectSolverBatchMatchesRows(pr);
  // Smoothing mode has no batch: the rows run.
  msk::SimplexInternalConstraints smoothing(pr.reference, 0.5, msk::InternalMode::Smoothing);
  EXPECT_EQ(smoothing.batch(), nullptr);
  msk::SimplexInternalConstraints memory(pr.reference, 0.5);
  memory.setFirstParticle(3);
  ASSERT_NE(memory.batch(), nullptr);
  EXPECT_EQ(memory.batch()->firstParticle(), 3);
  EXPECT_EQ(memory.batch()->size(), pr.reference.vertexCount());
}

// Closed mesh, every particle free: the Solver's Jacobi takes the equal shares (ω/4, no counts) for a set counted
// alone; the coloured scheme keeps the packed copy between iterations. Both agree with the rows and are bitwise the
// same on one and two threads.
TEST(SimplexBatch, SolverShortcutsMatchTheRowsOnAnyThreadCount) {
  const Problem pr = makeProblem(4, 0.3, 2.0, 3, 19, false);
  expectSolverBatchMatchesRows(pr);
}

// Two batch sets on the same particles (different stiffness), swept in turn by the Solver: each sweep must see the
// other's corrections (the packed copy written back and reloaded between them), as the rows do.
TEST(SimplexBatch, SolverAlternatingBatchSetsMatchTheRows) {
  const Problem pr = makeProblem(3, 0.5, 1.0, 2, 20);
  for (msk::Scheme scheme : {msk::Scheme::ColouredGaussSeidel, msk::Scheme::Jacobi}) {
    Points result[2];
    for (int batch = 0; batch < 2; ++batch) {
      msk::SimplexInternalConstraints a(pr.reference, 0.9), b(pr.reference, 0.4);
      a.setFirstParticle(pr.offset);
      b.setFirstParticle(pr.offset);
      msk::SolverOptions o;
      o.scheme = scheme;
      o.iterations = 3;
      o.omega = 1.2;
      o.threads = 1;
      o.batchKernels = batch == 1;
      msk::Solver solver(o);
      solver.prepare(pr.p0, pr.w);
      solver.step({&a, &b});
      result[batch] = solver.positions();
    }
    EXPECT_LT(relativeDifference(result[1], result[0], pr.p0), 1e-12) << msk::schemeName(scheme);
  }
}
