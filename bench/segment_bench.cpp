// Benchmarks of the single-object pipeline: per-vertex cost of the kernels and the whole femur run on the bundled
// phantom. Run: build/bench/segment_bench  (add --benchmark_filter=Femur for the whole run only).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>

#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/simplex_mesh.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/image_forces.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"
#include "msk/test/shapes.h"

namespace {

const std::string kSample = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1";

// One Gauss–Seidel sweep of the 2-simplex shape-memory constraint over every vertex.
void BM_SimplexInternalSweep(benchmark::State& state) {
  const msk::SimplexMesh s = msk::test::simplexSphere(30.0, static_cast<int>(state.range(0)));
  msk::SimplexInternalConstraints c(s, 0.5);
  msk::Points p = s.positions * 1.01;
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(s.vertexCount());
  for (auto _ : state) {
    c.project(p, w);
    benchmark::DoNotOptimize(p.data());
  }
  state.SetItemsProcessed(state.iterations() * s.vertexCount());
  state.counters["vertices"] = s.vertexCount();
  state.counters["ns_per_vertex"] = benchmark::Counter(static_cast<double>(s.vertexCount()) * state.iterations(),
                                                       benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_SimplexInternalSweep)->Arg(3)->Arg(4)->Arg(5)->Arg(6)->Unit(benchmark::kMicrosecond);

// Image target search along the normals for every vertex of the femur template in the bundled sample.
void BM_TargetSearch(benchmark::State& state) {
  const msk::ImageF img = msk::readNifti<float>(kSample + "/image.nii.gz");
  const msk::Scene scene = msk::loadScene(kSample + "/scene.json");
  const msk::SimplexMesh s = msk::simplexFromTriangles(scene.objects[0].templ);
  const msk::ImageFeatures f = msk::computeImageFeatures(img, 0.6);
  const msk::Points normals = msk::simplexVertexNormals(s);
  msk::TargetSearchOptions o;
  for (auto _ : state) {
    auto r = msk::searchTargets(f, s.positions, normals, s.neighbors, o, msk::Polarity::DarkInside, img.grid);
    benchmark::DoNotOptimize(r.targets.data());
  }
  state.SetItemsProcessed(state.iterations() * s.vertexCount());
  state.counters["ns_per_vertex"] = benchmark::Counter(static_cast<double>(s.vertexCount()) * state.iterations(),
                                                       benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_TargetSearch)->Unit(benchmark::kMillisecond);

// The whole femur run at each preset on the bundled sample (one core), with its accuracy against the truth mesh.
void BM_FemurSegmentation(benchmark::State& state) {
  const msk::ImageF img = msk::readNifti<float>(kSample + "/image.nii.gz");
  msk::Scene scene = msk::loadScene(kSample + "/scene.json");
  scene.objects.resize(1);  // femur only
  scene.collisions.clear();
  msk::SegmentOptions opts;
  opts.evolution.quality = static_cast<msk::Quality>(state.range(0));
  msk::SegmentationResult res;
  for (auto _ : state) res = msk::segmentScene(img, scene, opts);
  const msk::ObjectResult& o = res.objects[0];
  int steps = 0, stepVertices = 0;
  for (const auto& l : o.levels) {
    steps += l.steps;
    stepVertices += l.steps * l.vertices;
  }
  const msk::LabelMap truth = msk::readNifti<int32_t>(kSample + "/labels.nii.gz");
  const msk::SegmentationMetrics m = msk::labelMetrics(res.labels, 1, truth, 1);
  state.counters["run_s"] = res.seconds;
  state.counters["steps"] = steps;
  state.counters["us_per_step_vertex"] = 1e6 * (res.secondsPerStage["evolution"]) / std::max(1, stepVertices);
  state.counters["dice"] = m.dice;
  state.counters["assd_mm"] = m.assd;
  state.SetLabel(msk::qualityName(opts.evolution.quality));
}
BENCHMARK(BM_FemurSegmentation)->DenseRange(0, 2)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
