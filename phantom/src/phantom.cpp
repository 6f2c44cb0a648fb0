// Synthetic T1-weighted thigh phantom: anatomy from phantom_model.h, image formation and implicit-surface sampling from
// phantom_synthesis.h; grid, meshes and files here.
#include "msk/phantom/phantom.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <tuple>
#include <utility>

#include "msk/core/error.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/surface_extraction.h"
#include "msk/segmentation/surface_quality.h"
#include "phantom_model.h"
#include "phantom_synthesis.h"

namespace msk {

namespace {

using phantom::Model;
using phantom::Slice;

constexpr int kGeneratorVersion = 1;
constexpr double kFovHalfXY = 85;  // mm: world box [-85, 85]² × [-100, 100] holds the limb for every seed
constexpr double kFovHalfZ = 100;

struct ObjectInfo {
  const char* name;
  int32_t label;
  const char* kind;
};
constexpr ObjectInfo kObjects[] = {
    {"femur", 1, "bone"}, {"quadriceps", 2, "muscle"}, {"hamstrings", 3, "muscle"}, {"adductors", 4, "muscle"}};
constexpr int kObjectCount = 4;

// The image grid: given spacing and rotation, covering the fixed world box moved by the pose (centred on it).
Grid phantomGrid(const PhantomOptions& o) {
  return phantom::coveringGrid(o.spacing, o.obliqueDegrees, Eigen::Vector3d(-kFovHalfXY, -kFovHalfXY, -kFovHalfZ),
                               Eigen::Vector3d(kFovHalfXY, kFovHalfXY, kFovHalfZ), o.pose, o.fovZ);
}

// Samples object `object` of `model` on an axis-aligned grid of step h around its bounding box. Far from the
// surface (checked on a 4× coarser lattice with the Lipschitz bound) values are interpolated, not evaluated:
// only their sign matters to marching cubes, and it is exact there.
ImageF sampleObject(const Model& model, int object, double h) {
  const Grid g = phantom::implicitSamplingGrid(model.objectBounds(object), h);
  std::vector<Slice> slices(static_cast<size_t>(g.dims[2]));
  for (int k = 0; k < g.dims[2]; ++k) slices[static_cast<size_t>(k)] = model.slice(g.origin[2] + k * h);
  return phantom::sampleImplicit(g, Model::kLipschitz, [&](int i, int j, int k) {
    return static_cast<float>(
        model.object(object, slices[static_cast<size_t>(k)], g.origin + h * Eigen::Vector3d(i, j, k)));
  });
}

// Truth-quality meshes of all objects of a model.
std::vector<TriangleMesh> objectMeshes(const Model& model, double h, int vertices,
                                       const std::function<void(int)>& objectDone) {
  std::vector<TriangleMesh> meshes;
  IsosurfaceOptions iso;
  iso.inside = IsoInside::Below;
  iso.largestComponentOnly = true;
  for (int o = 0; o < kObjectCount; ++o) {
    const ImageF field = sampleObject(model, o, h);
    meshes.push_back(decimateMesh(isosurface(field, 0.0, iso), vertices));
    if (objectDone) objectDone(o);
  }
  return meshes;
}

// Templates depend only on the mesh settings: computed once per process and setting.
std::vector<TriangleMesh> templateMeshes(double h, int vertices, bool remeshMuscles,
                                         const std::function<void(int)>& objectDone) {
  static std::mutex mutex;
  static std::map<std::tuple<double, int, bool>, std::vector<TriangleMesh>> cache;
  std::lock_guard<std::mutex> lock(mutex);
  const std::tuple<double, int, bool> key(h, vertices, remeshMuscles);
  auto it = cache.find(key);
  if (it == cache.end()) {
    const Model mean{phantom::Anatomy{}};
    std::vector<TriangleMesh> meshes = objectMeshes(mean, h, vertices, objectDone);
    // The muscles' templates are written remeshed, as segment would remesh them (bones keep their triangulation), so
    // that segment uses them as they are.
    for (int o = 0; o < kObjectCount && remeshMuscles; ++o)
      if (std::string(kObjects[o].kind) != "bone") {
        TriangleMesh& m = meshes[static_cast<size_t>(o)];
        m = remeshIsotropic(m, m.vertexCount());
      }
    it = cache.emplace(key, std::move(meshes)).first;
  }
  return it->second;
}

// The pose as scene.json's provenance records it: its numbers, its centre and its matrix (rows).
Json phantomPoseJson(const PhantomPose& pose) {
  auto array3 = [](const Eigen::Vector3d& v) { return Json::array({v[0], v[1], v[2]}); };
  Json j = Json::object();
  j["rotationDegrees"] = array3(pose.rotationDegrees);
  j["translationMm"] = array3(pose.translationMm);
  j["scale"] = pose.scale;
  j["centre"] = array3(phantomPoseCentre());
  const Eigen::Matrix4d m = phantomPoseMatrix(pose);
  Json rows = Json::array();
  for (int r = 0; r < 4; ++r) rows.push_back(Json::array({m(r, 0), m(r, 1), m(r, 2), m(r, 3)}));
  j["matrix"] = rows;
  return j;
}

}  // namespace

Phantom makePhantom(const PhantomOptions& opts, const ProgressFn& progress) {
  checkPhantomOptions(opts);
  auto report = [&](double f, const char* stage) {
    if (progress) progress(f, stage);
  };
  const double imageShare = opts.meshes ? 0.45 : 0.95;
  report(0.0, "anatomy");
  const Model model(phantom::drawAnatomy(opts.seed));

  Phantom ph;
  const Grid grid = phantomGrid(opts);
  ph.image = ImageF(grid);
  ph.labels = LabelMap(grid);
  ph.tissues = LabelMap(grid);

  // Labels and tissues at voxel centres; intensities with partial volume (supersampling where a boundary may
  // cross the voxel, judged by the Lipschitz bound of the implicit functions).
  report(0.02, "image");
  phantom::renderTissues([&](const Eigen::Vector3d& p) { return model.classify(p); }, Model::kLipschitz, opts.pose,
                         ph.image, ph.labels, ph.tissues,
                         [&](int k) { report(0.02 + 0.8 * imageShare * (k + 1) / grid.dims[2], "image"); });
  phantom::degradeImage(ph.image, opts.seed, opts.noise, opts.bias);
  report(0.02 + imageShare, "image");

  for (int o = 0; o < kObjectCount; ++o) {
    PhantomObject obj;
    obj.name = kObjects[o].name;
    obj.label = kObjects[o].label;
    obj.kind = kObjects[o].kind;
    // The femur is wrapped by every compartment; each pair of compartments shares a septum (or touches
    // directly where it is missing).
    for (int q = 0; q < kObjectCount; ++q)
      if (q != o) obj.touching.push_back(kObjects[q].name);
    ph.objects.push_back(std::move(obj));
  }

  if (opts.meshes) {
    const double base = 0.02 + imageShare, share = (1.0 - base) / (2 * kObjectCount);
    const std::vector<TriangleMesh> truth = objectMeshes(model, opts.meshSpacingMm, opts.meshVertices,
                                                         [&](int o) { report(base + share * (o + 1), "meshes"); });
    const std::vector<TriangleMesh> templ =
        templateMeshes(opts.meshSpacingMm, opts.meshVertices, opts.remeshMuscleTemplates,
                       [&](int o) { report(base + share * (kObjectCount + o + 1), "templates"); });
    for (int o = 0; o < kObjectCount; ++o) {
      ph.objects[static_cast<size_t>(o)].truth = phantom::posedMesh(truth[static_cast<size_t>(o)], opts.pose);
      ph.objects[static_cast<size_t>(o)].templ = templ[static_cast<size_t>(o)];
    }
  }
  report(1.0, "done");
  return ph;
}

Scene phantomScene(const Phantom& phantom, const std::string& folder) {
  Scene scene;
  scene.path = (std::filesystem::path(folder) / "scene.json").string();
  for (const PhantomObject& o : phantom.objects) {
    SceneObject so;
    so.name = o.name;
    so.label = o.label;
    so.kind = parseObjectKind(o.kind).value_or(ObjectKind::Generic);
    so.model = defaultModel(so.kind);
    so.templatePath = (std::filesystem::path(folder) / ("template_" + o.name + ".vtk")).string();
    so.templ = o.templ;
    scene.objects.push_back(std::move(so));
  }
  for (size_t a = 0; a < phantom.objects.size(); ++a)
    for (size_t b = a + 1; b < phantom.objects.size(); ++b) {
      const auto& t = phantom.objects[a].touching;
      if (std::find(t.begin(), t.end(), phantom.objects[b].name) != t.end())
        scene.collisions.push_back(CollisionPair{static_cast<int>(a), static_cast<int>(b)});
    }
  return scene;
}

void writePhantom(const Phantom& phantom, const PhantomOptions& opts, const std::string& dir) {
  checkPhantomOptions(opts);
  if (phantom.image.data.empty() || phantom.image.data.size() != phantom.image.grid.voxelCount())
    throw Error("writePhantom: the phantom has no image");
  if (!phantom.labels.grid.sameGeometry(phantom.image.grid) || phantom.labels.data.size() != phantom.image.data.size())
    throw Error("writePhantom: labels and image grids differ");
  if (phantom.objects.empty()) throw Error("writePhantom: the phantom has no objects");
  int32_t maxLabel = 0;
  for (const PhantomObject& o : phantom.objects) {
    if (o.truth.vertexCount() == 0 || o.templ.vertexCount() == 0)
      throw Error("writePhantom: object '" + o.name + "' has no meshes (generated with meshes = false?)");
    maxLabel = std::max(maxLabel, o.label);
  }
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) throw IoError(dir, "cannot create folder: " + ec.message());
  const std::string base = (std::filesystem::path(dir) / "").string();

  ImageF stored = phantom.image;
  for (float& v : stored.data) v = std::isfinite(v) ? std::clamp(std::round(v), -32768.f, 32767.f) : 0.f;
  writeNifti(base + "image.nii.gz", stored, DataType::Int16);
  writeNifti(base + "labels.nii.gz", phantom.labels, maxLabel <= 255 ? DataType::UInt8 : DataType::Int16);

  for (const PhantomObject& o : phantom.objects) {
    writeMesh(base + "truth_" + o.name + ".vtk", o.truth, opts.meshSpace);
    writeMesh(base + "template_" + o.name + ".vtk", o.templ, opts.meshSpace);
  }
  auto array3 = [](const Eigen::Vector3d& v) { return Json::array({v[0], v[1], v[2]}); };
  Json params = Json::object();
  params["generator"] = phantom.generator;
  params["version"] = kGeneratorVersion;
  params["mskseg_version"] = MSK_VERSION;
  params["seed"] = opts.seed;
  params["spacing"] = array3(opts.spacing);
  params["oblique"] = array3(opts.obliqueDegrees);
  params["pose"] = phantomPoseJson(opts.pose);
  params["noise"] = opts.noise;
  params["bias"] = opts.bias;
  if (opts.fovZ) params["fovZ"] = Json::array({(*opts.fovZ)[0], (*opts.fovZ)[1]});
  params["meshVertices"] = opts.meshVertices;
  params["muscleTemplatesRemeshed"] = opts.remeshMuscleTemplates;
  params["meshSpace"] = meshSpaceName(opts.meshSpace);
  Scene scene = phantomScene(phantom, dir);
  scene.provenance = params;
  writeScene(scene, base + "scene.json");
}

}  // namespace msk
