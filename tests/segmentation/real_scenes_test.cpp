// Real multi-object scenes: every template is built from the contralateral label, mirrored across the sagittal plane
// through a midline landmark, then displaced by 3 mm and scaled by ±3 % (a template is never exactly in place); the
// profile force learns each object's profiles on the structure its template came from. Scores are taken on the full
// grid against the reference labels (TotalSegmentator's, not by hand). Skipped without ../shared/data. The scenarios
// (msk/test/real_scan_scenarios.h) are shared with bench/real_scans_bench.cpp, which reports their figures.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "msk/imaging/nifti_io.h"
#include "msk/test/files.h"
#include "msk/test/real_scan_scenarios.h"

namespace {
using msk::test::RealScene;
using msk::test::SceneScore;

/// Every object of a correct run passes the quality check (quality_check.h).
void expectQualityOk(const SceneScore& sc) {
  for (const msk::ObjectResult& o : sc.result.objects)
    EXPECT_EQ(o.quality.status, msk::QualityStatus::Ok)
        << o.name << ": " << (o.quality.reasons.empty() ? "" : o.quality.reasons[0]);
}
}  // namespace

// Each autochthon muscle Dice ≥ 0.90 and no overlap: met. Every object uses the profile force with its
// profiles learned on the contralateral structure its template was mirrored from (on this blurry MRI the steepest
// muscle–fat gradient lies about one voxel outside TotalSegmentator's boundary, so the gradient force grows the
// muscles: 0.896 / 0.873 at best; profiles learned on the template itself keep it where it starts). Measured: left
// 0.887 → 0.940, right 0.795 → 0.916, vertebrae 0.946 / 0.948, no overlap.
TEST(RealScenes, MrAutochthonMusclesWithTheVertebrae) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const SceneScore sc = msk::test::runMrScene(msk::test::mrScene(data));
  ASSERT_GE(sc.objects.size(), 3u);  // two muscles and at least one vertebra
  for (size_t i = 0; i < sc.objects.size(); ++i) {
    EXPECT_GE(sc.objects[i].after.dice, i < 2 ? 0.90 : 0.92) << sc.objects[i].name;
    EXPECT_GT(sc.objects[i].after.dice, sc.objects[i].before.dice) << sc.objects[i].name;
  }
  EXPECT_EQ(sc.overlapVoxels, 0u);
  expectQualityOk(sc);
}

// Each Dice ≥ 0.88 and no overlap. Every object uses the profile force learned on the contralateral
// structure (the crop holds both sides), the global prior ends at λ = 0.2, the finest search reaches ± 1 voxel on an
// image smoothed at σ = 1 voxel; the two bones then take the refinement pass (SegmentOptions::refinePass; it costs the
// muscles, whose edges on this CT are not the labelled boundary, so they stay fixed in it). Measured: femur 0.763 →
// 0.915 (0.896 without the pass), hip bone 0.847 → 0.948 (0.947), gluteus maximus 0.731 → 0.892, gluteus medius
// 0.770 → 0.859, no overlap. The gluteus medius is short of 0.88 (it reaches 0.849–0.866 from every start and option
// tried, 0.859 from the undisplaced mirror, whose own Dice is 0.792; the best rigid fit of the mirrored left label onto
// the right one scores 0.847, and a template started there ends at 0.867: the sides differ where the image shows no
// boundary, see docs/measurements.md and CtGlutealSidesBestRigidFit below); guard its level.
TEST(RealScenes, CtFemurHipAndGlutealMusclesOfOneSide) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  RealScene rs = msk::test::ctScene(data);
  const SceneScore sc = msk::test::runCtScene(rs);
  const double guard[] = {0.90, 0.93, 0.88, 0.85};
  for (size_t i = 0; i < sc.objects.size(); ++i) {
    EXPECT_GE(sc.objects[i].after.dice, guard[i]) << sc.objects[i].name;
    EXPECT_GT(sc.objects[i].after.dice, sc.objects[i].before.dice + 0.05) << sc.objects[i].name;
  }
  EXPECT_EQ(sc.overlapVoxels, 0u);
  expectQualityOk(sc);
}

// How far a mirrored contralateral label can match at best on this CT (docs/measurements.md): the best rigid fit of the
// left gluteus maximus and medius labels, mirrored, onto the right ones. Measured: maximus 0.827 → 0.858 (1.7°,
// centroid moved 2.5 mm), medius 0.801 → 0.847 (3.9°, 5.4 mm); the gluteus medius template started at its fitted pose
// ends at 0.867, so its 0.88 cannot come from placing the template better, only from the image, which shows no boundary
// toward the other gluteal muscles. The assertions check the fit (it does not lose Dice, stays a small motion) and the
// documented limit.
TEST(RealScenes, CtGlutealSidesBestRigidFit) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const msk::LabelMap labels = msk::readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  const double midX = msk::test::ctMidSagittalX(labels);
  const struct {
    const char* name;
    int from, to;
  } muscles[] = {{"gluteus maximus", 80, 81}, {"gluteus medius", 82, 83}};
  for (const auto& m : muscles) {
    const msk::test::RigidFitScore f = msk::test::rigidFitOfMirror(labels, m.from, m.to, midX);
    EXPECT_GE(f.fittedDice, f.mirrorDice - 0.005) << m.name;
    EXPECT_LT(f.rotationDeg, 10.0) << m.name;
    EXPECT_LT(f.centroidMoveMm, 15.0) << m.name;
    if (m.to == 83) {
      EXPECT_LT(f.fittedDice, 0.88) << "the sides now agree: the gluteus medius' 0.88 may be in reach";
      // The CT scene with no displacement and the gluteus medius template started at that fitted pose.
      RealScene rs = msk::test::ctScene(data, 0.0, f.pose);
      const SceneScore sc = msk::test::runCtScene(rs);
      EXPECT_GT(sc.objects[3].after.dice, sc.objects[3].before.dice);
      EXPECT_EQ(sc.overlapVoxels, 0u);
    }
  }
}

// What the CT image itself says about the gluteus medius' labelled boundary (docs/measurements.md): the same scene with
// every template built from the right side's OWN label (the shape the result should have), displaced by 3 mm and scaled
// by ±3 % as above. If the image carried that boundary, the muscle would end near its label from there. It does not:
// the run leaves it further from its label than its template started, with the profiles learned on the left side (as in
// the scene above) and with the gradient force and the edge level. So the 0.88 asked of the mirrored left
// template (best rigid fit 0.847, CtGlutealSidesBestRigidFit) would have to come from the image, which on this 3 mm CT
// moves even the right shape away. Measured: gluteus medius template alone 0.927 → 0.851 (profiles) and 0.910
// (gradient); gluteus maximus 0.880 → 0.898 and 0.929; femur 0.899 → 0.952 / 0.977, hip bone 0.858 → 0.943 / 0.949.
TEST(RealScenes, CtGluteusMediusFromItsOwnLabelLosesToTheImage) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  for (bool gradient : {false, true}) {
    SCOPED_TRACE(gradient ? "gradient force with the edge level" : "profiles learned on the left side");
    const SceneScore sc = msk::test::runCtSceneFromOwnLabels(data, gradient);
    const msk::test::ObjectScore& medius = sc.objects[3];
    EXPECT_GE(medius.before.dice, 0.90) << "the right shape, displaced and scaled, starts close";
    EXPECT_LT(medius.after.dice, medius.before.dice) << "the image now moves the right shape toward its label";
    EXPECT_EQ(sc.overlapVoxels, 0u);
    for (size_t i = 0; i < 2; ++i) EXPECT_GE(sc.objects[i].after.dice, 0.93) << sc.objects[i].name;  // the bones
  }
}
