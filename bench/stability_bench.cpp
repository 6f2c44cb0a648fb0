// Figures of the stability checks at the extremes (the tests assert their bounds on the same scenarios,
// tests/support/*/msk/test/*_scenarios.h): momentum through whole position-based steps, the smoothing mode of the
// internal constraint left alone, and the segmenter on a ball in metres against millimetres.
// Run: build/bench/stability_bench [--benchmark_filter=MetreSpacing]
#include <benchmark/benchmark.h>

#include <cmath>

#include "msk/core/solver.h"
#include "msk/test/ball_scenarios.h"
#include "msk/test/solver_scenarios.h"

namespace {

// Two overlapping perturbed spheres, 20 position-based steps without damping, drag or targets, under their internal
// sets (argument 0) or also the collision sets of both directions (1): the largest per-step change of angular momentum
// relative to Σ m|x||v|, and the largest linear momentum relative to Σ m|v|.
// (ExtremeMomentum.AngularMomentumDriftPerStepWithinBudget asserts 5e-3 and 1e-9.)
void BM_AngularMomentumDrift(benchmark::State& state) {
  msk::test::MomentumDrift d;
  for (auto _ : state) d = msk::test::momentumDrift(state.range(0) != 0);
  if (!d.finite) state.SkipWithError("the run is not finite");
  state.SetLabel(state.range(0) ? "internal + collision sets" : "internal sets");
  state.counters["angular_per_step"] = d.angular;
  state.counters["linear"] = d.linear;
}
BENCHMARK(BM_AngularMomentumDrift)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The internal constraint's smoothing mode projected alone, 2000 sweeps, on a sphere of radius 10 mm at rest or
// perturbed by ±0.05 mm, at γ = 1 and 0.3 (arguments: γ × 10, perturbation × 100): the smallest and largest radius.
// (ExtremeStability.InternalSmoothingAloneStaysBounded asserts 9.5–10.5 mm.)
void BM_InternalSmoothingSweeps(benchmark::State& state) {
  const double gamma = state.range(0) / 10.0, amplitude = state.range(1) / 100.0;
  std::pair<double, double> r;
  for (auto _ : state) r = msk::test::internalSweepRadii(gamma, amplitude, 2000);
  state.counters["radius_min_mm"] = r.first;
  state.counters["radius_max_mm"] = r.second;
}
BENCHMARK(BM_InternalSmoothingSweeps)->ArgsProduct({{10, 3}, {0, 5}})->Unit(benchmark::kMillisecond);

// The same through the rows: 300 steps of every scheme (the argument, in allSchemes() order) at γ = 1 from the sphere
// perturbed by ±0.05 mm.
void BM_InternalSmoothingSteps(benchmark::State& state) {
  const msk::Scheme scheme = msk::allSchemes().at(static_cast<size_t>(state.range(0)));
  std::pair<double, double> r;
  for (auto _ : state) r = msk::test::smoothingSolverRadii(scheme, 1.0, 0.05, 300);
  state.SetLabel(msk::schemeName(scheme));
  state.counters["radius_min_mm"] = r.first;
  state.counters["radius_max_mm"] = r.second;
}
BENCHMARK(BM_InternalSmoothingSteps)->DenseRange(0, 5)->Unit(benchmark::kMillisecond);

// The segmenter's ball scene with every length in metres against millimetres, with one or two levels (the argument):
// the largest vertex difference in mm, and (two levels) the same with every length scaled by 2⁻¹⁰, exact in binary.
// (SegmenterExtremes.MetreSpacing* assert 1e-3 mm for one level; 0, and 0.01 mm in metres, for two.)
void BM_MetreSpacing(benchmark::State& state) {
  const int levels = static_cast<int>(state.range(0));
  double metres = 0, pow2 = 0;
  for (auto _ : state) {
    const msk::TriangleMesh mm = msk::test::ballInUnits(1.0, levels), m = msk::test::ballInUnits(1e-3, levels);
    metres = (mm.vertices - m.vertices).cwiseAbs().maxCoeff();
    if (levels > 1) pow2 = (mm.vertices - msk::test::ballInUnits(1.0 / 1024, levels).vertices).cwiseAbs().maxCoeff();
  }
  state.counters["metres_diff_mm"] = metres;
  if (levels > 1) state.counters["pow2_diff_mm"] = pow2;
}
BENCHMARK(BM_MetreSpacing)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
