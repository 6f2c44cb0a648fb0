#include "msk/test/volume_model_scenarios.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/tet_split.h"
#include "msk/core/volume_simplex.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/template_builder.h"
#include "msk/segmentation/tetrahedralize.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"

namespace msk::test {

TriangleMesh movedScaled(const TriangleMesh& mesh, double angleDeg, const Eigen::Vector3d& axis, double scale,
                         const Eigen::Vector3d& offset) {
  const Eigen::Vector3d c = mesh.vertices.colwise().mean().transpose();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(angleDeg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  TriangleMesh out = mesh;
  for (int v = 0; v < mesh.vertexCount(); ++v)
    out.vertices.row(v) = (c + offset + scale * r * (mesh.vertices.row(v).transpose() - c)).transpose();
  return out;
}

Eigen::Matrix4d movedScaledMatrix(const TriangleMesh& mesh, double angleDeg, const Eigen::Vector3d& axis, double scale,
                                  const Eigen::Vector3d& offset) {
  const Eigen::Vector3d c = mesh.vertices.colwise().mean().transpose();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * Eigen::AngleAxisd(angleDeg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  m.topRightCorner<3, 1>() = c + offset - m.topLeftCorner<3, 3>() * c;
  return m;
}

VolumeRun runVolumeModel(const ImageF& image, SceneObject object, const LabelMap& labels, int label, double truthMm3,
                         const SegmentOptions& opts, RestQuality rest) {
  object.model.volumetric = true;
  Scene scene;
  scene.objects.push_back(object);
  VolumeRun r;
  const auto t0 = std::chrono::steady_clock::now();
  const SegmentationResult res = segmentScene(image, scene, opts);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const ObjectResult& o = res.objects.at(0);
  r.tets = o.volumeMesh.tetCount();
  r.inverted = o.invertedTets;
  const Eigen::VectorXd vols = tetVolumes(o.volumeMesh);
  Eigen::VectorXi owner;
  tetBoundaryFaces(o.volumeMesh, &owner);
  std::vector<char> atSurface(static_cast<size_t>(r.tets), 0);
  for (int f = 0; f < owner.size(); ++f) atSurface[static_cast<size_t>(owner[f])] = 1;
  for (int t = 0; t < r.tets; ++t) r.invertedAtSurface += vols[t] <= 0 && atSurface[static_cast<size_t>(t)] ? 1 : 0;
  // The tet boundary is the surface's triangulation (same vertex order): how far its nodes are from the surface's.
  Eigen::VectorXi nodeOf;
  const TriangleMesh tb = tetBoundary(o.volumeMesh, &nodeOf);
  if (tb.vertexCount() == o.mesh.vertexCount())
    r.boundaryOffSurfaceMm = (tb.vertices - o.mesh.vertices).rowwise().norm().maxCoeff();
  else
    r.boundaryOffSurfaceMm = -1;
  if (rest == RestQuality::Measure) {
    // The template's tets as the segmenter makes them (same options, same canonical order): their quality, and how
    // flat the tets that inverted were at rest.
    TetOptions to;
    const double edge = meanEdgeLength(object.templ);
    to.facetSizeMm = edge;
    to.cellSizeMm = 1.5 * edge;
    to.facetDistanceMm = 0.1 * edge;
    to.odt = to.perturb = to.exude = true;
    to.interiorNodes = true;
    const TetMesh restTets = tetrahedralize(object.templ, to);
    if (restTets.tetCount() == r.tets) {  // (exudation may break a tie differently: then no rest figures)
      const Eigen::VectorXd angle = tetMinDihedralAngles(restTets);
      r.minDihedralDeg = angle.minCoeff();
      r.slivers = static_cast<int>((angle.array() < 5.0).count());
      for (int t = 0; t < r.tets; ++t) {
        if (vols[t] > 0) continue;
        r.invertedSlivers += angle[t] < 5.0 ? 1 : 0;
        r.invertedRestDeg = std::max(r.invertedRestDeg, angle[t]);
      }
    }
  }
  r.templateMm3 = o.volumeModelTemplateMm3;
  r.decision = o.volumeDecision;
  r.modelMm3 = o.volumeModelMm3;
  r.surfaceMm3 = o.volumeMm3;
  r.truthMm3 = truthMm3;
  r.dice = labelMetrics(rasterize(o.mesh, labels.grid), 1, labels, label).dice;
  r.templateDice = labelMetrics(rasterize(object.templ, labels.grid), 1, labels, label).dice;
  return r;
}

VolumeCase phantomMuscleCase(const std::string& name) {
  const std::string dir = bundledSample();
  VolumeCase c;
  c.name = name;
  c.image = readNifti<float>(dir + "image.nii.gz");
  c.labels = readNifti<int32_t>(dir + "labels.nii.gz");
  c.truth = readMesh(dir + "truth_" + name + ".vtk");
  for (const SceneObject& o : loadScene(dir + "scene.json").objects)
    if (o.name == name) c.object = o;
  if (c.object.name != name) throw Error(dir + "scene.json: no object named " + name);
  return c;
}

VolumeCase realAutochthonCase(const std::string& sharedData) {
  const ImageF mr = readNifti<float>(sharedData + "/totalseg-mr/mr.nii.gz");
  VolumeCase c;
  c.name = "autochthon";
  c.real = true;
  c.labels = readNifti<int32_t>(sharedData + "/totalseg-mr/labels.nii.gz");
  c.truth = templateFromLabels(c.labels, 46);
  Eigen::Vector3i lo, hi;
  voxelBox(mr.grid, {c.truth}, 20.0, lo, hi);
  c.image = cropVolume(mr, lo, hi);
  c.object.name = "autochthon_left";
  c.object.label = 46;
  c.object.kind = ObjectKind::Muscle;
  c.object.model = defaultModel(c.object.kind);
  c.object.hasForce = true;
  c.object.force = c.object.model.imageForce = TargetMode::Profile;
  return c;
}

namespace {
/// The case's object with its true surface moved (and scaled) as runMovedTruth() describes.
SceneObject movedTruthObject(const VolumeCase& c, double angleDeg, double scale) {
  const Eigen::Vector3d axis(1, 2, 3), offset(2.0, -2.5, 1.5);
  SceneObject o = c.object;
  o.templ = movedScaled(c.truth, angleDeg, axis, scale, offset);
  if (c.real) o.profileSource = movedScaledMatrix(c.truth, angleDeg, axis, scale, offset).inverse();
  return o;
}
}  // namespace

VolumeRun runMovedTruth(const VolumeCase& c, double angleDeg, double scale, RestQuality rest) {
  const SceneObject o = movedTruthObject(c, angleDeg, scale);
  return runVolumeModel(c.image, o, c.labels, o.label, enclosedVolume(c.truth), SegmentOptions{}, rest);
}

double surfaceModelMovedTruthMm3(const VolumeCase& c, double angleDeg, double scale) {
  Scene scene;
  scene.objects.push_back(movedTruthObject(c, angleDeg, scale));
  scene.objects.back().model.volumetric = false;
  return enclosedVolume(segmentScene(c.image, scene, SegmentOptions{}).objects.at(0).mesh);
}

}  // namespace msk::test
