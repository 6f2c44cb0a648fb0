// Real scan: the right femur of totalseg-ct segmented from a template built from the left femur's label, mirrored
// across the mid-sagittal plane through the sacrum (label 25; the femur labels give only the template). The profile
// force learns its profiles on the left femur (the template's source), where the template fits by construction. Skipped without ../shared/data.
#include <cstdio>
#include <tuple>

#include <gtest/gtest.h>

#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/segmenter.h"
#include "msk/segmentation/template_builder.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"
#include "msk/test/templates.h"

namespace {
/// Mid-sagittal plane: x (RAS mm) of the sacrum's centroid (label 25), a midline landmark; no femur label is used.
double midSagittalX(const msk::LabelMap& labels) { return msk::test::labelCentroid(labels, 25).x(); }

/// A bone of the right side from the left side's label, mirrored across x = midX, with the profile force learning
/// its profiles on the left structure ("profiles_from": {"mirror_x": midX}).
msk::SceneObject mirroredBone(const msk::LabelMap& labels, const char* name, int label, int from, double midX) {
  msk::SceneObject o;
  o.name = name;
  o.label = label;
  o.kind = msk::ObjectKind::Bone;
  o.templ = msk::test::mirroredTemplate(labels, from, midX);
  o.hasForce = true;
  o.force = o.model.imageForce = msk::TargetMode::Profile;
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  mirror(0, 3) = 2 * midX;
  o.profileSource = mirror;
  return o;
}

/// The run's options: the global prior ends at λ = 0.2, the finest search reaches ± 1 voxel (measured on the femur
/// alone: defaults 0.884, λ_end 0.2 0.892, both 0.896), and the refinement pass finishes the bone on the CT's own
/// edges (segmenter.h, SegmentOptions::refinePass).
msk::SegmentOptions femurOptions(bool refine = true) {
  msk::SegmentOptions opts;
  opts.shape.priorEnd = 0.2;
  opts.image.rangeFine = 1.0;
  opts.image.refinePass = refine;
  return opts;
}
}  // namespace

TEST(RealCtFemur, MirroredContralateralTemplate) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const msk::ImageF ct = msk::readNifti<float>(data + "/totalseg-ct/ct.nii.gz");
  const msk::LabelMap labels = msk::readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");

  const double midX = midSagittalX(labels);
  msk::Scene scene;
  scene.objects.push_back(mirroredBone(labels, "femur_right", 76, 75, midX));
  const msk::SegmentationResult res = msk::segmentScene(ct, scene, femurOptions());
  const msk::SegmentationResult unrefined = msk::segmentScene(ct, scene, femurOptions(false));

  msk::LabelMap start(ct.grid, 0);
  msk::rasterizeInto(start, scene.objects[0].templ, 76);
  const msk::SegmentationMetrics before = msk::labelMetrics(start, 76, labels, 76);
  const msk::SegmentationMetrics after = msk::labelMetrics(res.labels, 76, labels, 76);
  const msk::SegmentationMetrics without = msk::labelMetrics(unrefined.labels, 76, labels, 76);
  std::printf("mid-sagittal x = %.2f mm; mirrored template: Dice %.4f ASSD %.2f mm -> segmented: Dice %.4f ASSD %.2f "
              "mm HD95 %.2f mm (%.2f s); without the refinement pass: Dice %.4f ASSD %.2f mm\n",
              midX, before.dice, before.assd, after.dice, after.assd, after.hd95, res.seconds, without.dice,
              without.assd);
  // Issue 3: Dice ≥ 0.90. Measured 0.913 (ASSD 1.40 mm); 0.896 (1.71 mm) without the refinement pass. The profiles,
  // learned on the left femur, carry its label's boundary, which lies about one voxel out on the shaft (the mirrored
  // left label is one voxel layer wider in every shaft slice); the pass puts the surface on this side's own edge,
  // where the intensity crosses the bone's level (the muscle–fat edge just outside the shaft, as strong as the
  // blurred cortex's at 3 mm, does not count).
  EXPECT_GE(after.dice, 0.90);
  EXPECT_GT(after.dice, without.dice);
  EXPECT_GT(after.dice, before.dice + 0.1);
  EXPECT_LT(after.assd, before.assd);
}

// The same femur with the hip bone of its side as a second object (template: the other side's hip bone label,
// mirrored) and a collision pair between them: the contact keeps the femoral head out of the acetabulum.
TEST(RealCtFemur, WithTheHipBoneAsCollisionPartner) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const msk::ImageF ct = msk::readNifti<float>(data + "/totalseg-ct/ct.nii.gz");
  const msk::LabelMap labels = msk::readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  const double midX = midSagittalX(labels);
  msk::Scene scene;
  scene.objects.push_back(mirroredBone(labels, "femur_right", 76, 75, midX));
  scene.objects.push_back(mirroredBone(labels, "hip_right", 78, 77, midX));
  scene.collisions.push_back({0, 1});
  const msk::SegmentationResult res = msk::segmentScene(ct, scene, femurOptions());
  msk::LabelMap start(ct.grid, 0);
  msk::rasterizeInto(start, scene.objects[0].templ, 76);
  msk::rasterizeInto(start, scene.objects[1].templ, 78);
  for (int label : {76, 78}) {
    const msk::SegmentationMetrics before = msk::labelMetrics(start, label, labels, label);
    const msk::SegmentationMetrics after = msk::labelMetrics(res.labels, label, labels, label);
    std::printf("label %d: mirrored template Dice %.4f ASSD %.2f mm -> segmented with collisions: Dice %.4f ASSD %.2f mm\n",
                label, before.dice, before.assd, after.dice, after.assd);
  }
  std::printf("overlap voxels %zu, deepest penetration %.2f mm, %.1f s\n", res.overlapVoxels, res.pairPenetrationMm[0],
              res.seconds);
  const msk::SegmentationMetrics femur = msk::labelMetrics(res.labels, 76, labels, 76);
  // Issue 3's 0.90 with a partner: measured 0.913 (0.897 without the refinement pass); hip bone 0.950, no overlap.
  EXPECT_GE(femur.dice, 0.90);
  EXPECT_GT(msk::labelMetrics(res.labels, 78, labels, 78).dice, 0.93);
  EXPECT_EQ(res.overlapVoxels, 0u);
}
