// Volume models on anatomy, from the scenarios tests/segmentation/volume_model_test.cpp asserts on
// (tests/support/segmentation/msk/test/volume_model_scenarios.h): the bundled phantom's muscles and the left autochthon
// muscle of totalseg-mr made volumetric, their template the phantom's own or the true surface moved and scaled; what
// tetrahedralising the muscles' templates costs; and a volumetric muscle among collision partners. One run each
// (Iterations(1)); the figures are the counters. Run: build/bench/volume_model_bench [--benchmark_filter=MovedTruth]
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>

#include "msk/core/tet_split.h"
#include "msk/core/volume_simplex.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/tetrahedralize.h"
#include "msk/test/files.h"
#include "msk/test/phantom_scenarios.h"
#include "msk/test/tet_surface.h"
#include "msk/test/volume_model_scenarios.h"

namespace {

/// The figures of one volume-model run as counters, its volume decision as the label.
void volumeCounters(benchmark::State& state, const msk::test::VolumeRun& r) {
  state.counters["tets"] = r.tets;
  state.counters["template_mm3"] = r.templateMm3;
  state.counters["model_mm3"] = r.modelMm3;
  state.counters["truth_mm3"] = r.truthMm3;
  state.counters["change_pct"] = r.changePercent();
  state.counters["model_vs_truth_pct"] = r.errorPercent();
  state.counters["surface_vs_truth_pct"] = r.surfaceErrorPercent();
  state.counters["inverted"] = r.inverted;
  state.counters["inverted_at_surface"] = r.invertedAtSurface;
  state.counters["inverted_slivers_at_rest"] = r.invertedSlivers;
  state.counters["flattest_inverted_rest_deg"] = r.invertedRestDeg;
  state.counters["rest_min_dihedral_deg"] = r.minDihedralDeg;
  state.counters["rest_slivers"] = r.slivers;
  state.counters["boundary_off_surface_mm"] = r.boundaryOffSurfaceMm;
  state.counters["template_dice"] = r.templateDice;
  state.counters["dice"] = r.dice;
  state.counters["run_s"] = r.seconds;
  state.SetLabel(r.decision);
}

// A phantom muscle (hamstrings, quadriceps, adductors) as a volume model from the phantom's own template.
void BM_VolumeModelPhantomTemplate(benchmark::State& state, const char* muscle) {
  const msk::test::VolumeCase c = msk::test::phantomMuscleCase(muscle);
  msk::test::VolumeRun r;
  for (auto _ : state)
    r = msk::test::runVolumeModel(c.image, c.object, c.labels, c.object.label, msk::enclosedVolume(c.truth));
  volumeCounters(state, r);
}
BENCHMARK_CAPTURE(BM_VolumeModelPhantomTemplate, hamstrings, "hamstrings")->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_VolumeModelPhantomTemplate, quadriceps, "quadriceps")->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_VolumeModelPhantomTemplate, adductors, "adductors")->Unit(benchmark::kSecond)->Iterations(1);

// A phantom muscle as a volume model from its true surface moved by 3.5 mm and rotated (arguments: the angle in
// degrees, the scale in %): scale 100 asks for no change of volume, 92 for +30 %, 95 and 105 for ±15 %.
// (VolumeModel.KeepsItsVolumeUnlessTheImageDemandsOtherwise asserts the hamstrings at 4°, 100 and 92.)
void BM_VolumeModelMovedTruth(benchmark::State& state, const char* muscle) {
  const msk::test::VolumeCase c = msk::test::phantomMuscleCase(muscle);
  msk::test::VolumeRun r;
  for (auto _ : state) r = msk::test::runMovedTruth(c, static_cast<double>(state.range(0)), state.range(1) / 100.0);
  volumeCounters(state, r);
}
BENCHMARK_CAPTURE(BM_VolumeModelMovedTruth, hamstrings, "hamstrings")
    ->Args({4, 100})
    ->Args({4, 92})
    ->Args({4, 95})
    ->Args({4, 105})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_VolumeModelMovedTruth, quadriceps, "quadriceps")
    ->Args({4, 100})
    ->Args({4, 95})
    ->Args({4, 105})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_VolumeModelMovedTruth, adductors, "adductors")
    ->Args({4, 100})
    ->Args({4, 95})
    ->Args({4, 105})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

// The left autochthon muscle of totalseg-mr (profile force) from its own label moved and rotated (arguments: the angle
// in degrees, the scale in %). Skipped without ../shared/data.
// (VolumeModel.KeepsItsVolumeUnlessTheImageDemandsOtherwise asserts 4°, 100 and 92.)
void BM_VolumeModelRealAutochthon(benchmark::State& state) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) {
    state.SkipWithError("../shared/data absent");
    return;
  }
  const msk::test::VolumeCase c = msk::test::realAutochthonCase(data);
  msk::test::VolumeRun r;
  for (auto _ : state) r = msk::test::runMovedTruth(c, static_cast<double>(state.range(0)), state.range(1) / 100.0);
  volumeCounters(state, r);
}
BENCHMARK(BM_VolumeModelRealAutochthon)
    ->Args({4, 100})
    ->Args({4, 92})
    ->Args({3, 100})
    ->Args({3, 95})
    ->Args({3, 105})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

// What the mesh optimisers cost: a phantom muscle's template tetrahedralised at the segmenter's sizes
// (volumeModelTetOptions(): facets of its mean edge, cells 1.5 times that) plain (argument 0), with ODT, perturbation
// and exudation (1), and also with interior nodes, bridges split (2) or every boundary-only tet split (3): tets, the
// smallest dihedral angle, tets under 5° and tets with all four nodes on the surface; the time is the
// tetrahedralisation's.
void BM_Tetrahedralisation(benchmark::State& state, const char* muscle) {
  const msk::TriangleMesh t = msk::readMesh(msk::test::bundledSample() + "template_" + muscle + ".vtk");
  const int variant = static_cast<int>(state.range(0));
  msk::TetOptions to = msk::volumeModelTetOptions(t);
  to.odt = to.perturb = to.exude = variant > 0;
  to.interiorNodes = variant >= 2;
  to.interiorSplit = variant == 2 ? msk::BoundarySplit::Bridges : msk::BoundarySplit::Tets;
  msk::TetMesh m;
  for (auto _ : state) m = msk::tetrahedralize(t, to);
  const std::string problem = msk::tetMeshProblem(m);
  if (!problem.empty()) state.SkipWithError(problem.c_str());
  const Eigen::VectorXd angle = msk::tetMinDihedralAngles(m);
  state.counters["tets"] = m.tetCount();
  state.counters["min_dihedral_deg"] = angle.minCoeff();
  state.counters["under_5deg"] = static_cast<double>((angle.array() < 5.0).count());
  state.counters["boundary_only_tets"] = msk::boundaryOnlyTetCount(m);
  state.SetLabel(variant == 0   ? "plain"
                 : variant == 1 ? "optimised"
                 : variant == 2 ? "optimised + bridges split"
                                : "optimised + tets split");
}
BENCHMARK_CAPTURE(BM_Tetrahedralisation, hamstrings, "hamstrings")
    ->DenseRange(0, 3)
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_Tetrahedralisation, quadriceps, "quadriceps")
    ->DenseRange(0, 3)
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_Tetrahedralisation, adductors, "adductors")
    ->DenseRange(0, 3)
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

// The bundled thigh scene, fast quality, the quadriceps volumetric among its collision partners: how many of the
// quadriceps' surface vertices have no tet boundary node on them after the separation and untangling, and how far the
// nearest one is at most (the run of SegmentCli.VolumetricMuscleAmongPartnersFollowsItsSeparatedSurface, in process).
void BM_VolumetricQuadricepsAmongPartners(benchmark::State& state) {
  const msk::test::BundledThigh thigh = msk::test::loadBundledThigh();
  msk::Scene scene = thigh.scene;
  for (msk::SceneObject& o : scene.objects)
    if (o.name == "quadriceps") o.model.volumetric = true;
  msk::SegmentOptions opts;
  opts.evolution.quality = msk::Quality::Fast;
  msk::SegmentationResult res;
  for (auto _ : state) res = msk::segmentScene(thigh.image, scene, opts);
  for (const msk::ObjectResult& o : res.objects) {
    if (o.name != "quadriceps") continue;
    const msk::test::TetSurfaceOffsets off = msk::test::tetSurfaceOffsets(o.volumeMesh, o.mesh);
    state.counters["tets"] = o.volumeMesh.tetCount();
    state.counters["inverted"] = o.invertedTets;
    state.counters["surface_vertices"] = off.surfaceVertices;
    state.counters["off_surface"] = off.offSurface;
    state.counters["largest_off_mm"] = off.largestMm;
    state.counters["mean_edge_mm"] = off.meanEdgeMm;
  }
}
BENCHMARK(BM_VolumetricQuadricepsAmongPartners)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
