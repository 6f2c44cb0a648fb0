// The 24-structure phantom: four limb segments, each the thigh phantom's limb model (phantom_model.h) with five
// compartments, placed by a rigid map (translation and axis flips); image formation and surface sampling from
// phantom_synthesis.h.
#include "msk/phantom/multi_phantom.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "msk/imaging/surface_extraction.h"
#include "msk/segmentation/surface_quality.h"
#include "phantom_model.h"
#include "phantom_synthesis.h"

namespace msk {

namespace {

using phantom::Anatomy;
using phantom::Model;
using phantom::PointClass;
using phantom::Slice;

constexpr int kSegments = 4;
constexpr int kMusclesPerSegment = 5;
constexpr int kObjectsPerSegment = kMusclesPerSegment + 1;
static_assert(kSegments * kObjectsPerSegment == kMultiPhantomStructures, "4 segments × (bone + 5 muscles)");

// Field of view (RAS mm): both limbs side by side, thighs above the knee plane z = 0, lower legs below.
const Eigen::Vector3d kFovLo(-145, -75, -170), kFovHi(145, 75, 170);
constexpr double kLimbOffsetX = 72;     // mm from the midline to each limb's model origin
constexpr double kSegmentOffsetZ = 84;  // mm from the knee plane to each segment's model origin

struct SegmentInfo {
  const char* side;  // name prefix
  bool thigh;        // thigh (femur) or lower leg (tibia)
  double sx, sz;     // axis flips of the rigid map (±1): left limbs mirror x, lower legs flip z
  double ox, oz;     // model origin in world mm
};
constexpr SegmentInfo kSegmentInfo[kSegments] = {
    {"r_", true, 1, 1, kLimbOffsetX, kSegmentOffsetZ},
    {"l_", true, -1, 1, -kLimbOffsetX, kSegmentOffsetZ},
    {"r_", false, 1, -1, kLimbOffsetX, -kSegmentOffsetZ},
    {"l_", false, -1, -1, -kLimbOffsetX, -kSegmentOffsetZ},
};
// Compartments counter-clockwise from lateral (model +x) through anterior (+y); compartment m spans septa m → m+1.
constexpr const char* kThighNames[kObjectsPerSegment] = {"femur",           "vastus_lateralis", "vastus_intermedius",
                                                         "vastus_medialis", "adductors",        "hamstrings"};
constexpr const char* kLegNames[kObjectsPerSegment] = {"tibia",   "peroneus", "tibialis_anterior",
                                                       "flexors", "soleus",   "gastrocnemius"};

void ringCompartments(Anatomy& a, const std::array<double, kMusclesPerSegment>& septumDeg) {
  a.muscles = kMusclesPerSegment;
  for (int m = 0; m < kMusclesPerSegment; ++m) {
    const size_t i = static_cast<size_t>(m);
    a.septumAngleDeg[i] = septumDeg[i];
    a.muscleFirstSeptum[i] = m;
    a.muscleLastSeptum[i] = (m + 1) % kMusclesPerSegment;
  }
}

// Mean thigh with five compartments, a little shorter and slimmer than the thigh phantom's.
Anatomy meanThigh() {
  Anatomy a;
  a.bowHalfLength = 80;
  a.femurBottom = -60;
  a.femurTop = 62;
  a.flareLength = 35;
  a.envelopeHalfLength = 62;
  a.envelopeRadiusX = 42;
  a.envelopeRadiusY = 38;
  ringCompartments(a, {-40, 40, 110, 170, 250});
  return a;
}

// Mean lower leg in model coordinates (the rigid map flips z, so the model's distal flare becomes the tibial
// plateau and a negative taper makes the calf wider proximally).
Anatomy meanLeg() {
  Anatomy a;
  a.femurBase = Eigen::Vector2d(3, 6);
  a.femurTilt = Eigen::Vector2d(0.02, 0.0);
  a.femurBow = Eigen::Vector2d(0.0, 1.0);
  a.bowHalfLength = 80;
  a.femurBottom = -60;
  a.femurTop = 62;
  a.shaftRadius = 10.5;
  a.flare = 6.0;
  a.flareLength = 35;
  a.marrowRatio = 0.5;
  a.marrowRatioFlare = 0.7;
  a.envelopeOffset = Eigen::Vector2d(-3, -8);
  a.envelopeHalfLength = 62;
  a.envelopeRadiusX = 36;
  a.envelopeRadiusY = 34;
  a.envelopeTaper = -0.15;
  ringCompartments(a, {-40, 40, 120, 190, 260});
  return a;
}

// One placed limb segment: world p ↦ model q = (sx (px − ox), py, sz (pz − oz)), an isometry.
struct Segment {
  Model model;
  SegmentInfo info;
  Segment(const Anatomy& a, const SegmentInfo& i) : model(a), info(i) {}
  Eigen::Vector3d toModel(const Eigen::Vector3d& p) const {
    return Eigen::Vector3d(info.sx * (p[0] - info.ox), p[1], info.sz * (p[2] - info.oz));
  }
  double modelZ(double worldZ) const { return info.sz * (worldZ - info.oz); }
  // World bounding box of object o (0 bone, 1..5 muscles).
  std::array<Eigen::Vector3d, 2> worldBounds(int o) const {
    const auto box = model.objectBounds(o);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
    for (const Eigen::Vector3d& q : box) {
      const Eigen::Vector3d p(info.ox + info.sx * q[0], q[1], info.oz + info.sz * q[2]);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    return {lo, hi};
  }
};

std::vector<Segment> placeSegments(const std::array<Anatomy, kSegments>& anatomies) {
  std::vector<Segment> s;
  for (int i = 0; i < kSegments; ++i) s.emplace_back(anatomies[static_cast<size_t>(i)], kSegmentInfo[i]);
  return s;
}

// Which segment holds p: side by the sign of x, thigh or leg by the sign of z.
int segmentAt(const Eigen::Vector3d& p) { return (p[0] < 0 ? 1 : 0) + (p[2] < 0 ? 2 : 0); }

PointClass classify(const std::vector<Segment>& segments, const Eigen::Vector3d& p) {
  const int s = segmentAt(p);
  PointClass c = segments[static_cast<size_t>(s)].model.classify(segments[static_cast<size_t>(s)].toModel(p));
  if (c.label > 0) c.label += kObjectsPerSegment * s;
  // Across the partition planes the classifier changes: voxels near them are supersampled too.
  c.bound = std::min({c.bound, std::fabs(p[0]), std::fabs(p[2])});
  return c;
}

// Meshes of the 24 objects (segment order, bone first).
std::vector<TriangleMesh> objectMeshes(const std::vector<Segment>& segments, double h, int vertices,
                                       const std::function<void(int)>& objectDone) {
  std::vector<TriangleMesh> meshes;
  IsosurfaceOptions iso;
  iso.inside = IsoInside::Below;
  iso.largestComponentOnly = true;
  for (int s = 0; s < kSegments; ++s) {
    const Segment& seg = segments[static_cast<size_t>(s)];
    for (int o = 0; o < kObjectsPerSegment; ++o) {
      const Grid g = phantom::implicitSamplingGrid(seg.worldBounds(o), h);
      std::vector<Slice> slices(static_cast<size_t>(g.dims[2]));
      for (int k = 0; k < g.dims[2]; ++k)
        slices[static_cast<size_t>(k)] = seg.model.slice(seg.modelZ(g.origin[2] + k * h));
      const ImageF field = phantom::sampleImplicit(g, Model::kLipschitz, [&](int i, int j, int k) {
        const Eigen::Vector3d q = seg.toModel(g.origin + h * Eigen::Vector3d(i, j, k));
        return static_cast<float>(seg.model.object(o, slices[static_cast<size_t>(k)], q));
      });
      meshes.push_back(decimateMesh(isosurface(field, 0.0, iso), vertices));
      if (objectDone) objectDone(kObjectsPerSegment * s + o);
    }
  }
  return meshes;
}

std::array<Anatomy, kSegments> meanAnatomies() {
  const Anatomy thigh = meanThigh(), leg = meanLeg();
  return {thigh, thigh, leg, leg};
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
    std::vector<TriangleMesh> meshes = objectMeshes(placeSegments(meanAnatomies()), h, vertices, objectDone);
    // The muscles' templates are written remeshed, as segment would remesh them (each segment's bone, its first
    // object, keeps its triangulation), so that segment uses them as they are.
    for (size_t i = 0; i < meshes.size() && remeshMuscles; ++i)
      if (i % kObjectsPerSegment != 0) meshes[i] = remeshIsotropic(meshes[i], meshes[i].vertexCount());
    it = cache.emplace(key, std::move(meshes)).first;
  }
  return it->second;
}

}  // namespace

Phantom makeMultiPhantom(const PhantomOptions& opts, const ProgressFn& progress) {
  checkPhantomOptions(opts);
  auto report = [&](double f, const char* stage) {
    if (progress) progress(f, stage);
  };
  report(0.0, "anatomy");
  // Each segment draws its own anatomy from an independent stream of the seed.
  std::array<Anatomy, kSegments> anatomies = meanAnatomies();
  for (int s = 0; s < kSegments; ++s) {
    phantom::Random rng(phantom::streamSeed(opts.seed, 16 + static_cast<uint32_t>(s)));
    phantom::perturbAnatomy(anatomies[static_cast<size_t>(s)], rng);
  }
  const std::vector<Segment> segments = placeSegments(anatomies);

  Phantom ph;
  ph.generator = "mskseg-multi-phantom";
  const Grid grid = phantom::coveringGrid(opts.spacing, opts.obliqueDegrees, kFovLo, kFovHi, opts.pose, opts.fovZ);
  ph.image = ImageF(grid);
  ph.labels = LabelMap(grid);
  ph.tissues = LabelMap(grid);
  const double imageShare = opts.meshes ? 0.3 : 0.95;
  report(0.02, "image");
  phantom::renderTissues([&](const Eigen::Vector3d& p) { return classify(segments, p); }, Model::kLipschitz, opts.pose,
                         ph.image, ph.labels, ph.tissues,
                         [&](int k) { report(0.02 + 0.8 * imageShare * (k + 1) / grid.dims[2], "image"); });
  phantom::degradeImage(ph.image, opts.seed, opts.noise, opts.bias);
  report(0.02 + imageShare, "image");

  for (int s = 0; s < kSegments; ++s) {
    const SegmentInfo& info = kSegmentInfo[s];
    const char* const* names = info.thigh ? kThighNames : kLegNames;
    auto name = [&](int o) { return std::string(info.side) + names[o]; };
    for (int o = 0; o < kObjectsPerSegment; ++o) {
      PhantomObject obj;
      obj.name = name(o);
      obj.label = kObjectsPerSegment * s + o + 1;
      obj.kind = o == 0 ? "bone" : "muscle";
      // The bone touches every compartment; a compartment touches the bone and its two neighbours in the ring.
      if (o == 0) {
        for (int m = 1; m < kObjectsPerSegment; ++m) obj.touching.push_back(name(m));
      } else {
        obj.touching.push_back(name(0));
        obj.touching.push_back(name(1 + (o - 2 + kMusclesPerSegment) % kMusclesPerSegment));
        obj.touching.push_back(name(1 + o % kMusclesPerSegment));
      }
      ph.objects.push_back(std::move(obj));
    }
  }

  if (opts.meshes) {
    const double base = 0.02 + imageShare, share = (1.0 - base) / (2 * kMultiPhantomStructures);
    const std::vector<TriangleMesh> truth = objectMeshes(segments, opts.meshSpacingMm, opts.meshVertices,
                                                         [&](int o) { report(base + share * (o + 1), "meshes"); });
    const std::vector<TriangleMesh> templ =
        templateMeshes(opts.meshSpacingMm, opts.meshVertices, opts.remeshMuscleTemplates,
                       [&](int o) { report(base + share * (kMultiPhantomStructures + o + 1), "templates"); });
    for (size_t o = 0; o < ph.objects.size(); ++o) {
      ph.objects[o].truth = phantom::posedMesh(truth[o], opts.pose);
      ph.objects[o].templ = templ[o];
    }
  }
  report(1.0, "done");
  return ph;
}

}  // namespace msk
