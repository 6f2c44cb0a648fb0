// Synthetic T1-weighted thigh phantom: anatomy from phantom_model.h, image formation, meshes and files here.
#include "msk/segmentation/phantom.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <utility>

#include "msk/core/error.h"
#include "msk/core/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/surface_extraction.h"
#include "phantom_model.h"

namespace msk {

namespace {

using phantom::Model;
using phantom::Random;
using phantom::Slice;

constexpr const char* kGenerator = "mskseg-phantom";
constexpr int kGeneratorVersion = 1;
constexpr double kFovHalfXY = 85;  // mm: world box [-85, 85]² × [-100, 100] holds the limb for every seed
constexpr double kFovHalfZ = 100;
constexpr double kScale = 1000;  // stored intensity of fat

// T1-weighted intensities of the PhantomTissue classes, fat = 1.
constexpr double kIntensity[] = {0.0, 0.45, 1.0, 0.35, 0.08, 0.85, 0.7};

struct ObjectInfo {
  const char* name;
  int32_t label;
  const char* kind;
};
constexpr ObjectInfo kObjects[] = {
    {"femur", 1, "bone"}, {"quadriceps", 2, "muscle"}, {"hamstrings", 3, "muscle"}, {"adductors", 4, "muscle"}};
constexpr int kObjectCount = 4;

std::string num(double v) { return std::to_string(v); }
std::string vec(const Eigen::Vector3d& v) { return num(v[0]) + "," + num(v[1]) + "," + num(v[2]); }

void validate(const PhantomOptions& o) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(o.spacing[a]) || o.spacing[a] <= 0 || o.spacing[a] > 10)
      throw ParameterError("spacing", vec(o.spacing), "each voxel size must be in (0, 10] mm");
  if (!o.obliqueDegrees.allFinite()) throw ParameterError("oblique", vec(o.obliqueDegrees), "angles must be finite");
  if (!std::isfinite(o.noise) || o.noise < 0 || o.noise > 1)
    throw ParameterError("noise", num(o.noise), "must be in [0, 1] (fraction of fat intensity)");
  if (!std::isfinite(o.bias) || o.bias < 0 || o.bias >= 1)
    throw ParameterError("bias", num(o.bias), "must be in [0, 1)");
  if (o.meshVertices < 100 || o.meshVertices > 1000000)
    throw ParameterError("meshVertices", std::to_string(o.meshVertices), "must be in [100, 1000000]");
  if (!std::isfinite(o.meshSpacingMm) || o.meshSpacingMm < 0.2 || o.meshSpacingMm > 3)
    throw ParameterError("meshSpacingMm", num(o.meshSpacingMm), "must be in [0.2, 3] mm");
}

uint32_t streamSeed(uint32_t seed, uint32_t stream) {
  // splitmix-like mixing so that neighbouring seeds give unrelated streams
  uint64_t z = (static_cast<uint64_t>(seed) << 32 | stream) + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return static_cast<uint32_t>((z ^ (z >> 31)) & 0xffffffffu);
}

// The image grid: given spacing and rotation, covering the fixed world box (centred on it).
Grid phantomGrid(const PhantomOptions& o) {
  Grid g;
  g.spacing = o.spacing;
  g.direction = Grid::rotationXYZ(o.obliqueDegrees);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? kFovHalfXY : -kFovHalfXY, (c & 2) ? kFovHalfXY : -kFovHalfXY,
                                 (c & 4) ? kFovHalfZ : -kFovHalfZ);
    const Eigen::Vector3d v = g.direction.transpose() * corner;
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  for (int a = 0; a < 3; ++a) {
    g.dims[a] = static_cast<int>(std::ceil((hi[a] - lo[a]) / g.spacing[a] - 1e-9)) + 1;
    lo[a] -= 0.5 * ((g.dims[a] - 1) * g.spacing[a] - (hi[a] - lo[a]));
  }
  g.origin = g.direction * lo;
  return g;
}

// Separable Gaussian blur with sigma = `sigmaVoxels` along each grid axis (replicated borders).
void blurVoxels(ImageF& img, double sigmaVoxels) {
  const int r = static_cast<int>(std::ceil(3 * sigmaVoxels));
  std::vector<double> w(static_cast<size_t>(2 * r + 1));
  double sum = 0;
  for (int d = -r; d <= r; ++d)
    sum += w[static_cast<size_t>(d + r)] = std::exp(-0.5 * d * d / (sigmaVoxels * sigmaVoxels));
  for (double& x : w) x /= sum;
  const Eigen::Vector3i n = img.grid.dims;
  std::vector<float> line;
  for (int axis = 0; axis < 3; ++axis) {
    const int len = n[axis];
    line.resize(static_cast<size_t>(len));
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    for (int v = 0; v < n[a2]; ++v)
      for (int u = 0; u < n[a1]; ++u) {
        Eigen::Vector3i ijk;
        ijk[a1] = u;
        ijk[a2] = v;
        for (int t = 0; t < len; ++t) {
          ijk[axis] = t;
          line[static_cast<size_t>(t)] = img.at(ijk[0], ijk[1], ijk[2]);
        }
        for (int t = 0; t < len; ++t) {
          double s = 0;
          for (int d = -r; d <= r; ++d)
            s += w[static_cast<size_t>(d + r)] * line[static_cast<size_t>(std::clamp(t + d, 0, len - 1))];
          ijk[axis] = t;
          img.at(ijk[0], ijk[1], ijk[2]) = static_cast<float>(s);
        }
      }
  }
}

// Smooth multiplicative bias: 1 + amplitude · B(p), B a sum of three long-wavelength plane waves, |B| ≤ 1.
struct BiasField {
  std::array<Eigen::Vector3d, 3> k;
  std::array<double, 3> phase{}, weight{0.5, 0.3, 0.2};
  explicit BiasField(uint32_t seed) {
    Random rng(seed);
    for (size_t j = 0; j < 3; ++j) {
      Eigen::Vector3d d(rng.normal(), rng.normal(), rng.normal());
      if (d.norm() < 1e-6) d = Eigen::Vector3d::UnitX();
      k[j] = d.normalized() * (2 * M_PI / rng.uniform(250, 450));
      phase[j] = rng.uniform(0, 2 * M_PI);
    }
  }
  double operator()(const Eigen::Vector3d& p) const {
    double b = 0;
    for (size_t j = 0; j < 3; ++j) b += weight[j] * std::sin(k[j].dot(p) + phase[j]);
    return b;
  }
};

// Samples object `object` of `model` on an axis-aligned grid of step h around its bounding box. Far from the
// surface (checked on a 4× coarser lattice with the Lipschitz bound) values are interpolated, not evaluated:
// only their sign matters to marching cubes, and it is exact there.
ImageF sampleObject(const Model& model, int object, double h) {
  constexpr int S = 4;
  auto box = model.objectBounds(object);
  Grid g;
  g.spacing = Eigen::Vector3d::Constant(h);
  Eigen::Vector3i cells;
  for (int a = 0; a < 3; ++a) {
    const double lo = box[0][a] - 3 * h, hi = box[1][a] + 3 * h;
    cells[a] = static_cast<int>(std::ceil((hi - lo) / (S * h)));
    g.dims[a] = S * cells[a] + 1;
    g.origin[a] = 0.5 * (lo + hi) - 0.5 * (g.dims[a] - 1) * h;
  }
  ImageF f(g);
  std::vector<Slice> slices(static_cast<size_t>(g.dims[2]));
  for (int k = 0; k < g.dims[2]; ++k) slices[static_cast<size_t>(k)] = model.slice(g.origin[2] + k * h);
  auto eval = [&](int i, int j, int k) {
    return static_cast<float>(
        model.object(object, slices[static_cast<size_t>(k)], g.origin + h * Eigen::Vector3d(i, j, k)));
  };
  // Coarse lattice.
  const Eigen::Vector3i cn = cells + Eigen::Vector3i::Ones();
  std::vector<float> coarse(static_cast<size_t>(cn[0]) * cn[1] * cn[2]);
  auto cidx = [&](int i, int j, int k) {
    return static_cast<size_t>(i) + static_cast<size_t>(cn[0]) * (j + static_cast<size_t>(cn[1]) * k);
  };
  for (int k = 0; k < cn[2]; ++k)
    for (int j = 0; j < cn[1]; ++j)
      for (int i = 0; i < cn[0]; ++i) coarse[cidx(i, j, k)] = eval(S * i, S * j, S * k);
  // Interpolate everywhere (sign-correct in cells far from the surface) ...
  for (int k = 0; k < g.dims[2]; ++k) {
    const int ck = std::min(k / S, cells[2] - 1);
    const double tk = (k - S * ck) / static_cast<double>(S);
    for (int j = 0; j < g.dims[1]; ++j) {
      const int cj = std::min(j / S, cells[1] - 1);
      const double tj = (j - S * cj) / static_cast<double>(S);
      for (int i = 0; i < g.dims[0]; ++i) {
        const int ci = std::min(i / S, cells[0] - 1);
        const double ti = (i - S * ci) / static_cast<double>(S);
        double v = 0;
        for (int c = 0; c < 8; ++c) {
          const double wt = ((c & 1) ? ti : 1 - ti) * ((c & 2) ? tj : 1 - tj) * ((c & 4) ? tk : 1 - tk);
          if (wt != 0) v += wt * coarse[cidx(ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1))];
        }
        f.at(i, j, k) = static_cast<float>(v);
      }
    }
  }
  // ... then evaluate exactly in the cells that may hold surface.
  const double threshold = Model::kLipschitz * 0.5 * std::sqrt(3.0) * S * h;
  std::vector<uint8_t> done(g.voxelCount(), 0);
  for (int ck = 0; ck < cells[2]; ++ck)
    for (int cj = 0; cj < cells[1]; ++cj)
      for (int ci = 0; ci < cells[0]; ++ci) {
        bool pos = false, neg = false;
        double minAbs = INFINITY;
        for (int c = 0; c < 8; ++c) {
          const float v = coarse[cidx(ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1))];
          (v < 0 ? neg : pos) = true;
          minAbs = std::min(minAbs, std::fabs(static_cast<double>(v)));
        }
        if (!(pos && neg) && minAbs > threshold) continue;
        for (int k = S * ck; k <= S * ck + S; ++k)
          for (int j = S * cj; j <= S * cj + S; ++j)
            for (int i = S * ci; i <= S * ci + S; ++i) {
              const size_t n = g.index(i, j, k);
              if (done[n]) continue;
              done[n] = 1;
              f.data[n] = eval(i, j, k);
            }
      }
  return f;
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
std::vector<TriangleMesh> templateMeshes(double h, int vertices, const std::function<void(int)>& objectDone) {
  static std::mutex mutex;
  static std::map<std::pair<double, int>, std::vector<TriangleMesh>> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find({h, vertices});
  if (it == cache.end()) {
    const Model mean{phantom::Anatomy{}};
    it = cache.emplace(std::make_pair(h, vertices), objectMeshes(mean, h, vertices, objectDone)).first;
  }
  return it->second;
}

}  // namespace

Phantom makePhantom(const PhantomOptions& opts, const ProgressFn& progress) {
  validate(opts);
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
  const Eigen::Matrix3d step = grid.direction * grid.spacing.asDiagonal();
  const double halfDiagonal = 0.5 * grid.spacing.norm();
  Eigen::Vector3i sub;
  for (int a = 0; a < 3; ++a) sub[a] = std::clamp(static_cast<int>(std::ceil(grid.spacing[a] / 0.6)), 2, 5);
  std::vector<Eigen::Vector3d> offsets;
  for (int c = 0; c < sub[2]; ++c)
    for (int b = 0; b < sub[1]; ++b)
      for (int a = 0; a < sub[0]; ++a)
        offsets.push_back(
            step * Eigen::Vector3d((a + 0.5) / sub[0] - 0.5, (b + 0.5) / sub[1] - 0.5, (c + 0.5) / sub[2] - 0.5));
  for (int k = 0; k < grid.dims[2]; ++k) {
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        const Eigen::Vector3d p = grid.toWorld(Eigen::Vector3d(i, j, k));
        const phantom::PointClass c = model.classify(p);
        const size_t n = grid.index(i, j, k);
        ph.labels.data[n] = c.label;
        ph.tissues.data[n] = c.tissue;
        double v = kIntensity[c.tissue];
        if (c.bound < Model::kLipschitz * halfDiagonal) {
          v = 0;
          for (const Eigen::Vector3d& d : offsets) v += kIntensity[model.classify(p + d).tissue];
          v /= static_cast<double>(offsets.size());
        }
        ph.image.data[n] = static_cast<float>(v);
      }
    if ((k & 7) == 7) report(0.02 + 0.8 * imageShare * (k + 1) / grid.dims[2], "image");
  }
  blurVoxels(ph.image, 0.5);
  const BiasField bias(streamSeed(opts.seed, 2));
  Random noise(streamSeed(opts.seed, 3));
  const double sigma = opts.noise;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        const size_t n = grid.index(i, j, k);
        double v = ph.image.data[n];
        if (opts.bias > 0) v *= 1.0 + opts.bias * bias(grid.toWorld(Eigen::Vector3d(i, j, k)));
        if (sigma > 0) {
          const double n1 = sigma * noise.normal(), n2 = sigma * noise.normal();
          v = std::sqrt((v + n1) * (v + n1) + n2 * n2);
        }
        ph.image.data[n] = static_cast<float>(kScale * v);
      }
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
    const std::vector<TriangleMesh> templ = templateMeshes(opts.meshSpacingMm, opts.meshVertices, [&](int o) {
      report(base + share * (kObjectCount + o + 1), "templates");
    });
    for (int o = 0; o < kObjectCount; ++o) {
      ph.objects[static_cast<size_t>(o)].truth = truth[static_cast<size_t>(o)];
      ph.objects[static_cast<size_t>(o)].templ = templ[static_cast<size_t>(o)];
    }
  }
  report(1.0, "done");
  return ph;
}

void writePhantom(const Phantom& phantom, const PhantomOptions& opts, const std::string& dir) {
  validate(opts);
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

  Json objects = Json::array();
  for (const PhantomObject& o : phantom.objects) {
    writeMesh(base + "truth_" + o.name + ".vtk", o.truth, opts.meshSpace);
    writeMesh(base + "template_" + o.name + ".vtk", o.templ, opts.meshSpace);
    Json j = Json::object();
    j["name"] = o.name;
    j["label"] = static_cast<int>(o.label);
    j["kind"] = o.kind;
    j["template"] = "template_" + o.name + ".vtk";
    objects.push(std::move(j));
  }
  Json collisions = Json::array();
  for (size_t a = 0; a < phantom.objects.size(); ++a)
    for (size_t b = a + 1; b < phantom.objects.size(); ++b) {
      const auto& t = phantom.objects[a].touching;
      if (std::find(t.begin(), t.end(), phantom.objects[b].name) != t.end())
        collisions.push(Json(Json::Array{phantom.objects[a].name, phantom.objects[b].name}));
    }
  auto array3 = [](const Eigen::Vector3d& v) { return Json(Json::Array{v[0], v[1], v[2]}); };
  Json params = Json::object();
  params["seed"] = static_cast<unsigned long>(opts.seed);
  params["spacing"] = array3(opts.spacing);
  params["oblique"] = array3(opts.obliqueDegrees);
  params["noise"] = opts.noise;
  params["bias"] = opts.bias;
  params["meshVertices"] = opts.meshVertices;
  params["meshSpace"] = meshSpaceName(opts.meshSpace);
  params["mskseg_version"] = MSK_VERSION;
  params["generator"] = kGenerator;
  params["version"] = kGeneratorVersion;
  Json scene = Json::object();
  scene["objects"] = std::move(objects);
  scene["collisions"] = std::move(collisions);
  scene["phantom"] = std::move(params);
  scene.writeFile(base + "scene.json");
}

}  // namespace msk
