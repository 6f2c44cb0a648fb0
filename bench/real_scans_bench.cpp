// Real scans (../shared/data: totalseg-ct, totalseg-mr), from the scenarios the segmentation tests assert on
// (tests/support/segmentation/msk/test/real_scan_scenarios.h): the MR autochthon muscles with the vertebrae, the CT
// femur, hip bone and gluteal muscles of one side, how far the mirrored gluteal labels can match at best, the CT scene
// from the right side's own labels, the CT femur alone and with its hip bone, and building a template from a CT label.
// Every template comes from the other side's label, mirrored. One run each (Iterations(1)); the figures are the
// counters: per object Dice / ASSD / HD95 of the template alone (before_*) and of the result. Each benchmark reports
// an error without the shared data. Run: build/bench/real_scans_bench [--benchmark_filter=RealCtScene]
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/template_builder.h"
#include "msk/test/files.h"
#include "msk/test/real_scan_scenarios.h"

namespace {

/// The shared data folder, or an error on `state` (empty string) without it.
std::string dataOrSkip(benchmark::State& state) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) state.SkipWithError("../shared/data absent");
  return data;
}

/// Template-alone and result scores of every object, and the run's overlap, penetration and time, as counters.
void sceneCounters(benchmark::State& state, const msk::test::SceneScore& sc) {
  for (const msk::test::ObjectScore& o : sc.objects) {
    state.counters[o.name + "_before_dice"] = o.before.dice;
    state.counters[o.name + "_before_assd_mm"] = o.before.assd;
    state.counters[o.name + "_dice"] = o.after.dice;
    state.counters[o.name + "_assd_mm"] = o.after.assd;
    state.counters[o.name + "_hd95_mm"] = o.after.hd95;
  }
  state.counters["overlap_voxels"] = static_cast<double>(sc.overlapVoxels);
  state.counters["deepest_inside_mm"] = sc.maxPenetrationMm;
  state.counters["run_s"] = sc.seconds;
}

// totalseg-mr: the left and right autochthon muscles with the vertebrae as bones, templates displaced by 3 mm and
// scaled by ±3 %. (RealScenes.MrAutochthonMusclesWithTheVertebrae asserts muscles ≥ 0.90, vertebrae ≥ 0.92, no
// overlap.)
void BM_RealMrScene(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  const msk::test::RealScene rs = msk::test::mrScene(data);
  msk::test::SceneScore sc;
  for (auto _ : state) sc = msk::test::runMrScene(rs);
  sceneCounters(state, sc);
}
BENCHMARK(BM_RealMrScene)->Unit(benchmark::kSecond)->Iterations(1);

// totalseg-ct, right side: femur, hip bone, gluteus maximus and medius, templates displaced and scaled; for the two
// muscles, the mean signed and absolute error of the surface against its label (mm, + = outside) by what lies 6 mm
// outside each vertex (fat, bone, partner muscles, other soft tissue).
// (RealScenes.CtFemurHipAndGlutealMusclesOfOneSide asserts 0.90 / 0.93 / 0.88 / 0.85 and no overlap.)
void BM_RealCtScene(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  msk::test::RealScene rs = msk::test::ctScene(data);
  msk::test::SceneScore sc;
  for (auto _ : state) sc = msk::test::runCtScene(rs);
  sceneCounters(state, sc);
  const char* classes[] = {"fat", "bone", "partners", "other"};
  for (size_t i = 2; i < 4 && i < sc.objects.size(); ++i) {
    const std::vector<msk::test::BoundaryClassError> errors =
        msk::test::errorByOutside(sc.result.objects[i].mesh, rs.reference, sc.objects[i].label, rs.image,
                                  i == 2 ? std::vector<int>{83, 85} : std::vector<int>{81, 85}, {76, 78});
    for (size_t c = 0; c < errors.size(); ++c) {
      const std::string key = sc.objects[i].name + "_" + classes[c];
      state.counters[key + "_vertices"] = errors[c].vertices;
      state.counters[key + "_signed_mm"] = errors[c].signedMm;
      state.counters[key + "_abs_mm"] = errors[c].absMm;
    }
  }
}
BENCHMARK(BM_RealCtScene)->Unit(benchmark::kSecond)->Iterations(1);

// The best rigid fit of a left gluteal label (argument 0: maximus 80 → 81, 1: medius 82 → 83), mirrored, onto the
// right one: Dice as is and fitted, the fit's rotation and centroid move; for the medius also the CT scene not
// displaced with its template started at the fitted pose. (RealScenes.CtGlutealSidesBestRigidFit asserts the fit and
// that the medius stays short of 0.88.)
void BM_CtGlutealRigidFit(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  const bool medius = state.range(0) == 1;
  const msk::LabelMap labels = msk::readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  const double midX = msk::test::ctMidSagittalX(labels);
  msk::test::RigidFitScore f;
  msk::test::SceneScore sc;
  for (auto _ : state) {
    f = msk::test::rigidFitOfMirror(labels, medius ? 82 : 80, medius ? 83 : 81, midX);
    if (medius) {
      msk::test::RealScene rs = msk::test::ctScene(data, 0.0, f.pose);
      sc = msk::test::runCtScene(rs);
    }
  }
  state.counters["mirror_dice"] = f.mirrorDice;
  state.counters["fitted_dice"] = f.fittedDice;
  state.counters["rotation_deg"] = f.rotationDeg;
  state.counters["centroid_move_mm"] = f.centroidMoveMm;
  if (medius) sceneCounters(state, sc);
  state.SetLabel(medius ? "gluteus medius" : "gluteus maximus");
}
BENCHMARK(BM_CtGlutealRigidFit)->Arg(0)->Arg(1)->Unit(benchmark::kSecond)->Iterations(1);

// The CT scene with every template from the right side's own label, displaced and scaled: profiles learned on the left
// side (argument 0), or the gradient force with the edge level (1).
// (RealScenes.CtGluteusMediusFromItsOwnLabelLosesToTheImage asserts the medius ends below its start.)
void BM_CtSceneFromOwnLabels(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  msk::test::SceneScore sc;
  for (auto _ : state) sc = msk::test::runCtSceneFromOwnLabels(data, state.range(0) == 1);
  sceneCounters(state, sc);
  state.SetLabel(state.range(0) == 1 ? "gradient force, edge level" : "profiles learned on the left side");
}
BENCHMARK(BM_CtSceneFromOwnLabels)->Arg(0)->Arg(1)->Unit(benchmark::kSecond)->Iterations(1);

// The right CT femur alone from the mirrored left label (not displaced), with and without the refinement pass.
// (RealCtFemur.MirroredContralateralTemplate asserts Dice ≥ 0.90 and the pass's gain.)
void BM_RealCtFemur(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  msk::test::CtFemurRuns r;
  for (auto _ : state) r = msk::test::runCtFemur(data);
  state.counters["mid_sagittal_x_mm"] = r.midX;
  state.counters["before_dice"] = r.before.dice;
  state.counters["before_assd_mm"] = r.before.assd;
  state.counters["dice"] = r.after.dice;
  state.counters["assd_mm"] = r.after.assd;
  state.counters["hd95_mm"] = r.after.hd95;
  state.counters["without_pass_dice"] = r.withoutPass.dice;
  state.counters["without_pass_assd_mm"] = r.withoutPass.assd;
  state.counters["run_s"] = r.seconds;
}
BENCHMARK(BM_RealCtFemur)->Unit(benchmark::kSecond)->Iterations(1);

// The right CT femur with the right hip bone as its collision partner. (RealCtFemur.WithTheHipBoneAsCollisionPartner
// asserts femur ≥ 0.90, hip bone > 0.93, no overlap.)
void BM_RealCtFemurWithHip(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  msk::test::CtFemurWithHip r;
  for (auto _ : state) r = msk::test::runCtFemurWithHip(data);
  state.counters["femur_before_dice"] = r.femurBefore.dice;
  state.counters["femur_dice"] = r.femur.dice;
  state.counters["femur_assd_mm"] = r.femur.assd;
  state.counters["hip_before_dice"] = r.hipBefore.dice;
  state.counters["hip_dice"] = r.hip.dice;
  state.counters["hip_assd_mm"] = r.hip.assd;
  state.counters["overlap_voxels"] = static_cast<double>(r.overlapVoxels);
  state.counters["deepest_inside_mm"] = r.penetrationMm;
  state.counters["run_s"] = r.seconds;
}
BENCHMARK(BM_RealCtFemurWithHip)->Unit(benchmark::kSecond)->Iterations(1);

// A smooth template from the left CT femur label (75): vertices, its volume against the label's voxels, the
// volume-preserving offset; the time is templateFromLabels'. (TemplateBuilder.RealCtFemur checks the template.)
void BM_TemplateFromCtFemurLabel(benchmark::State& state) {
  const std::string data = dataOrSkip(state);
  if (data.empty()) return;
  const msk::LabelMap labels = msk::readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  msk::TemplateReport rep;
  msk::TriangleMesh m;
  for (auto _ : state) m = msk::templateFromLabels(labels, 75, {}, &rep);
  state.counters["voxels"] = static_cast<double>(rep.voxels);
  state.counters["vertices"] = m.vertexCount();
  state.counters["volume_vs_voxels_pct"] = 100 * (msk::enclosedVolume(m) / rep.maskVolumeMm3 - 1);
  state.counters["offset_mm"] = rep.offsetMm;
}
BENCHMARK(BM_TemplateFromCtFemurLabel)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
