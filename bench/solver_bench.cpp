// The solver's schemes on the sphere problem of the core tests (tests/support/core/msk/test/solver_scenarios.h): steps
// to the unique answer, XPBD's independence of the iteration count, the mass-relative XPBD stiffness, and the cost of
// each scheme's settings. Counters hold the figures; the tests assert the properties on the same scenarios.
// Run: build/bench/solver_bench [--benchmark_filter=SchemeConvergence]
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>
#include <vector>

#include "msk/core/solver.h"
#include "msk/test/solver_scenarios.h"

namespace {

using msk::Scheme;

/// Every scheme, in allSchemes() order, by index (the benchmark argument).
Scheme schemeAt(int64_t i) { return msk::allSchemes().at(static_cast<size_t>(i)); }

// Every scheme from the sphere of radius 10 mm (320 vertices) to the answer of the consistent problem (the sphere
// scaled by 1.2): steps until no vertex moves 1e-7 mm, and the largest distance to the answer.
// (SolverSchemes.EverySchemeConvergesToTheSameAnswer asserts convergence within 0.01 mm.)
void BM_SchemeConvergence(benchmark::State& state) {
  const Scheme scheme = schemeAt(state.range(0));
  const msk::test::SphereProblem s = msk::test::sphereProblem(2);
  msk::test::SphereRun r;
  for (auto _ : state)
    r = msk::test::runSphereProblem(msk::test::sphereProblemOptions(scheme), s, 3000, 1e-7, &s.expected);
  state.SetLabel(msk::schemeName(scheme));
  state.counters["steps"] = r.steps;
  state.counters["converged"] = r.converged;
  state.counters["max_error_mm"] = r.error;
}
BENCHMARK(BM_SchemeConvergence)->DenseRange(0, 5)->Unit(benchmark::kMillisecond);

// XPBD (stiffness 1) and plain Gauss–Seidel on the inconsistent problem (targets at 1.2× on one half against the shape
// memory), 100 steps at 5, 10, 20, 40 and 80 iterations: the largest vertex distance to the 80-iteration result, % of
// its displacement (dev_<n>it_pct). (SolverSchemes.XpbdWithinTwoPercentFrom5To80Iterations asserts XPBD's < 2 %.)
void BM_IterationIndependence(benchmark::State& state, Scheme scheme) {
  const std::vector<int> counts = {5, 10, 20, 40, 80};
  std::vector<double> dev;
  double moved = 0;
  for (auto _ : state) dev = msk::test::iterationDeviations(scheme, counts, moved);
  if (dev.size() != counts.size()) {
    state.SkipWithError("a result is not finite");
    return;
  }
  for (size_t i = 0; i < counts.size(); ++i)
    state.counters["dev_" + std::to_string(counts[i]) + "it_pct"] = 100 * dev[i];
  state.counters["moved_mm"] = moved;
}
BENCHMARK_CAPTURE(BM_IterationIndependence, xpbd, Scheme::Xpbd)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_IterationIndependence, gauss_seidel, Scheme::GaussSeidel)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// XPBD with mass-relative stiffness k = 1 against the implicit scheme at their steady states: the largest distance, %
// of the displacement. (SolverSchemes.MassRelativeXpbdSharesTheForceBasedEquilibrium asserts < 2 %.)
void BM_MassRelativeXpbd(benchmark::State& state) {
  msk::test::MassRelativeXpbd f;
  for (auto _ : state) f = msk::test::massRelativeXpbdAgainstImplicit();
  state.counters["deviation_pct"] = 100 * f.deviation;
  state.counters["moved_mm"] = f.movedMm;
  state.counters["mass_scale_diff_mm"] = f.heavierMm;
}
BENCHMARK(BM_MassRelativeXpbd)->Unit(benchmark::kMillisecond)->Iterations(1);

/// A setting of the trade-off: a scheme with its substeps × iterations and threads.
struct TradeOffSetting {
  const char* label;
  Scheme scheme;
  int substeps, iterations, threads;
};
const TradeOffSetting kTradeOff[] = {{"gauss-seidel 1x1", Scheme::GaussSeidel, 1, 1, 1},
                                     {"gauss-seidel 1x4", Scheme::GaussSeidel, 1, 4, 1},
                                     {"coloured-gs 1x1", Scheme::ColouredGaussSeidel, 1, 1, 1},
                                     {"coloured-gs 1x1 2thr", Scheme::ColouredGaussSeidel, 1, 1, 2},
                                     {"jacobi 1x4", Scheme::Jacobi, 1, 4, 1},
                                     {"xpbd 1x4", Scheme::Xpbd, 1, 4, 1},
                                     {"xpbd 2x2", Scheme::Xpbd, 2, 2, 1},
                                     {"explicit 4", Scheme::Explicit, 4, 1, 1},
                                     {"implicit 1", Scheme::Implicit, 1, 1, 1}};

// Cost and accuracy of each setting on the 5120-vertex sphere of the consistent problem: wall time to run until no
// vertex moves 1e-4 mm (at most 2000 steps), the steps, time per step and the largest distance to the answer.
void BM_SchemeTradeOff(benchmark::State& state) {
  const TradeOffSetting& st = kTradeOff[state.range(0)];
  const msk::test::SphereProblem s = msk::test::sphereProblem(4);
  msk::SolverOptions o = msk::test::sphereProblemOptions(st.scheme);
  o.substeps = st.substeps;
  o.iterations = st.iterations;
  o.threads = st.threads;
  msk::test::SphereRun r;
  double seconds = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    r = msk::test::runSphereProblem(o, s, 2000, 1e-4, &s.expected);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (!r.x.allFinite()) state.SkipWithError("the run is not finite");
  state.SetLabel(st.label);
  state.counters["steps"] = r.steps;
  state.counters["max_error_mm"] = r.error;
  state.counters["us_per_step"] = 1e6 * seconds / (static_cast<double>(state.iterations()) * r.steps);
}
BENCHMARK(BM_SchemeTradeOff)->DenseRange(0, 8)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
