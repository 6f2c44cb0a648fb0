// Accuracy on the phantoms, from the scenarios the segmentation tests assert on (tests/support/segmentation/msk/test/
// phantom_scenarios.h, axis_first_scenarios.h): the femur of six phantoms from the mean template, the presets on them,
// the bundled thigh scene with and without collision response and under other collision responses, the thigh scene on
// five more phantoms, and the axis-first stage. One run each (Iterations(1)); the figures are the counters, the time
// is the whole scenario's. Run: build/bench/phantom_bench [--benchmark_filter=FemurPhantom]
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "msk/test/axis_first_scenarios.h"
#include "msk/test/phantom_scenarios.h"

namespace {

/// The six femur phantoms: the bundled seed 1, then seeds 2–6 (built once).
const std::vector<msk::test::FemurCase>& femurCases() {
  static const std::vector<msk::test::FemurCase> cases = [] {
    std::vector<msk::test::FemurCase> c = {msk::test::bundledFemur()};
    for (const msk::test::PhantomCase& p : msk::test::otherPhantomCases()) c.push_back(msk::test::phantomFemur(p));
    return c;
  }();
  return cases;
}

/// Adds Dice and ASSD of every object of a thigh run as counters (`dice_<name>`, `assd_<name>_mm`).
void thighCounters(benchmark::State& state, const msk::test::ThighRun& r) {
  for (size_t i = 0; i < r.res.objects.size() && i < 4; ++i) {
    const std::string& name = r.res.objects[i].name;
    state.counters["dice_" + name] = r.dice[i];
    state.counters["assd_" + name + "_mm"] = r.assd[i];
  }
  state.counters["overlap_voxels"] = static_cast<double>(r.res.overlapVoxels);
  double deepest = 0;
  for (double d : r.res.pairPenetrationMm) deepest = std::max(deepest, d);
  state.counters["deepest_inside_mm"] = deepest;
  state.counters["run_s"] = r.res.seconds;
}

// The femur alone from the mean template, default settings, on phantom k (the argument: 1 the bundled seed, 2–6 the
// others): Dice, ASSD and HD95 of the labels, ASSD and HD95 of the mesh, the template's mesh ASSD.
// (FemurPhantom.BundledSampleFromTheMeanTemplate and FemurPhantom/FiveOtherSeeds.IncludingObliqueAndAnisotropicGrids
// assert Dice ≥ 0.95 and ASSD ≤ 0.6 mm.)
void BM_FemurPhantom(benchmark::State& state) {
  const msk::test::FemurCase& c = femurCases().at(static_cast<size_t>(state.range(0) - 1));
  msk::test::FemurScore s;
  for (auto _ : state) s = msk::test::segmentFemur(c);
  state.SetLabel(c.name);
  state.counters["dice"] = s.labels.dice;
  state.counters["assd_labels_mm"] = s.labels.assd;
  state.counters["hd95_labels_mm"] = s.labels.hd95;
  state.counters["assd_mesh_mm"] = s.mesh.assd;
  state.counters["hd95_mesh_mm"] = s.mesh.hd95;
  state.counters["template_assd_mm"] = s.start.assd;
  state.counters["run_s"] = s.seconds;
}
BENCHMARK(BM_FemurPhantom)->DenseRange(1, 6)->Unit(benchmark::kSecond)->Iterations(1);

// Each preset (the argument: 0 fast, 1 balanced, 2 accurate) on the six femur phantoms: mesh ASSD per phantom
// (assd_seed<k>_mm) and their mean. (FemurPhantom.PresetsGainAccuracyFromFastToAccurate asserts the mean order and
// accurate ahead of fast on each.)
void BM_FemurPresets(benchmark::State& state) {
  msk::SegmentOptions o;
  o.evolution.quality = static_cast<msk::Quality>(state.range(0));
  std::vector<double> assd;
  for (auto _ : state) {
    assd.clear();
    for (const msk::test::FemurCase& c : femurCases()) assd.push_back(msk::test::segmentFemur(c, o).mesh.assd);
  }
  double mean = 0;
  for (size_t k = 0; k < assd.size(); ++k) {
    state.counters["assd_seed" + std::to_string(k + 1) + "_mm"] = assd[k];
    mean += assd[k] / static_cast<double>(assd.size());
  }
  state.counters["mean_assd_mm"] = mean;
  state.SetLabel(msk::qualityName(o.evolution.quality));
}
BENCHMARK(BM_FemurPresets)->DenseRange(0, 2)->Unit(benchmark::kSecond)->Iterations(1);

// The bundled thigh scene (femur, quadriceps, hamstrings, adductors), default quality: without collision response
// (argument 0), with it (1), and with it but the muscles kept on their decimated templates, not unfolded (2): Dice
// and ASSD per object against the exact labels, voxels inside two objects, the deepest vertex inside a partner, the
// output separation's sweeps and each surface's crossing face pairs. (ThighScene.* assert zero overlap, penetration
// ≤ 0.1 mm, Dice ≥ 0.95 and no crossing with the remeshed templates.)
void BM_ThighScene(benchmark::State& state) {
  const msk::test::BundledThigh thigh = msk::test::loadBundledThigh();
  msk::SegmentOptions opts;
  opts.collision.enabled = state.range(0) > 0;
  opts.surface.remeshTemplates = opts.surface.unfoldSurfaces = state.range(0) < 2;
  msk::test::ThighRun r;
  for (auto _ : state) r = msk::test::segmentThigh(thigh, thigh.scene, opts);
  thighCounters(state, r);
  state.counters["separation_sweeps"] = r.res.separationSweeps;
  for (const msk::ObjectResult& o : r.res.objects)
    state.counters["crossing_pairs_" + o.name] = static_cast<double>(o.selfIntersections);
  state.SetLabel(state.range(0) == 0   ? "without collision response"
                 : state.range(0) == 1 ? "with collision response"
                                       : "with collision response, templates kept");
}
BENCHMARK(BM_ThighScene)->DenseRange(0, 2)->Unit(benchmark::kSecond)->Iterations(1);

// The bundled thigh scene with every pair in velocity mode (argument 0), and with every pair resolved globally (1).
// (CollisionResponseScene.ThighSceneUnderVelocityModeAndGlobalResolution asserts no overlap and the default's Dice.)
void BM_ThighSceneCollisionModes(benchmark::State& state) {
  const msk::test::BundledThigh thigh = msk::test::loadBundledThigh();
  const msk::test::ThighCollisionCase& c = msk::test::thighCollisionCases().at(static_cast<size_t>(state.range(0)));
  msk::Scene scene = thigh.scene;
  for (msk::CollisionPair& p : scene.collisions) p.mode = c.mode;
  msk::SegmentOptions opts;
  opts.collision.resolution = c.resolution;
  msk::test::ThighRun r;
  for (auto _ : state) r = msk::test::segmentThigh(thigh, scene, opts);
  thighCounters(state, r);
  state.SetLabel(c.name);
}
BENCHMARK(BM_ThighSceneCollisionModes)->DenseRange(0, 1)->Unit(benchmark::kSecond)->Iterations(1);

// The thigh scene on phantoms 2–6 (the argument), default settings: Dice and mesh ASSD per object, their mean ASSD,
// voxels inside two objects (and those handed over after the separation), the deepest vertex inside a partner, and the
// muscles' boundary error where the septum between two muscles is missing and elsewhere.
// (ThighSceneSeeds/FiveMoreSeeds.IncludingObliqueAndAnisotropicGrids asserts Dice ≥ 0.92, mean ASSD ≤ 0.8 mm, no
// overlap and penetration ≤ 0.1 mm.)
void BM_ThighSceneSeeds(benchmark::State& state) {
  const msk::test::PhantomCase& c = msk::test::otherPhantomCases().at(static_cast<size_t>(state.range(0) - 2));
  msk::test::ThighSceneScore sc;
  for (auto _ : state) sc = msk::test::segmentPhantomThigh(c);
  for (const msk::test::ThighObjectScore& o : sc.objects) {
    state.counters["dice_" + o.name] = o.dice;
    state.counters["assd_" + o.name + "_mm"] = o.meshAssd;
    state.counters["template_assd_" + o.name + "_mm"] = o.templateAssd;
  }
  state.counters["mean_assd_mm"] = sc.meanAssd;
  state.counters["overlap_voxels"] = static_cast<double>(sc.overlapVoxels);
  state.counters["handed_over_voxels"] = static_cast<double>(sc.overlapVoxelsRepaired);
  state.counters["deepest_inside_mm"] = sc.deepestMm;
  state.counters["septa_missing_mm"] = sc.septaMissingMm;
  state.counters["septa_elsewhere_mm"] = sc.septaOtherMm;
  state.counters["run_s"] = sc.seconds;
  state.SetLabel(c.name());
}
BENCHMARK(BM_ThighSceneSeeds)->DenseRange(2, 6)->Unit(benchmark::kSecond)->Iterations(1);

// A straight template moved toward a tube bent in the image (the argument: 0 straight and moved 6.7 mm, 1 bent 8 mm,
// 2 bent 12 mm and moved 6.7 mm): Dice and mesh ASSD of the template, and of the runs with no medial axis, the axis
// alone and the axis evolved first, with the stage's steps and seconds.
// (AxisFirst/BentTubeIsReached.FromADisplacedStraightTemplate asserts the stage's gain.)
void BM_AxisFirstBentTube(benchmark::State& state) {
  const msk::test::BentTubeCase& c = msk::test::bentTubeCases().at(static_cast<size_t>(state.range(0)));
  msk::test::BentTubeRuns r;
  for (auto _ : state) r = msk::test::runBentTube(c);
  const std::pair<const char*, const msk::SegmentationMetrics*> runs[] = {
      {"template", &r.start}, {"no_axis", &r.plain.m}, {"axis", &r.axis.m}, {"axis_first", &r.first.m}};
  for (const auto& [name, m] : runs) {
    state.counters[std::string(name) + "_dice"] = m->dice;
    state.counters[std::string(name) + "_assd_mm"] = m->assd;
  }
  if (!r.first.res.axisFirst.empty()) {
    state.counters["stage_steps"] = r.first.res.axisFirst[0].steps;
    state.counters["stage_s"] = r.first.res.axisFirst[0].seconds;
  }
  char label[64];
  std::snprintf(label, sizeof label, "bend %.0f mm, moved %.1f mm", c.bendMm, c.offsetMm.norm());
  state.SetLabel(label);
}
BENCHMARK(BM_AxisFirstBentTube)->DenseRange(0, 2)->Unit(benchmark::kSecond)->Iterations(1);

// A muscle of the bundled thigh alone, its template moved by (8, 4, 0) mm: Dice and ASSD of the template, after the
// stage alone, and of the full runs with no axis, the axis alone and the axis first (with the stage's steps).
// (AxisFirst.StageBringsDisplacedThighMusclesBack asserts the stage's gain.)
void BM_AxisFirstThighMuscle(benchmark::State& state, const char* name) {
  msk::test::DisplacedMuscleRuns r;
  for (auto _ : state) r = msk::test::runDisplacedThighMuscle(name);
  const std::pair<const char*, const msk::SegmentationMetrics*> runs[] = {{"template", &r.templ},
                                                                          {"stage_alone", &r.stage},
                                                                          {"no_axis", &r.plain},
                                                                          {"axis", &r.axis},
                                                                          {"axis_first", &r.first}};
  for (const auto& [run, m] : runs) {
    state.counters[std::string(run) + "_dice"] = m->dice;
    state.counters[std::string(run) + "_assd_mm"] = m->assd;
  }
  state.counters["stage_steps"] = r.stageSteps;
}
BENCHMARK_CAPTURE(BM_AxisFirstThighMuscle, hamstrings, "hamstrings")->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_AxisFirstThighMuscle, adductors, "adductors")->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
