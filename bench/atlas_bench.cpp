// The atlas route from the scenarios the segmentation tests assert on (tests/support/segmentation/msk/test/
// atlas_scenarios.h): an atlas built from one subject, placed by registration in another and segmented. Phantom: atlas
// from seed 1, subject seed 2 posed (15°, 35 mm, +8 %) and seed 3 (−12°, 30 mm, −8 %). Real scans (../shared/data):
// the atlas from the scan mirrored (one side standing for the other), the subject the scan moved by 15° and 40 mm.
// One run each (Iterations(1)); the figures are the counters: per object Dice / ASSD of the placed template alone
// (placed_*) and of the result, the run's overlap and penetration, and the seconds of each part.
// Run: build/bench/atlas_bench [--benchmark_filter=Ct]
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "msk/test/atlas_scenarios.h"
#include "msk/test/files.h"

namespace {

void runCase(benchmark::State& state, const msk::test::AtlasCase& c) {
  if (c.name.empty()) {
    state.SkipWithError("../shared/data absent");
    return;
  }
  msk::test::ScratchDir dir;
  // MSK_ATLAS_KEEP=DIR keeps the atlas and the subject's image and labels in DIR (to look at or rerun by hand).
  const char* keep = std::getenv("MSK_ATLAS_KEEP");
  const std::string scratch = keep ? std::string(keep) : dir.path();
  std::filesystem::create_directories(scratch);
  msk::test::AtlasRun run;
  for (auto _ : state) run = msk::test::runAtlasCase(c, scratch);
  for (const msk::test::AtlasObjectScore& o : run.objects) {
    state.counters[o.name + "_placed_dice"] = o.placed.dice;
    state.counters[o.name + "_dice"] = o.result.dice;
    state.counters[o.name + "_assd_mm"] = o.result.assd;
  }
  double deepest = 0;
  for (double p : run.result.pairPenetrationMm) deepest = std::max(deepest, p);
  state.counters["mean_assd_mm"] = run.meanAssd;
  state.counters["overlap_voxels"] = static_cast<double>(run.result.overlapVoxels);
  state.counters["deepest_inside_mm"] = deepest;
  state.counters["atlas_s"] = run.buildSeconds;
  state.counters["placement_s"] = run.placementSeconds;
  state.counters["segment_s"] = run.segmentSeconds;
  int kept = 0;
  double refused = 0;
  for (const msk::ObjectPlacement& o : run.placement.objects) {
    kept += o.registered ? 1 : 0;
    if (!o.registered) refused = std::max(refused, o.moveDegrees);
  }
  state.counters["objects_placed_on_their_own"] = kept;
  state.counters["largest_refused_move_deg"] = refused;
}

msk::PhantomPose pose(double ax, double ay, double az, double tx, double ty, double tz, double scale) {
  msk::PhantomPose p;
  p.rotationDegrees = Eigen::Vector3d(ax, ay, az);
  p.translationMm = Eigen::Vector3d(tx, ty, tz);
  p.scale = scale;
  return p;
}

void BM_AtlasPhantomSeed2Posed(benchmark::State& state) {
  runCase(state, msk::test::phantomAtlasCase(1, 2, pose(10, -6, 9, 20, -25, 15, 1.08)));
}
BENCHMARK(BM_AtlasPhantomSeed2Posed)->Unit(benchmark::kSecond)->Iterations(1);

void BM_AtlasPhantomSeed3Posed(benchmark::State& state) {
  runCase(state, msk::test::phantomAtlasCase(1, 3, pose(-8, 7, -6, -18, 12, -20, 0.92)));
}
BENCHMARK(BM_AtlasPhantomSeed3Posed)->Unit(benchmark::kSecond)->Iterations(1);

void BM_AtlasCtMirroredOntoMovedCt(benchmark::State& state) {
  const std::string data = msk::test::sharedData();
  runCase(state, data.empty() ? msk::test::AtlasCase{} : msk::test::ctAtlasCase(data, 15, 40));
}
BENCHMARK(BM_AtlasCtMirroredOntoMovedCt)->Unit(benchmark::kSecond)->Iterations(1);

void BM_AtlasMrMirroredOntoMovedMr(benchmark::State& state) {
  const std::string data = msk::test::sharedData();
  runCase(state, data.empty() ? msk::test::AtlasCase{} : msk::test::mrAtlasCase(data, 15, 40));
}
BENCHMARK(BM_AtlasMrMirroredOntoMovedMr)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
BENCHMARK_MAIN();
