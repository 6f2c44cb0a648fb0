// Mesh conversions and queries: the triangle ↔ simplex conversion, binding points to a surface, rasterising a surface
// on a large oblique grid, and a smooth template from a label. The tests check the results of the same operations;
// these time them.
// Run: build/bench/mesh_bench
#include <benchmark/benchmark.h>

#include "msk/core/simplex_mesh.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/grid.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/template_builder.h"
#include "msk/test/shapes.h"
#include "msk/test/volumes.h"

namespace {

// simplexFromTriangles and trianglesFromSimplex on icospheres of radius 20 mm subdivided 4 and 5 times (5 120 and
// 20 480 simplex vertices): both conversions per iteration.
void BM_SimplexConversion(benchmark::State& state) {
  const msk::TriangleMesh m = msk::makeIcosphere(20.0, static_cast<int>(state.range(0)));
  int vertices = 0;
  for (auto _ : state) {
    const msk::SimplexMesh s = msk::simplexFromTriangles(m);
    const msk::TriangleMesh back = msk::trianglesFromSimplex(s);
    vertices = s.vertexCount();
    benchmark::DoNotOptimize(back.vertices.data());
  }
  state.counters["simplex_vertices"] = vertices;
}
BENCHMARK(BM_SimplexConversion)->Arg(4)->Arg(5)->Unit(benchmark::kMillisecond);

// SurfaceTransfer: 50 000 points within ±10 % of a sphere of radius 20 mm bound to its 5120 triangles.
void BM_SurfaceTransfer(benchmark::State& state) {
  const msk::TriangleMesh source = msk::makeIcosphere(20.0, 4);
  const msk::Points targets = msk::test::pointsNearSphere(50000, 20.0, 0.1, 5);
  for (auto _ : state) {
    const msk::SurfaceTransfer transfer(source, targets);
    benchmark::DoNotOptimize(transfer.distances().data());
  }
  state.counters["points"] = static_cast<double>(targets.rows());
  state.counters["triangles"] = source.faceCount();
}
BENCHMARK(BM_SurfaceTransfer)->Unit(benchmark::kMillisecond);

// A sphere of 20 480 triangles (radius 45 mm) rasterised on a 256 × 256 × 100 grid of 0.4 × 0.4 × 1 mm, rotated
// (5°, 10°, −15°).
void BM_RasterizeLargeGrid(benchmark::State& state) {
  const Eigen::Vector3d c(1.5, -2.25, 3.0);
  const msk::TriangleMesh sphere = msk::makeIcosphere(45.0, 5, c);
  msk::Grid g;
  g.dims = {256, 256, 100};
  g.spacing = {0.4, 0.4, 1.0};
  g.direction = msk::Grid::rotationXYZ({5, 10, -15});
  g.origin = c - g.direction * g.spacing.cwiseProduct((g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2);
  for (auto _ : state) {
    const msk::LabelMap labels = msk::rasterize(sphere, g);
    benchmark::DoNotOptimize(labels.data.data());
  }
  state.counters["triangles"] = sphere.faceCount();
  state.counters["voxels"] = static_cast<double>(g.voxelCount());
}
BENCHMARK(BM_RasterizeLargeGrid)->Unit(benchmark::kMillisecond);

// A smooth template (3000 vertices) from a ball of radius 15 mm labelled on 1 × 1 × 3 mm voxels, off the voxel
// lattice; its volume against the ball's. (TemplateBuilder.BallOnThickSlicesIsSmoothClosedAndTrue checks it.)
void BM_TemplateFromBallLabels(benchmark::State& state) {
  const Eigen::Vector3d c(10, -20, 30);
  msk::Grid g;
  g.spacing = {1.0, 1.0, 3.0};
  g.dims = {48, 48, 18};
  g.origin = c - g.spacing.cwiseProduct((g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2) +
             Eigen::Vector3d(0.31, -0.17, 0.43);
  const msk::LabelMap labels = msk::test::ballLabels(g, c, 15.0, 7);
  msk::TriangleMesh m;
  for (auto _ : state) m = msk::templateFromLabels(labels, 7);
  state.counters["vertices"] = m.vertexCount();
  state.counters["volume_vs_ball_pct"] = 100 * (msk::enclosedVolume(m) / (4.0 / 3.0 * M_PI * 15 * 15 * 15) - 1);
}
BENCHMARK(BM_TemplateFromBallLabels)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
