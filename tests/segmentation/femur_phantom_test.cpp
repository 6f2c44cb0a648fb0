// The acceptance check for single objects: the femur of phantoms (the bundled seed and five others,
// oblique and anisotropic grids included) segmented from the mean template: ASSD ≤ 0.6 mm and Dice ≥ 0.95.
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/metrics.h"
#include "msk/phantom/phantom.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace {

struct Case {
  uint32_t seed;
  Eigen::Vector3d spacing, oblique;
};

/// A scene of the femur alone (label 1) from `templ`.
msk::Scene femurScene(const msk::TriangleMesh& templ) {
  msk::Scene scene;
  msk::SceneObject femur;
  femur.name = "femur";
  femur.label = 1;
  femur.kind = msk::ObjectKind::Bone;
  femur.templ = templ;
  scene.objects.push_back(femur);
  return scene;
}

void checkFemur(const std::string& what, const msk::ImageF& image, const msk::LabelMap& truthLabels,
                const msk::TriangleMesh& truthMesh, const msk::TriangleMesh& templ) {
  const msk::SegmentationResult res = msk::segmentScene(image, femurScene(templ), msk::SegmentOptions{});
  const msk::SegmentationMetrics vox = msk::labelMetrics(res.labels, 1, truthLabels, 1);
  const msk::SegmentationMetrics mesh = msk::meshMetrics(res.objects[0].mesh, truthMesh);
  const msk::SegmentationMetrics start = msk::meshMetrics(templ, truthMesh);
  std::printf("%-34s template ASSD %.2f mm -> labels: Dice %.4f ASSD %.3f mm HD95 %.2f mm | mesh: ASSD %.3f mm "
              "HD95 %.2f mm | %.2f s\n",
              what.c_str(), start.assd, vox.dice, vox.assd, vox.hd95, mesh.assd, mesh.hd95, res.seconds);
  EXPECT_GE(vox.dice, 0.95) << what;
  EXPECT_LE(vox.assd, 0.6) << what;
  EXPECT_LE(mesh.assd, 0.6) << what;
}

}  // namespace

TEST(FemurPhantom, BundledSampleFromTheMeanTemplate) {
  const std::string dir = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1/";
  const msk::Scene scene = msk::loadScene(dir + "scene.json");
  ASSERT_EQ(scene.objects[0].name, "femur");
  checkFemur("bundled seed 1 (1.2x1.2x3)", msk::readNifti<float>(dir + "image.nii.gz"),
             msk::readNifti<int32_t>(dir + "labels.nii.gz"), msk::readMesh(dir + "truth_femur.vtk"),
             scene.objects[0].templ);
}

/// The five phantoms besides the bundled one.
const Case kOtherSeeds[] = {{2, {1.2, 1.2, 3}, {0, 0, 0}},
                            {3, {1.2, 1.2, 3}, {10, -15, 20}},
                            {4, {1, 1.5, 2.5}, {0, 0, 0}},
                            {5, {0.9, 0.9, 4}, {-20, 10, 5}},
                            {6, {1.5, 1.5, 1.5}, {0, 0, 30}}};

/// The phantom of a case, and its description.
msk::Phantom phantomOf(const Case& c, std::string& what) {
  msk::PhantomOptions o;
  o.seed = c.seed;
  o.spacing = c.spacing;
  o.obliqueDegrees = c.oblique;
  char text[96];
  std::snprintf(text, sizeof text, "seed %u (%gx%gx%g, oblique %g,%g,%g)", c.seed, c.spacing[0], c.spacing[1],
                c.spacing[2], c.oblique[0], c.oblique[1], c.oblique[2]);
  what = text;
  return msk::makePhantom(o);
}

TEST(FemurPhantom, FiveOtherSeedsIncludingObliqueAndAnisotropicGrids) {
  for (const Case& c : kOtherSeeds) {
    std::string what;
    const msk::Phantom p = phantomOf(c, what);
    ASSERT_EQ(p.objects[0].name, "femur");
    checkFemur(what, p.image, p.labels, p.objects[0].truth, p.objects[0].templ);
  }
}

// Issue 5, convergence: accuracy rises from the fast preset to the accurate one on these six phantoms. Per phantom the
// differences between neighbouring presets are a few hundredths of a millimetre either way where the template starts
// close (README: where a level stops sets the prior weight a result carries), so the test asserts the mean order and
// that accurate beats fast on every phantom. Measured (mesh ASSD, mm, fast / balanced / accurate): mean 0.394 / 0.342 /
// 0.292; balanced behind fast on the bundled seed (0.282 / 0.305) and seed 3 (0.500 / 0.509), accurate ahead of both on
// every phantom (0.172–0.445).
TEST(FemurPhantom, PresetsGainAccuracyFromFastToAccurate) {
  const msk::Quality presets[] = {msk::Quality::Fast, msk::Quality::Balanced, msk::Quality::Accurate};
  double mean[3] = {0, 0, 0};
  int cases = 0;
  auto run = [&](const std::string& what, const msk::ImageF& image, const msk::TriangleMesh& truth,
                 const msk::TriangleMesh& templ) {
    const msk::Scene scene = femurScene(templ);
    double assd[3];
    for (int q = 0; q < 3; ++q) {
      msk::SegmentOptions o;
      o.evolution.quality = presets[q];
      assd[q] = msk::meshMetrics(msk::segmentScene(image, scene, o).objects[0].mesh, truth).assd;
      mean[q] += assd[q];
    }
    ++cases;
    std::printf("%-34s mesh ASSD fast %.3f  balanced %.3f  accurate %.3f mm\n", what.c_str(), assd[0], assd[1], assd[2]);
    EXPECT_LT(assd[2], assd[0]) << what << ": accurate no better than fast";
  };
  const std::string dir = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1/";
  run("bundled seed 1 (1.2x1.2x3)", msk::readNifti<float>(dir + "image.nii.gz"), msk::readMesh(dir + "truth_femur.vtk"),
      msk::loadScene(dir + "scene.json").objects[0].templ);
  for (const Case& c : kOtherSeeds) {
    std::string what;
    const msk::Phantom p = phantomOf(c, what);
    run(what, p.image, p.objects[0].truth, p.objects[0].templ);
  }
  for (double& m : mean) m /= cases;
  std::printf("mean mesh ASSD over %d phantoms: fast %.3f  balanced %.3f  accurate %.3f mm\n", cases, mean[0], mean[1],
              mean[2]);
  EXPECT_GT(mean[0], mean[1]);
  EXPECT_GT(mean[1], mean[2]);
}

// A template is never exactly in place: displaced by several mm and scaled by ±5 %, the femur still converges.
TEST(FemurPhantom, DisplacedAndScaledTemplate) {
  const std::string dir = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1/";
  const msk::Scene scene = msk::loadScene(dir + "scene.json");
  const msk::ImageF image = msk::readNifti<float>(dir + "image.nii.gz");
  const msk::LabelMap labels = msk::readNifti<int32_t>(dir + "labels.nii.gz");
  const msk::TriangleMesh truth = msk::readMesh(dir + "truth_femur.vtk");
  const msk::TriangleMesh& base = scene.objects[0].templ;
  const Eigen::Vector3d c = base.vertices.colwise().mean().transpose();
  for (auto [shift, scale] : {std::pair{Eigen::Vector3d(5, -3, 4), 1.05}, std::pair{Eigen::Vector3d(-3, 3, -4), 0.95}}) {
    msk::TriangleMesh t = base;
    for (int i = 0; i < t.vertexCount(); ++i)
      t.vertices.row(i) = (c + scale * (t.vertices.row(i).transpose() - c) + shift).transpose();
    char what[96];
    std::snprintf(what, sizeof what, "bundled, shifted %.1f mm, scale %.2f", shift.norm(), scale);
    checkFemur(what, image, labels, truth, t);
  }
}
