// Constraint-projection kernels: projections per second on one core for every constraint type, and how the
// cost of a sweep grows with the vertex count, 10³ to 10⁶ vertices (benchmark's complexity fit, BigO lines).
// Run: scripts/bench-kernels.sh (builds, runs with a short min time, prints M projections/s and scaling exponents),
// or build-*/bench/kernels_bench [--benchmark_filter=Internal].
//
// Meshes: simplex spheres, dual of an icosphere subdivided s = 3..8 times (20·4^s vertices: 1 280 .. 1 310 720);
// volume models: dual of an n³ block of Freudenthal cubes (6n³ tets + 12n² ghosts). Every sweep is one pass over all
// constraints of a set in its own (Gauss–Seidel) order, single-threaded (BM_SolverInternalThreads: 1 and 2 threads).
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <utility>

#include "msk/core/collision_constraint.h"
#include "msk/core/collision_surface.h"
#include "msk/core/constraint_set.h"
#include "msk/core/medial_axis.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/simplex_batch.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/solver.h"
#include "msk/core/target_constraint.h"
#include "msk/core/transform_fit.h"
#include "msk/core/triangle_mesh.h"
#include "msk/core/volume_simplex.h"
#include "msk/core/winding_number.h"
#include "msk/test/shapes.h"
#include "msk/test/solver_scenarios.h"

namespace {

/// Icosphere subdivision levels benchmarked: 20·4^s simplex vertices.
constexpr int kMinLevel = 3, kMaxLevel = 8;

/// Triangle mesh and dual simplex mesh of the unit icosphere at subdivision s (built once, reused).
const std::pair<msk::TriangleMesh, msk::SimplexMesh>& unitSphere(int s) {
  static std::map<int, std::pair<msk::TriangleMesh, msk::SimplexMesh>> cache;
  auto it = cache.find(s);
  if (it == cache.end())
    it = cache.emplace(s, std::make_pair(msk::makeIcosphere(1.0, s), msk::test::simplexSphere(1.0, s))).first;
  return it->second;
}

/// Simplex sphere of radius r (mm) at subdivision s.
msk::SimplexMesh scaledSphere(int s, double r) {
  msk::SimplexMesh m = unitSphere(s).second;
  m.positions *= r;
  return m;
}

/// Mean distance between simplex neighbours (mm).
double meanSimplexEdge(const msk::SimplexMesh& m) {
  double sum = 0;
  for (int v = 0; v < m.vertexCount(); ++v)
    for (int j = 0; j < 3; ++j) sum += (m.positions.row(v) - m.positions.row(m.neighbors(v, j))).norm();
  return sum / (3.0 * m.vertexCount());
}

using msk::test::perturbed;

/// The timed loop of a constraint set's benchmark: one ConstraintSet::project() sweep of `c` over `p` per iteration.
void projectEveryIteration(benchmark::State& state, msk::ConstraintSet& c, msk::Points& p, const Eigen::VectorXd& w) {
  for (auto _ : state) {
    c.project(p, w);
    benchmark::DoNotOptimize(p.data());
    benchmark::ClobberMemory();
  }
}

/// Records items (projections), the complexity N (default: the vertex count n) and the usual counters.
void finish(benchmark::State& state, int64_t perSweep, int64_t n, int64_t complexityN = -1) {
  state.SetItemsProcessed(state.iterations() * perSweep);
  state.SetComplexityN(complexityN >= 0 ? complexityN : n);
  state.counters["vertices"] = static_cast<double>(n);
  state.counters["complexity_n"] = static_cast<double>(complexityN >= 0 ? complexityN : n);
  state.counters["ns_per_item"] = benchmark::Counter(static_cast<double>(perSweep) * state.iterations(),
                                                     benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// 2-simplex internal constraint (shape memory), one Gauss–Seidel sweep over every vertex of a sphere of radius 50 mm.
void BM_SimplexInternal(benchmark::State& state) {
  const msk::SimplexMesh s = scaledSphere(static_cast<int>(state.range(0)), 50.0);
  msk::SimplexInternalConstraints c(s, 0.5);
  msk::Points p = perturbed(s.positions, 0.2 * meanSimplexEdge(s));
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(s.vertexCount());
  projectEveryIteration(state, c, p, w);
  state.counters["skipped"] = c.skipped();
  finish(state, s.vertexCount(), s.vertexCount());
}
BENCHMARK(BM_SimplexInternal)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

// 2-simplex internal constraint, smoothing mode (ε̃ = 1/3, neighbourhood-mean heights: two extra passes).
void BM_SimplexInternalSmoothing(benchmark::State& state) {
  const msk::SimplexMesh s = scaledSphere(static_cast<int>(state.range(0)), 50.0);
  msk::SimplexInternalConstraints c(s, 0.5, msk::InternalMode::Smoothing);
  msk::Points p = perturbed(s.positions, 0.2 * meanSimplexEdge(s));
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(s.vertexCount());
  projectEveryIteration(state, c, p, w);
  finish(state, s.vertexCount(), s.vertexCount());
}
BENCHMARK(BM_SimplexInternalSmoothing)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

// The bare kernels on one fixed neighbourhood (no memory traffic): the ceiling of a sweep.
void BM_SimplexInternalKernelOnly(benchmark::State& state) {
  const Eigen::Vector3d pi[3] = {{10, 0, 0}, {-5, 8.7, 0.3}, {-5, -8.7, -0.2}};
  const double eps[3] = {0.3, 0.3, 0.4}, wi[3] = {1, 1, 1};
  Eigen::Vector3d p(0.2, 0.1, 3.0);
  for (auto _ : state) {
    Eigen::Vector3d target, dp, dpi[3];
    benchmark::DoNotOptimize(p);
    if (msk::simplexShapeTarget(pi, eps, 0.25, target) &&
        msk::simplexInternalCorrection(p, pi, target, 1.0, wi, eps, 0.5, dp, dpi)) {
      benchmark::DoNotOptimize(dp);
      benchmark::DoNotOptimize(dpi[0]);
    }
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SimplexInternalKernelOnly);

// The 2-simplex internal set run by the solver of every position-based scheme (solver.h), one thread, 10 iterations per
// step from a sphere scaled by 1.05: items = iterations × vertices per step (colouring and caches set up untimed). The
// coloured and Jacobi schemes run the set's batch kernel (simplex_batch.h) on the widest instruction set available, in
// its locality order; on one thread, from 32 768 vertices, the colours as a wavefront and Jacobi fused (compute and
// apply chunk by chunk). The step's own passes (prediction, velocities, damping) are included.
void BM_SolverInternal(benchmark::State& state, msk::Scheme scheme) {
  const msk::SimplexMesh s = scaledSphere(static_cast<int>(state.range(0)), 50.0);
  const int n = s.vertexCount();
  msk::SimplexInternalConstraints c(s, 1.0);
  msk::SolverOptions o;
  o.scheme = scheme;
  o.iterations = 10;
  o.threads = 1;
  msk::Solver solver(o);
  solver.prepare(1.05 * s.positions, Eigen::VectorXd::Ones(n));
  const std::vector<msk::ConstraintSet*> sets = {&c};
  solver.step(sets);
  for (auto _ : state) benchmark::DoNotOptimize(solver.step(sets));
  finish(state, static_cast<int64_t>(o.iterations) * n, n);
}
BENCHMARK_CAPTURE(BM_SolverInternal, gauss_seidel, msk::Scheme::GaussSeidel)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMillisecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_SolverInternal, coloured, msk::Scheme::ColouredGaussSeidel)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMillisecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_SolverInternal, jacobi, msk::Scheme::Jacobi)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMillisecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_SolverInternal, xpbd, msk::Scheme::Xpbd)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMillisecond)
    ->Complexity();

// The same set of the sphere problem of the solver's tests (radius 10 mm, 20 480 vertices, γ = 0.8) on 1 and 2 threads
// (the argument), each scheme at its test settings with 10 iterations per step, from the sphere scaled by 1.05: items
// = iterations × vertices per step, wall time (the threads share the step).
void BM_SolverInternalThreads(benchmark::State& state, msk::Scheme scheme) {
  const msk::test::SphereProblem s = msk::test::sphereProblem(5);
  const int n = s.internal->rowCount();
  msk::SolverOptions o = msk::test::sphereProblemOptions(scheme);
  o.iterations = 10;
  o.threads = static_cast<int>(state.range(0));
  msk::Solver solver(o);
  solver.prepare(1.05 * s.x0, s.w);
  const std::vector<msk::ConstraintSet*> sets = {s.internal.get()};
  solver.step(sets);  // colouring and caches
  for (auto _ : state) benchmark::DoNotOptimize(solver.step(sets));
  if (!solver.positions().allFinite()) state.SkipWithError("the run is not finite");
  finish(state, static_cast<int64_t>(o.iterations) * n, n);
  state.counters["threads"] = o.threads;
}
BENCHMARK_CAPTURE(BM_SolverInternalThreads, gauss_seidel, msk::Scheme::GaussSeidel)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_SolverInternalThreads, coloured, msk::Scheme::ColouredGaussSeidel)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_SolverInternalThreads, jacobi, msk::Scheme::Jacobi)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_SolverInternalThreads, xpbd, msk::Scheme::Xpbd)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The same set through the batch kernel (simplex_batch.h): rows as a struct of arrays, on a packed copy of the
// particles, sixteen rows at a time with AVX-512 or eight with AVX2 (the widest the processor has, chosen at run time),
// eight with AVX2 (`_avx2`) or two with SSE2 (`_sse2`), no virtual call. Every sweep includes filling the packed copy
// from the solver's arrays and writing it back. One thread; one sweep per iteration over every
// vertex of the perturbed sphere of BM_SimplexInternal (γ = 0.5, unit masses): a weighted-sum Jacobi iteration
// (ω = 1.5: corrections from the same positions, then scaled and applied; jacobiSweep() with its every-row-kept
// shortcut), the same through the four steps a multi-set solver calls (`jacobi_counted`: compute, count, scale,
// apply), or a coloured Gauss–Seidel sweep. Items = projections; compare BM_SolverInternal/jacobi and /coloured, the
// same schemes in the Solver. `_mesh_order`: the batch kept in the mesh's vertex order (BatchOrder::Mesh; bitwise the
// same results), whose gathers and colour passes range over the whole packed copy.
enum class BatchMode { Jacobi, JacobiCounted, Coloured };
void BM_BatchInternal(benchmark::State& state, BatchMode mode, msk::BatchLanes lanes,
                      msk::BatchOrder order = msk::BatchOrder::Locality) {
  const msk::SimplexMesh s = scaledSphere(static_cast<int>(state.range(0)), 50.0);
  const int n = s.vertexCount();
  msk::SimplexInternalBatch batch(s, 0.5, order);
  batch.useLanes(lanes);
  msk::Points p = perturbed(s.positions, 0.2 * meanSimplexEdge(s));
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  Eigen::VectorXi counts(n);
  int skipped = 0;
  {  // one untimed sweep: the batch allocates its fused Jacobi buffers on first use
    msk::Points q = p;
    if (mode == BatchMode::Coloured)
      batch.colouredSweep(q, w);
    else
      batch.jacobiSweep(q, w, 1.5);
  }
  for (auto _ : state) {
    switch (mode) {
      case BatchMode::Jacobi:
        skipped = batch.jacobiSweep(p, w, 1.5);
        break;
      case BatchMode::JacobiCounted:
        batch.loadRange(p, w, 0, n);
        skipped = batch.computeRange(0, n);
        counts.setZero();
        batch.addCounts(w, counts);
        batch.scaleRange(counts, 1.5, 0, n);
        batch.applyRange(p, 0, n);
        break;
      case BatchMode::Coloured:
        skipped = batch.colouredSweep(p, w);
        break;
    }
    benchmark::DoNotOptimize(p.data());
    benchmark::ClobberMemory();
  }
  state.counters["skipped"] = skipped;
  state.counters["colours"] = batch.colours();
  const msk::BatchLanes used = batch.lanes();
  state.counters["lanes"] = used == msk::BatchLanes::Avx512 ? 16 : used == msk::BatchLanes::Avx2 ? 8 : 2;
  finish(state, n, n);
}
BENCHMARK_CAPTURE(BM_BatchInternal, jacobi, BatchMode::Jacobi, msk::BatchLanes::Avx512)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, jacobi_counted, BatchMode::JacobiCounted, msk::BatchLanes::Avx512)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, coloured, BatchMode::Coloured, msk::BatchLanes::Avx512)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, jacobi_mesh_order, BatchMode::Jacobi, msk::BatchLanes::Avx512,
                  msk::BatchOrder::Mesh)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, coloured_mesh_order, BatchMode::Coloured, msk::BatchLanes::Avx512,
                  msk::BatchOrder::Mesh)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, jacobi_avx2, BatchMode::Jacobi, msk::BatchLanes::Avx2)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, coloured_avx2, BatchMode::Coloured, msk::BatchLanes::Avx2)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, jacobi_sse2, BatchMode::Jacobi, msk::BatchLanes::Sse2)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();
BENCHMARK_CAPTURE(BM_BatchInternal, coloured_sse2, BatchMode::Coloured, msk::BatchLanes::Sse2)
    ->DenseRange(kMinLevel, kMaxLevel)
    ->Unit(benchmark::kMicrosecond)
    ->Complexity();

// Image target constraints (one per vertex, weight 1).
void BM_ImageTargets(benchmark::State& state) {
  const msk::SimplexMesh s = scaledSphere(static_cast<int>(state.range(0)), 50.0);
  const int n = s.vertexCount();
  msk::TargetConstraints c(0.25);
  c.setTargets(perturbed(s.positions * 1.02, 0.5, 2), Eigen::VectorXd::Ones(n));
  msk::Points p = s.positions;
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  projectEveryIteration(state, c, p, w);
  finish(state, n, n);
}
BENCHMARK(BM_ImageTargets)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

// Global shape prior (similarity fit + pull), items = vertices.
void BM_ShapePrior(benchmark::State& state) {
  const msk::SimplexMesh s = scaledSphere(static_cast<int>(state.range(0)), 50.0);
  const int n = s.vertexCount();
  msk::ShapeMatchingConstraint c(s.positions, msk::PriorTransform::Similarity, 0.1);
  msk::Points p = perturbed(s.positions * 1.05, 1.0, 3);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  projectEveryIteration(state, c, p, w);
  finish(state, n, n);
}
BENCHMARK(BM_ShapePrior)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

/// Two simplex spheres of radius r stacked in one particle system, B's centre 1.8 r along x (a cap of A overlaps B),
/// with B's fan triangles as the partner surface of A.
struct CollisionPair {
  msk::Points p;
  Eigen::VectorXd w;
  msk::Triangles trianglesB;
  int na = 0;
  double edge = 0;
};

CollisionPair collisionPair(int s, double r) {
  const msk::SimplexMesh a = scaledSphere(s, r);
  CollisionPair c;
  c.na = a.vertexCount();
  c.edge = meanSimplexEdge(a);
  c.p.resize(2 * c.na, 3);
  c.p.topRows(c.na) = a.positions;
  c.p.bottomRows(c.na) = a.positions.rowwise() + Eigen::RowVector3d(1.8 * r, 0, 0);
  c.w = Eigen::VectorXd::Ones(2 * c.na);
  c.trianglesB = msk::simplexFanTriangles(a).array() + c.na;
  return c;
}

/// Sphere radius (mm) giving a mean simplex edge of about 1 mm at subdivision s (the surface grows with the mesh).
double unitEdgeRadius(int s) { return 1.0 / meanSimplexEdge(unitSphere(s).second); }

// Collision detection of A's vertices against B (grid rebuild over B's triangles + closest-point queries, with the
// inside test). "FixedSize": radius 50 mm, reach 1.2 mm (gap 0.2 + proximity 1): the mesh refines under a fixed
// reach, as when a finer template of the same bone is used. "UnitEdge": the spheres grow so the mean edge stays
// ~1 mm, reach 1.2 mm: the surface grows with the vertex count. Items = queried vertices.
void collisionDetect(benchmark::State& state, bool unitEdge) {
  const int s = static_cast<int>(state.range(0));
  const CollisionPair c = collisionPair(s, unitEdge ? unitEdgeRadius(s) : 50.0);
  msk::CollisionConstraints set(0, c.na, c.trianglesB, 0.2, 1.0, 0.0);
  for (auto _ : state) {
    set.detect(c.p, true);
    benchmark::DoNotOptimize(set.contacts());
  }
  state.counters["contacts"] = set.contacts();
  state.counters["edge_mm"] = c.edge;
  finish(state, c.na, c.na);
}
void BM_CollisionDetectFixedSize(benchmark::State& state) { collisionDetect(state, false); }
void BM_CollisionDetectUnitEdge(benchmark::State& state) { collisionDetect(state, true); }
BENCHMARK(BM_CollisionDetectFixedSize)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();
BENCHMARK(BM_CollisionDetectUnitEdge)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

// Collision projection over the contacts of one detection (positions restored, untimed, before every sweep so each
// contact is violated). Items = contacts projected; complexity N = contacts (they lie along the intersection curve of
// the two spheres, so they grow like √vertices here).
void BM_CollisionProject(benchmark::State& state) {
  const int s = static_cast<int>(state.range(0));
  const CollisionPair c = collisionPair(s, unitEdgeRadius(s));
  msk::CollisionConstraints set(0, c.na, c.trianglesB, 0.2, 1.0, 0.0);
  set.detect(c.p, true);
  msk::Points p = c.p;
  for (auto _ : state) {
    state.PauseTiming();
    p = c.p;
    state.ResumeTiming();
    set.project(p, c.w);
    benchmark::DoNotOptimize(p.data());
    benchmark::ClobberMemory();
  }
  state.counters["contacts"] = set.contacts();
  finish(state, set.contacts(), c.na, set.contacts());
}
BENCHMARK(BM_CollisionProject)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

// Radial constraints of a tube-like ellipsoid (semi-axes r, r, 3r; r = 20 mm) bound to its medial axis (40 slices),
// axis particles stacked after the surface with the mass of the surface they carry. Items = surface vertices.
void BM_Radial(benchmark::State& state) {
  const int s = static_cast<int>(state.range(0));
  msk::TriangleMesh t = unitSphere(s).first;
  msk::SimplexMesh m = unitSphere(s).second;
  const Eigen::Vector3d axes(20, 20, 60);
  t.vertices = t.vertices * axes.asDiagonal();
  m.positions = m.positions * axes.asDiagonal();
  msk::MedialAxisOptions mo;
  mo.slices = 40;
  const msk::MedialAxis axis = msk::buildMedialAxis(t, mo);
  const msk::RadialAttachment att = msk::attachToAxis(m.positions, axis.curve.positions);
  const int n = m.vertexCount(), na = axis.curve.vertexCount();
  msk::Points p(n + na, 3);
  p.topRows(n) = perturbed(m.positions, 0.3, 4);
  p.bottomRows(na) = axis.curve.positions;
  Eigen::VectorXd w(n + na);
  w.head(n).setOnes();
  w.tail(na) = msk::axisInverseMass(att, na, w.head(n));
  msk::RadialConstraints c(att, n, 0.5);
  projectEveryIteration(state, c, p, w);
  finish(state, n, n);
}
BENCHMARK(BM_Radial)->DenseRange(kMinLevel, kMaxLevel)->Unit(benchmark::kMicrosecond)->Complexity();

// 3-simplex internal constraints of a volume model (tets and ghosts constrained), cube block of n³ cells, 2 mm.
void BM_VolumeSimplex(benchmark::State& state) {
  const msk::VolumeSimplexMesh vm =
      msk::volumeSimplexFromTets(msk::makeCubeTets(static_cast<int>(state.range(0)), 2.0));
  msk::VolumeSimplexConstraints c(vm, 0.5, msk::VolumeBoundary::Constrained);
  const int n = vm.vertexCount();
  msk::Points p = perturbed(vm.simplex.positions, 0.1, 5);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  projectEveryIteration(state, c, p, w);
  state.counters["skipped"] = c.skipped();
  finish(state, n, n);
}
// 6, 13, 27, 55 cells a side: 1 728, 15 210, 126 846, 1 034 550 vertices.
BENCHMARK(BM_VolumeSimplex)->Arg(6)->Arg(13)->Arg(27)->Arg(55)->Unit(benchmark::kMicrosecond)->Complexity();

}  // namespace

// Winding number (the inside test of collision detection and of the output separation): one query at each of the
// icosphere's vertices moved 0.5 mm in and out along the normal, the sphere scaled to a mean edge of about 2 mm (a
// template of a few thousand vertices on a thigh muscle), clusters of one edge as the collision surfaces use them.
// Items = queries.
void BM_WindingNumberNearSurface(benchmark::State& state) {
  const int s = static_cast<int>(state.range(0));
  msk::TriangleMesh m = unitSphere(s).first;
  const double radius = 2.0 / msk::meanEdgeLength(m);
  m.vertices *= radius;
  const msk::WindingNumber winding(m.vertices, m.faces, 2.0);
  std::vector<Eigen::Vector3d> queries;
  for (int v = 0; v < m.vertexCount(); ++v) {
    const Eigen::Vector3d x = m.vertices.row(v).transpose();
    queries.push_back(x * (1.0 + (v % 2 == 0 ? 0.5 : -0.5) / radius));
  }
  int inside = 0;
  for (auto _ : state) {
    inside = 0;
    for (const Eigen::Vector3d& q : queries) inside += winding.inside(q);
    benchmark::DoNotOptimize(inside);
  }
  state.counters["inside"] = inside;
  state.counters["triangles"] = static_cast<double>(m.faceCount());
  finish(state, static_cast<int64_t>(queries.size()), m.faceCount());
}
BENCHMARK(BM_WindingNumberNearSurface)->DenseRange(3, 6)->Unit(benchmark::kMicrosecond)->Complexity();

BENCHMARK_MAIN();
