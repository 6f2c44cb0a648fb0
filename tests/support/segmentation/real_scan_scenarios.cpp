#include "msk/test/real_scan_scenarios.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/template_builder.h"
#include "msk/test/shapes.h"
#include "msk/test/volumes.h"

namespace msk::test {

namespace {

const Eigen::Vector3d kDirections[] = {Eigen::Vector3d(1, 1, 1).normalized(), Eigen::Vector3d(-1, 1, -1).normalized(),
                                       Eigen::Vector3d(1, -1, -1).normalized(),
                                       Eigen::Vector3d(-1, -1, 1).normalized()};
constexpr double kScales[] = {1.03, 0.97, 1.03, 0.97};

/// Template of the other side: the smooth template of `fromLabel`, mirrored across the sagittal plane x = `midX`
/// (RAS mm).
TriangleMesh mirroredTemplate(const LabelMap& labels, int fromLabel, double midX, const TemplateOptions& opts = {}) {
  return mirrorMesh(templateFromLabels(labels, fromLabel, opts), Eigen::Vector3d(midX, 0, 0), Eigen::Vector3d::UnitX());
}

/// The affine map from a template made by displacedScaled(mirrored, offset, scale) back to the contralateral
/// structure it was mirrored from (the scene's profile source): undo the displacement and scale about the centroid,
/// then mirror across x = midX.
Eigen::Matrix4d sourceOfTemplate(const TriangleMesh& templ, const Eigen::Vector3d& offsetMm, double scale, double midX,
                                 const Eigen::Matrix4d& pose = Eigen::Matrix4d::Identity()) {
  const Eigen::Vector3d c = templ.vertices.colwise().mean().transpose();  // = mirrored centroid + offset
  Eigen::Matrix4d undo = Eigen::Matrix4d::Identity();
  undo.topLeftCorner<3, 3>() /= scale;
  undo.topRightCorner<3, 1>() = c - offsetMm - c / scale;
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  mirror(0, 3) = 2 * midX;
  return mirror * pose.inverse() * undo;
}

}  // namespace

RealScene makeRealScene(const ImageF& image, const LabelMap& labels, const std::vector<ObjectSpec>& specs, double midX,
                        const std::vector<std::pair<int, int>>& pairs, int vertices, double displacementMm,
                        double marginMm) {
  RealScene rs;
  rs.reference = labels;
  TemplateOptions topts;
  topts.vertices = vertices;
  std::vector<TriangleMesh> meshes;
  for (size_t i = 0; i < specs.size(); ++i) {
    SceneObject o;
    o.name = specs[i].name;
    o.label = specs[i].label;
    o.kind = specs[i].kind;
    const Eigen::Vector3d offset = displacementMm * kDirections[i % 4];
    const double scale = displacementMm > 0 ? kScales[i % 4] : 1.0;
    TriangleMesh mirrored = specs[i].mirror ? mirroredTemplate(labels, specs[i].templateFrom, midX, topts)
                                            : templateFromLabels(labels, specs[i].templateFrom, topts);
    const Eigen::Matrix4d& pose = specs[i].pose;
    mirrored.vertices = ((mirrored.vertices * pose.topLeftCorner<3, 3>().transpose()).rowwise() +
                         pose.topRightCorner<3, 1>().transpose())
                            .eval();
    o.templ = displacedScaled(mirrored, offset, scale);
    o.hasForce = true;
    o.force = o.model.imageForce = TargetMode::Profile;
    o.profileSource = sourceOfTemplate(o.templ, offset, scale, midX, pose);
    meshes.push_back(o.templ);
    meshes.push_back(o.templ);  // and where its profiles are learned
    Points normals = Points::Zero(o.templ.vertexCount(), 3);
    toProfileSource(o, meshes.back().vertices, normals);
    rs.scene.objects.push_back(o);
  }
  for (const auto& [a, b] : pairs) rs.scene.collisions.push_back({a, b});
  Eigen::Vector3i lo, hi;
  voxelBox(image.grid, meshes, marginMm, lo, hi);
  rs.image = cropVolume(image, lo, hi);
  return rs;
}

SceneScore runRealScene(const RealScene& rs, const SegmentOptions& opts) {
  SceneScore sc;
  sc.result = segmentScene(rs.image, rs.scene, opts);
  for (size_t i = 0; i < rs.scene.objects.size(); ++i) {
    const SceneObject& o = rs.scene.objects[i];
    ObjectScore s;
    s.name = o.name;
    s.label = o.label;
    s.before = labelMetrics(rasterize(o.templ, rs.reference.grid), 1, rs.reference, o.label);
    s.after = labelMetrics(rasterize(sc.result.objects[i].mesh, rs.reference.grid), 1, rs.reference, o.label);
    sc.objects.push_back(s);
  }
  sc.overlapVoxels = sc.result.overlapVoxels;
  for (double p : sc.result.pairPenetrationMm) sc.maxPenetrationMm = std::max(sc.maxPenetrationMm, p);
  sc.seconds = sc.result.seconds;
  return sc;
}

int splitComponents(LabelMap& labels, int label, int firstLabel, size_t minVoxels) {
  const Grid& g = labels.grid;
  std::vector<int> comp(g.voxelCount(), -1);
  std::vector<std::vector<size_t>> parts;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        if (labels.at(i, j, k) != label || comp[g.index(i, j, k)] >= 0) continue;
        std::vector<Eigen::Vector3i> stack = {Eigen::Vector3i(i, j, k)};
        comp[g.index(i, j, k)] = static_cast<int>(parts.size());
        parts.emplace_back();
        while (!stack.empty()) {
          const Eigen::Vector3i v = stack.back();
          stack.pop_back();
          parts.back().push_back(g.index(v[0], v[1], v[2]));
          for (int dk = -1; dk <= 1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
              for (int di = -1; di <= 1; ++di) {
                const Eigen::Vector3i u = v + Eigen::Vector3i(di, dj, dk);
                if (!g.contains(u[0], u[1], u[2]) || labels.at(u[0], u[1], u[2]) != label) continue;
                int& c = comp[g.index(u[0], u[1], u[2])];
                if (c < 0) c = static_cast<int>(parts.size()) - 1, stack.push_back(u);
              }
        }
      }
  std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  int n = 0;
  for (const auto& p : parts) {
    if (p.size() < minVoxels) break;
    for (size_t v : p) labels.data[v] = firstLabel + n;
    ++n;
  }
  return n;
}

RigidFitScore rigidFitOfMirror(const LabelMap& labels, int from, int to, double midX) {
  const Grid& g = labels.grid;
  auto boundary = [&](int label, bool mirror) {
    std::vector<Eigen::Vector3d> pts;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i) {
          if (labels.at(i, j, k) != label) continue;
          bool edge = false;
          for (const Eigen::Vector3i& d :
               {Eigen::Vector3i(1, 0, 0), Eigen::Vector3i(-1, 0, 0), Eigen::Vector3i(0, 1, 0),
                Eigen::Vector3i(0, -1, 0), Eigen::Vector3i(0, 0, 1), Eigen::Vector3i(0, 0, -1)}) {
            const Eigen::Vector3i u = Eigen::Vector3i(i, j, k) + d;
            edge = edge || !g.contains(u[0], u[1], u[2]) || labels.at(u[0], u[1], u[2]) != label;
          }
          if (!edge) continue;
          Eigen::Vector3d x = g.toWorld(Eigen::Vector3d(i, j, k));
          if (mirror) x.x() = 2 * midX - x.x();
          pts.push_back(x);
        }
    return pts;
  };
  const std::vector<Eigen::Vector3d> src = boundary(from, true), dst = boundary(to, false);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero(), centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& x : src) centroid += x / static_cast<double>(src.size());
  for (int it = 0; it < 30 && !src.empty() && !dst.empty(); ++it) {
    Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> match(src.size());
    for (size_t a = 0; a < src.size(); ++a) {
      const Eigen::Vector3d q = R * src[a] + t;
      double best = std::numeric_limits<double>::infinity();
      for (const Eigen::Vector3d& b : dst)
        if ((b - q).squaredNorm() < best) best = (b - q).squaredNorm(), match[a] = b;
      ca += src[a];
      cb += match[a];
    }
    ca /= static_cast<double>(src.size());
    cb /= static_cast<double>(src.size());
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    for (size_t a = 0; a < src.size(); ++a) h += (src[a] - ca) * (match[a] - cb).transpose();
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d flip = Eigen::Matrix3d::Identity();
    flip(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
    R = svd.matrixV() * flip * svd.matrixU().transpose();
    t = cb - R * ca;
  }
  // Dice over the grid: voxel x lies in the fitted mirror if R⁻¹(x − t), mirrored back, falls in a voxel of `from`.
  auto dice = [&](const Eigen::Matrix3d& rot, const Eigen::Vector3d& shift) {
    size_t a = 0, b = 0, both = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i) {
          Eigen::Vector3d q = rot.transpose() * (g.toWorld(Eigen::Vector3d(i, j, k)) - shift);
          q.x() = 2 * midX - q.x();
          const Eigen::Vector3i v = g.toVoxel(q).array().round().cast<int>();
          const bool in = g.contains(v[0], v[1], v[2]) && labels.at(v[0], v[1], v[2]) == from;
          const bool ref = labels.at(i, j, k) == to;
          a += in;
          b += ref;
          both += in && ref;
        }
    return a + b > 0 ? 2.0 * static_cast<double>(both) / static_cast<double>(a + b) : 0.0;
  };
  RigidFitScore sc;
  sc.mirrorDice = dice(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  sc.fittedDice = dice(R, t);
  sc.rotationDeg = Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
  sc.centroidMoveMm = (R * centroid + t - centroid).norm();
  sc.pose.topLeftCorner<3, 3>() = R;
  sc.pose.topRightCorner<3, 1>() = t;
  return sc;
}

std::vector<BoundaryClassError> errorByOutside(const TriangleMesh& mesh, const LabelMap& labels, int label,
                                               const ImageF& image, const std::vector<int>& partners,
                                               const std::vector<int>& bones, double outMm) {
  std::vector<BoundaryClassError> cls = {{"fat (< -40 HU)"}, {"bone"}, {"partner muscles"}, {"other soft tissue"}};
  auto labelAt = [&](const Eigen::Vector3d& x) {
    const Eigen::Vector3i v = labels.grid.toVoxel(x).array().round().cast<int>();
    return labels.grid.contains(v[0], v[1], v[2]) ? labels.at(v[0], v[1], v[2]) : 0;
  };
  auto valueAt = [&](const Eigen::Vector3d& x) {
    const Eigen::Vector3i v = image.grid.toVoxel(x).array().round().cast<int>();
    return image.grid.contains(v[0], v[1], v[2]) ? static_cast<double>(image.at(v[0], v[1], v[2])) : -1000.0;
  };
  auto among = [](int l, const std::vector<int>& set) { return std::find(set.begin(), set.end(), l) != set.end(); };
  const Points normals = vertexNormals(mesh);
  for (int i = 0; i < mesh.vertexCount(); ++i) {
    const Eigen::Vector3d p = mesh.vertices.row(i).transpose(), n = normals.row(i).transpose().normalized();
    const int outside = labelAt(p + outMm * n);
    const double hu = valueAt(p + outMm * n);
    const size_t c = among(outside, bones) || hu > 250 ? 1 : among(outside, partners) ? 2 : hu < -40 ? 0 : 3;
    double best = std::numeric_limits<double>::infinity();  // the label's inside → outside crossing nearest to p
    for (double s = -9; s < 9; s += 0.25)
      if (labelAt(p + s * n) == label && labelAt(p + (s + 0.25) * n) != label && std::abs(s + 0.125) < std::abs(best))
        best = s + 0.125;
    if (!std::isfinite(best)) continue;
    ++cls[c].vertices;
    cls[c].signedMm -= best;
    cls[c].absMm += std::abs(best);
  }
  for (auto& c : cls)
    if (c.vertices > 0) c.signedMm /= c.vertices, c.absMm /= c.vertices;
  return cls;
}

RealScene mrScene(const std::string& data, int vertices) {
  const ImageF mr = readNifti<float>(data + "/totalseg-mr/mr.nii.gz");
  LabelMap labels = readNifti<int32_t>(data + "/totalseg-mr/labels.nii.gz");
  const double midX = labelCentroid(labels, 19).x();
  std::vector<ObjectSpec> specs = {{"autochthon_left", 46, 47, ObjectKind::Muscle},
                                   {"autochthon_right", 47, 46, ObjectKind::Muscle}};
  static const char* names[] = {"vertebra_1", "vertebra_2", "vertebra_3", "vertebra_4"};
  const int vertebrae = std::min(4, splitComponents(labels, 19, 1901, 100));
  std::vector<std::pair<int, int>> pairs;
  for (int v = 0; v < vertebrae; ++v) {
    specs.push_back({names[v], 1901 + v, 1901 + v, ObjectKind::Bone});
    pairs.push_back({0, 2 + v});
    pairs.push_back({1, 2 + v});
  }
  return makeRealScene(mr, labels, specs, midX, pairs, vertices);
}

RealScene ctScene(const std::string& data, double displacementMm, const Eigen::Matrix4d& mediusPose, bool ownLabels) {
  const ImageF ct = readNifti<float>(data + "/totalseg-ct/ct.nii.gz");
  const LabelMap labels = readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  const double midX = labelCentroid(labels, 25).x();
  const Eigen::Matrix4d id = Eigen::Matrix4d::Identity();
  const bool mirror = !ownLabels;
  return makeRealScene(ct, labels,
                       {{"femur_right", 76, mirror ? 75 : 76, ObjectKind::Bone, id, mirror},
                        {"hip_right", 78, mirror ? 77 : 78, ObjectKind::Bone, id, mirror},
                        {"gluteus_maximus_right", 81, mirror ? 80 : 81, ObjectKind::Muscle, id, mirror},
                        {"gluteus_medius_right", 83, mirror ? 82 : 83, ObjectKind::Muscle, mediusPose, mirror}},
                       midX, {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}, 3000, displacementMm);
}

SceneScore runCtScene(RealScene& rs, bool edgeLevel) {
  rs.scene.objects[0].model.refine = rs.scene.objects[1].model.refine = true;  // the bones
  SegmentOptions opts;
  opts.shape.priorEnd = 0.2;
  opts.image.rangeFine = 1.0;
  opts.image.sigmaFine = 1.0;
  opts.image.edgeLevel = edgeLevel;
  return runRealScene(rs, opts);
}

SceneScore runMrScene(const RealScene& rs) {
  SegmentOptions opts;
  opts.shape.priorEnd = 0.3;
  return runRealScene(rs, opts);
}

SceneScore runCtSceneFromOwnLabels(const std::string& data, bool gradient) {
  RealScene rs = ctScene(data, kDisplacementMm, Eigen::Matrix4d::Identity(), true);
  if (gradient)
    for (SceneObject& o : rs.scene.objects) {
      o.force = o.model.imageForce = TargetMode::Gradient;
      o.profileSource.reset();
    }
  return runCtScene(rs, gradient);
}

double ctMidSagittalX(const LabelMap& labels) { return labelCentroid(labels, 25).x(); }

SceneObject mirroredBone(const LabelMap& labels, const char* name, int label, int from, double midX) {
  SceneObject o;
  o.name = name;
  o.label = label;
  o.kind = ObjectKind::Bone;
  o.templ = mirroredTemplate(labels, from, midX);
  o.hasForce = true;
  o.force = o.model.imageForce = TargetMode::Profile;
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  mirror(0, 3) = 2 * midX;
  o.profileSource = mirror;
  return o;
}

SegmentOptions ctFemurOptions(bool refine) {
  SegmentOptions opts;
  opts.shape.priorEnd = 0.2;
  opts.image.rangeFine = 1.0;
  opts.image.refinePass = refine;
  return opts;
}

CtFemurRuns runCtFemur(const std::string& data) {
  const ImageF ct = readNifti<float>(data + "/totalseg-ct/ct.nii.gz");
  const LabelMap labels = readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  CtFemurRuns r;
  r.midX = ctMidSagittalX(labels);
  Scene scene;
  scene.objects.push_back(mirroredBone(labels, "femur_right", 76, 75, r.midX));
  const SegmentationResult res = segmentScene(ct, scene, ctFemurOptions());
  const SegmentationResult unrefined = segmentScene(ct, scene, ctFemurOptions(false));
  LabelMap start(ct.grid, 0);
  rasterizeInto(start, scene.objects[0].templ, 76);
  r.before = labelMetrics(start, 76, labels, 76);
  r.after = labelMetrics(res.labels, 76, labels, 76);
  r.status = res.status;
  r.withoutPass = labelMetrics(unrefined.labels, 76, labels, 76);
  r.seconds = res.seconds;
  return r;
}

CtFemurWithHip runCtFemurWithHip(const std::string& data) {
  const ImageF ct = readNifti<float>(data + "/totalseg-ct/ct.nii.gz");
  const LabelMap labels = readNifti<int32_t>(data + "/totalseg-ct/labels.nii.gz");
  const double midX = ctMidSagittalX(labels);
  Scene scene;
  scene.objects.push_back(mirroredBone(labels, "femur_right", 76, 75, midX));
  scene.objects.push_back(mirroredBone(labels, "hip_right", 78, 77, midX));
  scene.collisions.push_back({0, 1});
  const SegmentationResult res = segmentScene(ct, scene, ctFemurOptions());
  LabelMap start(ct.grid, 0);
  rasterizeInto(start, scene.objects[0].templ, 76);
  rasterizeInto(start, scene.objects[1].templ, 78);
  CtFemurWithHip r;
  r.femurBefore = labelMetrics(start, 76, labels, 76);
  r.femur = labelMetrics(res.labels, 76, labels, 76);
  r.hipBefore = labelMetrics(start, 78, labels, 78);
  r.hip = labelMetrics(res.labels, 78, labels, 78);
  r.overlapVoxels = res.overlapVoxels;
  r.status = res.status;
  r.penetrationMm = res.pairPenetrationMm.empty() ? 0 : res.pairPenetrationMm[0];
  r.seconds = res.seconds;
  return r;
}

}  // namespace msk::test
