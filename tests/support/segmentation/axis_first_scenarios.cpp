#include "msk/test/axis_first_scenarios.h"

#include <cmath>

#include "msk/core/error.h"
#include "msk/test/phantom_scenarios.h"
#include "msk/test/volumes.h"

namespace msk::test {

bool BentTube::inside(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d q = p - offset;
  const double u = q.x() / half;
  const double y = q.y() - bend * u * u;
  return u * u * u * u + (y * y + q.z() * q.z()) / (radius * radius) <= 1.0;
}

TriangleMesh BentTube::mesh(int subdivisions) const {
  TriangleMesh m = makeIcosphere(1.0, subdivisions);
  for (int v = 0; v < m.vertexCount(); ++v) {
    const Eigen::Vector3d s = m.vertices.row(v);
    const double x = half * std::copysign(std::sqrt(std::fabs(s.x())), s.x());
    const double u = x / half;
    m.vertices.row(v) = (Eigen::Vector3d(x, radius * s.y() + bend * u * u, radius * s.z()) + offset).transpose();
  }
  return m;
}

Grid tubeGrid() {
  Grid g;
  g.dims = {105, 49, 37};
  g.spacing = Eigen::Vector3d::Ones();
  g.direction = Eigen::Matrix3d::Identity();
  g.origin = Eigen::Vector3d(-52, -18, -18);
  return g;
}

ImageF tubeImage(const Grid& g, const BentTube& t) {
  return partialVolumeImage(
      g, [&](const Eigen::Vector3d& x) { return t.inside(x); }, 800.f, 200.f);
}

Scene tubeScene(const TriangleMesh& templ, bool medialAxis, bool axisFirst) {
  Scene s;
  SceneObject o;
  o.name = "tube";
  o.label = 1;
  o.kind = ObjectKind::Muscle;
  o.templ = templ;
  o.model = defaultModel(o.kind);
  o.model.medialAxis = medialAxis;
  if (medialAxis) o.model.axisFirst = axisFirst;
  s.objects.push_back(o);
  return s;
}

const std::vector<BentTubeCase>& bentTubeCases() {
  static const std::vector<BentTubeCase> cases = {
      {0.0, Eigen::Vector3d(0, 6, -3)}, {8.0, Eigen::Vector3d::Zero()}, {12.0, Eigen::Vector3d(0, 6, -3)}};
  return cases;
}

BentTubeRuns runBentTube(const BentTubeCase& c) {
  BentTube truthTube, templTube;
  truthTube.bend = c.bendMm;
  templTube.offset = c.offsetMm;
  const ImageF img = tubeImage(tubeGrid(), truthTube);
  const TriangleMesh truth = truthTube.mesh(), templ = templTube.mesh();
  auto run = [&](bool axis, bool axisFirst) {
    AxisRun r;
    r.res = segmentScene(img, tubeScene(templ, axis, axisFirst), SegmentOptions{});
    r.m = meshMetrics(r.res.objects[0].mesh, truth, 0.5);
    return r;
  };
  BentTubeRuns runs;
  runs.start = meshMetrics(templ, truth, 0.5);
  runs.plain = run(false, false);
  runs.axis = run(true, false);
  runs.first = run(true, true);
  return runs;
}

DisplacedMuscleRuns runDisplacedThighMuscle(const std::string& name, FullRuns full) {
  const BundledThigh thigh = loadBundledThigh();
  const ImageF& img = thigh.image;
  const LabelMap& truth = thigh.labels;
  Scene s;
  for (const SceneObject& o : thigh.scene.objects)
    if (o.name == name) s.objects.push_back(o);
  if (s.objects.size() != 1) throw Error("bundled scene: no single object named " + name);
  SceneObject& o = s.objects[0];
  o.templ.vertices.rowwise() += Eigen::RowVector3d(8, 4, 0);
  auto metrics = [&](bool axis, bool axisFirst, const SegmentOptions& opts, int* steps = nullptr) {
    o.model.medialAxis = axis;
    o.model.axisFirst.reset();
    if (axis) o.model.axisFirst = axisFirst;
    const SegmentationResult r = segmentScene(img, s, opts);
    if (steps) *steps = r.axisFirst.empty() ? 0 : r.axisFirst[0].steps;
    return labelMetrics(r.labels, o.label, truth, o.label);
  };
  // One full step without image force: the template as it is, or as the stage left it.
  SegmentOptions still;
  still.evolution.levels = 1;
  still.evolution.maxStepsPerLevel = 1;
  still.image.stiffness = 0;
  DisplacedMuscleRuns r;
  r.templ = metrics(false, false, still);
  r.stage = metrics(true, true, still);
  if (full == FullRuns::All) {
    r.plain = metrics(false, false, {});
    r.axis = metrics(true, false, {});
  }
  r.first = metrics(true, true, {}, &r.stageSteps);
  return r;
}

}  // namespace msk::test
