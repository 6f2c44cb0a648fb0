// Benchmarks of scene loading: the "auto" collision pairs (which templates come within a distance) on a synthetic
// scene of 24 structures of about 2500 vertices each (the size of the 24-structure phantom), and on the bundled thigh.
// Run: build/bench/scene_bench
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/surface_proximity.h"

namespace {

// 24 ellipsoids (2562 vertices each) in a 4 × 6 grid whose neighbours along x touch within ~1 mm and along y are
// 3 mm apart: with D = 2 mm, the 18 x-neighbour pairs are selected (and every box test along y still runs).
std::vector<msk::TriangleMesh> gridOfStructures() {
  std::vector<msk::TriangleMesh> meshes;
  for (int j = 0; j < 6; ++j)
    for (int i = 0; i < 4; ++i) {
      msk::TriangleMesh m = msk::makeIcosphere(1.0, 4);
      m.vertices.col(0) *= 15.0;  // semi-axes 15 × 10 × 40 mm
      m.vertices.col(1) *= 10.0;
      m.vertices.col(2) *= 40.0;
      m.vertices.rowwise() += Eigen::RowVector3d(31.0 * i, 23.0 * j, 0);
      meshes.push_back(std::move(m));
    }
  return meshes;
}

void BM_AutoPairs24Structures(benchmark::State& state) {
  const std::vector<msk::TriangleMesh> meshes = gridOfStructures();
  std::vector<const msk::TriangleMesh*> ptrs;
  for (const auto& m : meshes) ptrs.push_back(&m);
  size_t pairs = 0;
  for (auto _ : state) {
    const auto found = msk::surfacesWithin(ptrs, 2.0);
    pairs = found.size();
    benchmark::DoNotOptimize(found.data());
  }
  state.counters["structures"] = static_cast<double>(meshes.size());
  state.counters["vertices_each"] = meshes[0].vertexCount();
  state.counters["pairs_found"] = static_cast<double>(pairs);
}
BENCHMARK(BM_AutoPairs24Structures)->Unit(benchmark::kMillisecond);

// The bundled thigh scene (4 objects) loaded with "collisions": "auto" instead of its six declared pairs.
void BM_AutoPairsBundledThigh(benchmark::State& state) {
  const std::string sample = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1/scene.json";
  const msk::Scene scene = msk::loadScene(sample);
  std::vector<const msk::TriangleMesh*> ptrs;
  for (const auto& o : scene.objects) ptrs.push_back(&o.templ);
  size_t pairs = 0;
  for (auto _ : state) {
    const auto found = msk::surfacesWithin(ptrs, 2.0);
    pairs = found.size();
    benchmark::DoNotOptimize(found.data());
  }
  state.counters["vertices_each"] = scene.objects[0].templ.vertexCount();
  state.counters["pairs_found"] = static_cast<double>(pairs);
}
BENCHMARK(BM_AutoPairsBundledThigh)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
