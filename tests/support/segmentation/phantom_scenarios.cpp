#include "msk/test/phantom_scenarios.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "msk/core/collision_surface.h"
#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/files.h"

namespace msk::test {

std::string PhantomCase::name() const {
  char text[96];
  std::snprintf(text, sizeof text, "seed %u (%gx%gx%g, oblique %g,%g,%g)", seed, spacing[0], spacing[1], spacing[2],
                oblique[0], oblique[1], oblique[2]);
  return text;
}

const std::vector<PhantomCase>& otherPhantomCases() {
  static const std::vector<PhantomCase> cases = {{2, {1.2, 1.2, 3}, {0, 0, 0}},
                                                 {3, {1.2, 1.2, 3}, {10, -15, 20}},
                                                 {4, {1, 1.5, 2.5}, {0, 0, 0}},
                                                 {5, {0.9, 0.9, 4}, {-20, 10, 5}},
                                                 {6, {1.5, 1.5, 1.5}, {0, 0, 30}}};
  return cases;
}

Phantom makeCasePhantom(const PhantomCase& c) {
  PhantomOptions o;
  o.seed = c.seed;
  o.spacing = c.spacing;
  o.obliqueDegrees = c.oblique;
  return makePhantom(o);
}

FemurCase bundledFemur() {
  const std::string dir = bundledSample();
  FemurCase c;
  c.name = "bundled seed 1 (1.2x1.2x3)";
  c.image = readNifti<float>(dir + "image.nii.gz");
  c.labels = readNifti<int32_t>(dir + "labels.nii.gz");
  c.truth = readMesh(dir + "truth_femur.vtk");
  const Scene scene = loadScene(dir + "scene.json");
  if (scene.objects.empty() || scene.objects[0].name != "femur") throw Error(dir + "scene.json: femur not first");
  c.templ = scene.objects[0].templ;
  return c;
}

FemurCase phantomFemur(const PhantomCase& pc) {
  Phantom p = makeCasePhantom(pc);
  if (p.objects.empty() || p.objects[0].name != "femur") throw Error("phantom " + pc.name() + ": femur not first");
  FemurCase c;
  c.name = pc.name();
  c.image = std::move(p.image);
  c.labels = std::move(p.labels);
  c.truth = p.objects[0].truth;
  c.templ = p.objects[0].templ;
  return c;
}

Scene femurScene(const TriangleMesh& templ) {
  Scene scene;
  SceneObject femur;
  femur.name = "femur";
  femur.label = 1;
  femur.kind = ObjectKind::Bone;
  femur.templ = templ;
  scene.objects.push_back(femur);
  return scene;
}

FemurScore segmentFemur(const FemurCase& c, const SegmentOptions& opts, const TriangleMesh* templ,
                        TemplateScores scores) {
  const TriangleMesh& t = templ ? *templ : c.templ;
  const SegmentationResult res = segmentScene(c.image, femurScene(t), opts);
  FemurScore s;
  s.labels = labelMetrics(res.labels, 1, c.labels, 1);
  s.mesh = meshMetrics(res.objects[0].mesh, c.truth);
  if (scores == TemplateScores::Measure) s.start = meshMetrics(t, c.truth);
  s.quality = res.objects[0].quality;
  s.seconds = res.seconds;
  return s;
}

BundledThigh loadBundledThigh() {
  const std::string dir = bundledSample();
  return {readNifti<float>(dir + "image.nii.gz"), readNifti<int32_t>(dir + "labels.nii.gz"),
          loadScene(dir + "scene.json")};
}

ThighRun segmentThigh(const BundledThigh& thigh, const Scene& scene, const SegmentOptions& opts) {
  ThighRun r;
  r.res = segmentScene(thigh.image, scene, opts);
  for (int l = 1; l <= 4; ++l) {
    const SegmentationMetrics m = labelMetrics(r.res.labels, l, thigh.labels, l);
    r.dice[l - 1] = m.dice;
    r.assd[l - 1] = m.assd;
  }
  return r;
}

const std::vector<ThighCollisionCase>& thighCollisionCases() {
  static const std::vector<ThighCollisionCase> cases = {
      {"velocity, spring, sequential", CollisionMode::Velocity, CollisionResolution::Sequential},
      {"position, spring, global", CollisionMode::Position, CollisionResolution::Global}};
  return cases;
}

namespace {

/// Tissue class at the voxel nearest to a world point (Air outside the grid).
int tissueAt(const Phantom& p, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = p.tissues.grid.toVoxel(x);
  const int i = static_cast<int>(std::lround(v.x())), j = static_cast<int>(std::lround(v.y())),
            k = static_cast<int>(std::lround(v.z()));
  return p.tissues.grid.contains(i, j, k) ? p.tissues.at(i, j, k) : 0;
}

/// Adds the distances from the truth surface's vertices to the result surface to `missingMm` where the septum is
/// missing (1.5 mm outside the truth vertex along its normal there is muscle of a neighbour, not fat), else to
/// `otherMm`, counting the vertices.
void septaErrors(const Phantom& p, const TriangleMesh& truth, const TriangleMesh& result, double& missingMm,
                 int& missingCount, double& otherMm, int& otherCount) {
  CollisionSurface surface(result.faces, 20.0);
  surface.update(result.vertices);
  const Points normals = vertexNormals(truth);
  for (int v = 0; v < truth.vertexCount(); ++v) {
    const Eigen::Vector3d x = truth.vertices.row(v).transpose(), n = normals.row(v).transpose();
    const int out = tissueAt(p, x + 1.5 * n);
    const bool missing =
        out == static_cast<int>(PhantomTissue::Muscle) || out == static_cast<int>(PhantomTissue::IntramuscularFat);
    const SurfacePoint s = surface.closest(result.vertices, x, 20.0);
    const double d = s.triangle < 0 ? 20.0 : s.distance;
    (missing ? missingMm : otherMm) += d;
    ++(missing ? missingCount : otherCount);
  }
}

}  // namespace

ThighSceneScore segmentPhantomThigh(const PhantomCase& c, TemplateScores scores) {
  const Phantom p = makeCasePhantom(c);
  const Scene scene = phantomScene(p);
  ThighSceneScore sc;
  sc.objectsInScene = scene.objects.size();
  sc.collisionPairs = scene.collisions.size();
  const SegmentationResult res = segmentScene(p.image, scene, SegmentOptions{});
  double assdSum = 0;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const int label = scene.objects[i].label;
    ThighObjectScore o;
    o.name = scene.objects[i].name;
    o.dice = labelMetrics(res.labels, label, p.labels, label).dice;
    o.meshAssd = meshMetrics(res.objects[i].mesh, p.objects[i].truth).assd;
    o.quality = res.objects[i].quality;
    if (scores == TemplateScores::Measure)
      o.templateAssd = meshMetrics(scene.objects[i].templ, p.objects[i].truth).assd;
    if (scene.objects[i].kind == ObjectKind::Muscle)
      septaErrors(p, p.objects[i].truth, res.objects[i].mesh, sc.septaMissingMm, sc.septaMissingVertices,
                  sc.septaOtherMm, sc.septaOtherVertices);
    assdSum += o.meshAssd;
    sc.objects.push_back(o);
  }
  sc.meanAssd = scene.objects.empty() ? 0 : assdSum / static_cast<double>(scene.objects.size());
  if (sc.septaMissingVertices > 0) sc.septaMissingMm /= sc.septaMissingVertices;
  if (sc.septaOtherVertices > 0) sc.septaOtherMm /= sc.septaOtherVertices;
  sc.overlapVoxels = res.overlapVoxels;
  sc.overlapVoxelsRepaired = res.overlapVoxelsRepaired;
  for (double d : res.pairPenetrationMm) sc.deepestMm = std::max(sc.deepestMm, d);
  sc.seconds = res.seconds;
  return sc;
}

}  // namespace msk::test
