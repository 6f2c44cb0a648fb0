// Volume models on anatomy (issue 4: "volume preserved within 2 % under the image forces unless the image demands
// otherwise"). The phantom thigh's muscles (bundled seed) as 3-simplex volume models, their template the true surface
// (a) moved rigidly, so the image asks for no change of volume, and (b) also scaled, so the image does ask for one:
// the object in the image keeps the volume of the true surface, and the model must reach it rather than keep the
// template's. "The image demands otherwise" is therefore decided by the ground truth: whether the true volume differs
// from the template's. Also, when the shared data are there, the left autochthon muscle of totalseg-mr from its own
// label, moved and scaled the same way.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>

#include "msk/core/tet_split.h"
#include "msk/core/volume_simplex.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"
#include "msk/segmentation/template_builder.h"
#include "msk/segmentation/tetrahedralize.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"

namespace {

using Vec3 = Eigen::Vector3d;

/// `mesh` rotated by `angleDeg` about `axis` through its centroid, scaled by `scale` about it, then moved by `offset`.
msk::TriangleMesh movedScaled(const msk::TriangleMesh& mesh, double angleDeg, const Vec3& axis, double scale,
                              const Vec3& offset) {
  const Vec3 c = mesh.vertices.colwise().mean().transpose();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(angleDeg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  msk::TriangleMesh out = mesh;
  for (int v = 0; v < mesh.vertexCount(); ++v)
    out.vertices.row(v) = (c + offset + scale * r * (mesh.vertices.row(v).transpose() - c)).transpose();
  return out;
}

/// The 4×4 map of movedScaled().
Eigen::Matrix4d movedScaledMatrix(const msk::TriangleMesh& mesh, double angleDeg, const Vec3& axis, double scale,
                                  const Vec3& offset) {
  const Vec3 c = mesh.vertices.colwise().mean().transpose();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * Eigen::AngleAxisd(angleDeg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  m.topRightCorner<3, 1>() = c + offset - m.topLeftCorner<3, 3>() * c;
  return m;
}

/// What one volume-model run measured.
struct VolumeRun {
  int tets = 0, inverted = 0, invertedAtSurface = 0;
  double boundaryOffSurfaceMm = 0;  ///< the furthest a .vtu boundary node lies from its surface vertex
  double minDihedralDeg = 0;  ///< of the tetrahedralised template
  int slivers = 0;            ///< template tets with a dihedral angle under 5°
  int invertedSlivers = 0;    ///< inverted tets that were slivers at rest
  double invertedRestDeg = 0; ///< the largest rest min-dihedral angle of an inverted tet
  double templateMm3 = 0, modelMm3 = 0, truthMm3 = 0, surfaceMm3 = 0;
  std::string decision;       ///< the volume constraint's decision (ObjectResult::volumeDecision)
  double dice = 0, templateDice = 0, seconds = 0;
  /// Volume change of the model against its template, %.
  double changePercent() const { return 100.0 * (modelMm3 / templateMm3 - 1.0); }
  /// The model's volume against the true object's, %.
  double errorPercent() const { return 100.0 * (modelMm3 / truthMm3 - 1.0); }
};

/// Segments `object` (made volumetric) alone in `image` and measures the volume model against `truth` (label `label`
/// of `labels`, whose object has the volume `truthMm3`).
VolumeRun runVolumeModel(const msk::ImageF& image, msk::SceneObject object, const msk::LabelMap& labels, int label,
                         double truthMm3, const msk::SegmentOptions& opts = {}) {
  object.model.volumetric = true;
  msk::Scene scene;
  scene.objects.push_back(object);
  VolumeRun r;
  const auto t0 = std::chrono::steady_clock::now();
  const msk::SegmentationResult res = msk::segmentScene(image, scene, opts);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const msk::ObjectResult& o = res.objects.at(0);
  r.tets = o.volumeMesh.tetCount();
  r.inverted = o.invertedTets;
  const Eigen::VectorXd vols = msk::tetVolumes(o.volumeMesh);
  Eigen::VectorXi owner;
  msk::tetBoundaryFaces(o.volumeMesh, &owner);
  std::vector<char> atSurface(static_cast<size_t>(r.tets), 0);
  for (int f = 0; f < owner.size(); ++f) atSurface[static_cast<size_t>(owner[f])] = 1;
  for (int t = 0; t < r.tets; ++t) r.invertedAtSurface += vols[t] <= 0 && atSurface[static_cast<size_t>(t)] ? 1 : 0;
  // The tet boundary is the surface's triangulation (same vertex order): how far its nodes are from the surface's.
  Eigen::VectorXi nodeOf;
  const msk::TriangleMesh tb = msk::tetBoundary(o.volumeMesh, &nodeOf);
  if (tb.vertexCount() == o.mesh.vertexCount())
    r.boundaryOffSurfaceMm = (tb.vertices - o.mesh.vertices).rowwise().norm().maxCoeff();
  else
    r.boundaryOffSurfaceMm = -1;
  // The template's tets as the segmenter makes them (same options, same canonical order): their quality, and how
  // flat the tets that inverted were at rest.
  msk::TetOptions to;
  const double edge = msk::meanEdgeLength(object.templ);
  to.facetSizeMm = edge;
  to.cellSizeMm = 1.5 * edge;
  to.facetDistanceMm = 0.1 * edge;
  to.odt = to.perturb = to.exude = true;
  to.interiorNodes = true;
  const msk::TetMesh rest = msk::tetrahedralize(object.templ, to);
  if (rest.tetCount() == r.tets) {  // (exudation may break a tie differently: then no rest figures)
    const Eigen::VectorXd angle = msk::tetMinDihedralAngles(rest);
    r.minDihedralDeg = angle.minCoeff();
    r.slivers = static_cast<int>((angle.array() < 5.0).count());
    for (int t = 0; t < r.tets; ++t) {
      if (vols[t] > 0) continue;
      r.invertedSlivers += angle[t] < 5.0 ? 1 : 0;
      r.invertedRestDeg = std::max(r.invertedRestDeg, angle[t]);
    }
  }
  r.templateMm3 = o.volumeModelTemplateMm3;
  r.decision = o.volumeDecision;
  r.modelMm3 = o.volumeModelMm3;
  r.surfaceMm3 = o.volumeMm3;
  r.truthMm3 = truthMm3;
  r.dice = msk::labelMetrics(msk::rasterize(o.mesh, labels.grid), 1, labels, label).dice;
  r.templateDice = msk::labelMetrics(msk::rasterize(object.templ, labels.grid), 1, labels, label).dice;
  return r;
}

void printRun(const char* name, const char* what, const VolumeRun& r) {
  std::printf("[          ] %-11s %-26s %6d tets | template %8.0f -> model %8.0f mm3 (%+6.2f %%), truth %8.0f "
              "(model %+6.2f %%, surface %+6.2f %%) | inverted %d (%d at the surface, %d slivers at rest, flattest rest angle of an "
              "inverted tet %.1f deg) | rest: min dihedral %.2f deg, %d slivers < 5 deg | .vtu boundary off the surface "
              "%.3f mm at most | Dice %.3f -> %.3f | %.1f s\n",
              name, what, r.tets, r.templateMm3, r.modelMm3, r.changePercent(), r.truthMm3, r.errorPercent(),
              100.0 * (r.surfaceMm3 / r.truthMm3 - 1.0), r.inverted, r.invertedAtSurface, r.invertedSlivers,
              r.invertedRestDeg, r.minDihedralDeg, r.slivers, r.boundaryOffSurfaceMm, r.templateDice, r.dice, r.seconds);
}

}  // namespace

// Measurement of the phantom thigh muscles as volume models (printed; run with --gtest_also_run_disabled_tests): the
// phantom's own template, and the true surface moved rigidly (3.5 mm, 4°) and also scaled by 0.95 and 1.05.
TEST(VolumeModel, DISABLED_PhantomThighMusclesMeasured) {
  const std::string dir = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1";
  const msk::ImageF img = msk::readNifti<float>(dir + "/image.nii.gz");
  const msk::Scene scene = msk::loadScene(dir + "/scene.json");
  const msk::LabelMap truth = msk::readNifti<int32_t>(dir + "/labels.nii.gz");
  for (const char* name : {"hamstrings", "quadriceps", "adductors"}) {
    const msk::SceneObject* found = nullptr;
    for (const msk::SceneObject& o : scene.objects)
      if (o.name == name) found = &o;
    ASSERT_NE(found, nullptr);
    const msk::TriangleMesh surface = msk::readMesh(dir + "/truth_" + std::string(name) + ".vtk");
    const double truthMm3 = msk::enclosedVolume(surface);
    msk::SceneObject o = *found;
    const VolumeRun asGiven = runVolumeModel(img, o, truth, o.label, truthMm3);
    printRun(name, "phantom template", asGiven);
    for (double scale : {1.0, 0.95, 1.05}) {
      o.templ = movedScaled(surface, 4.0, Vec3(1, 2, 3), scale, Vec3(2.0, -2.5, 1.5));
      const VolumeRun r = runVolumeModel(img, o, truth, o.label, truthMm3);
      char what[64];
      std::snprintf(what, sizeof what, "truth moved, scaled %.2f", scale);
      printRun(name, what, r);
    }
  }
}

// Measurement on a real muscle (printed; run with --gtest_also_run_disabled_tests; skipped without ../shared/data): the left autochthon muscle of totalseg-mr
// (label 46), its template built from its own label (volume-preserving template, so its volume is the label's), moved
// rigidly and also scaled.
TEST(VolumeModel, DISABLED_RealAutochthonMuscleMeasured) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const msk::ImageF mr = msk::readNifti<float>(data + "/totalseg-mr/mr.nii.gz");
  const msk::LabelMap labels = msk::readNifti<int32_t>(data + "/totalseg-mr/labels.nii.gz");
  const msk::TriangleMesh own = msk::templateFromLabels(labels, 46);
  Eigen::Vector3i lo, hi;
  msk::test::voxelBox(mr.grid, {own}, 20.0, lo, hi);
  const msk::ImageF img = msk::test::cropVolume(mr, lo, hi);
  msk::SceneObject o;
  o.name = "autochthon_left";
  o.label = 46;
  o.kind = msk::ObjectKind::Muscle;
  o.model = msk::defaultModel(o.kind);
  for (double scale : {1.0, 0.95, 1.05}) {
    o.templ = movedScaled(own, 3.0, Vec3(1, 2, 3), scale, Vec3(2.0, -2.5, 1.5));
    // The profile force, its profiles learned where the template came from (the label's own surface), as the real
    // scenes do: the gradient force grows this blurry muscle by about 40 %.
    o.hasForce = true;
    o.force = o.model.imageForce = msk::TargetMode::Profile;
    o.profileSource = movedScaledMatrix(own, 3.0, Vec3(1, 2, 3), scale, Vec3(2.0, -2.5, 1.5)).inverse();
    const VolumeRun r = runVolumeModel(img, o, labels, 46, msk::enclosedVolume(own));
    char what[64];
    std::snprintf(what, sizeof what, "own label moved, scaled %.2f", scale);
    printRun("autochthon", what, r);
  }
}

// Issue 4, on anatomy: the phantom hamstrings (always) and the real left autochthon muscle (when ../shared/data is
// there), each template its object's true surface moved rigidly by 3.5 mm and 4° (the image asks for no volume
// change: the model keeps its volume within 2 %) and the same also scaled by 0.92 (the image asks for +30 % of
// volume: the model must follow, ending at least 10 % from the template's volume and within 5 % of the true one).
// Measured: hamstrings +0.00 % (Dice 0.841 → 0.972), scaled +22.9 % (true volume −4.8 %, Dice 0.970); autochthon
// −0.00 % (Dice 0.867 → 0.967), scaled +23.0 % (true volume −4.7 %, Dice 0.952). Inverted tets at the end: none of
// about 15 600 (phantom) and 11 200 (real), the .vtu boundary on the surface's vertices (0 mm off). Before the
// tetrahedralisation gave every tet an interior node (bridges split) and the recovered mesh was untangled: 24 and 8 of
// about 9 730, 1 and 1 of about 10 850, most of them tets with all four nodes on the surface.
TEST(VolumeModel, KeepsItsVolumeUnlessTheImageDemandsOtherwise) {
  struct Case {
    const char* name;
    msk::ImageF image;
    msk::LabelMap labels;
    msk::SceneObject object;
    msk::TriangleMesh truth;
    bool real;
  };
  std::vector<Case> cases;
  {
    const std::string dir = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1";
    Case c{"hamstrings", msk::readNifti<float>(dir + "/image.nii.gz"), msk::readNifti<int32_t>(dir + "/labels.nii.gz"),
           {}, msk::readMesh(dir + "/truth_hamstrings.vtk"), false};
    for (const msk::SceneObject& o : msk::loadScene(dir + "/scene.json").objects)
      if (o.name == "hamstrings") c.object = o;
    ASSERT_EQ(c.object.name, "hamstrings");
    cases.push_back(std::move(c));
  }
  const std::string data = msk::test::sharedData();
  if (!data.empty()) {
    const msk::ImageF mr = msk::readNifti<float>(data + "/totalseg-mr/mr.nii.gz");
    Case c{"autochthon", {}, msk::readNifti<int32_t>(data + "/totalseg-mr/labels.nii.gz"), {}, {}, true};
    c.truth = msk::templateFromLabels(c.labels, 46);
    Eigen::Vector3i lo, hi;
    msk::test::voxelBox(mr.grid, {c.truth}, 20.0, lo, hi);
    c.image = msk::test::cropVolume(mr, lo, hi);
    c.object.name = "autochthon_left";
    c.object.label = 46;
    c.object.kind = msk::ObjectKind::Muscle;
    c.object.model = msk::defaultModel(c.object.kind);
    c.object.hasForce = true;
    c.object.force = c.object.model.imageForce = msk::TargetMode::Profile;
    cases.push_back(std::move(c));
  } else {
    std::printf("[          ] ../shared/data absent: the real autochthon muscle is not run\n");
  }
  for (Case& c : cases) {
    SCOPED_TRACE(c.name);
    const double truthMm3 = msk::enclosedVolume(c.truth);
    for (double scale : {1.0, 0.92}) {
      msk::SceneObject o = c.object;
      o.templ = movedScaled(c.truth, 4.0, Vec3(1, 2, 3), scale, Vec3(2.0, -2.5, 1.5));
      // Profiles (real muscle) learned where the template came from: its true place.
      if (c.real) o.profileSource = movedScaledMatrix(c.truth, 4.0, Vec3(1, 2, 3), scale, Vec3(2.0, -2.5, 1.5)).inverse();
      const VolumeRun r = runVolumeModel(c.image, o, c.labels, o.label, truthMm3);
      printRun(c.name, scale == 1.0 ? "truth moved rigidly" : "truth moved, scaled 0.92", r);
      EXPECT_GT(r.dice, r.templateDice + 0.05);
      EXPECT_GE(r.dice, 0.95);
      if (scale == 1.0) {
        EXPECT_LT(std::fabs(r.changePercent()), 2.0);  // kept
        EXPECT_EQ(r.decision, "holding");
      } else {
        EXPECT_EQ(r.decision, "following");
        EXPECT_GT(r.changePercent(), 10.0);            // followed the image
        EXPECT_LT(std::fabs(r.errorPercent()), 5.0);   // to the true volume
      }
      // None inverted (every tet has an interior node, tetrahedralize's interiorNodes; the recovered mesh untangled).
      EXPECT_EQ(r.inverted, 0);
    }
  }
}

// What the mesh optimisers cost (printed; run with --gtest_also_run_disabled_tests): the phantom muscles' templates
// tetrahedralised plain, with ODT + perturbation + exudation, and also with interior nodes (as the segmenter does).
TEST(VolumeModel, DISABLED_TetrahedralisationTimeMeasured) {
  const std::string dir = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1";
  for (const char* name : {"hamstrings", "quadriceps", "adductors"}) {
    const msk::TriangleMesh t = msk::readMesh(dir + "/template_" + std::string(name) + ".vtk");
    const double edge = msk::meanEdgeLength(t);
    for (int variant : {0, 1, 2, 3}) {
      const bool optimise = variant > 0;
      msk::TetOptions to;
      to.facetSizeMm = edge;
      to.cellSizeMm = 1.5 * edge;
      to.facetDistanceMm = 0.1 * edge;
      to.odt = to.perturb = to.exude = optimise;
      to.interiorNodes = variant >= 2;
      to.interiorSplit = variant == 2 ? msk::BoundarySplit::Bridges : msk::BoundarySplit::Tets;
      const auto t0 = std::chrono::steady_clock::now();
      const msk::TetMesh m = msk::tetrahedralize(t, to);
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const Eigen::VectorXd angle = msk::tetMinDihedralAngles(m);
      std::printf("[          ] %-11s %-24s %6d tets, %.2f s, smallest dihedral %.2f deg, %d under 5 deg, %d with all "
                  "nodes on the surface\n",
                  name, variant == 0   ? "plain"
                  : variant == 1 ? "optimised"
                  : variant == 2 ? "optimised + bridges split"
                                 : "optimised + tets split", m.tetCount(),
                  s, angle.minCoeff(), static_cast<int>((angle.array() < 5.0).count()), msk::boundaryOnlyTetCount(m));
      EXPECT_EQ(msk::tetMeshProblem(m), "");
    }
  }
}
