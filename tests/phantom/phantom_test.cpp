#include "msk/phantom/phantom.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "msk/core/error.h"
#include "msk/core/simplex_mesh.h"
#include "msk/imaging/filters.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"

namespace {

using msk::test::labelCentroid;
using msk::test::labelDice;

using msk::Phantom;
using msk::PhantomOptions;
using msk::PhantomTissue;

// Coarse, mesh-free phantom options for the image and label tests.
PhantomOptions coarse(uint32_t seed) {
  PhantomOptions o;
  o.seed = seed;
  o.spacing = {2.0, 2.0, 4.0};
  o.meshes = false;
  return o;
}

// Phantoms shared by several tests (generated once per process).
const Phantom& noiseFree() {  // fine enough in-plane to resolve the 1.4 mm septa
  static const std::unique_ptr<Phantom> p = [] {
    PhantomOptions o;
    o.seed = 3;
    o.spacing = {1.4, 1.4, 3.0};
    o.noise = 0;
    o.bias = 0;
    o.meshes = false;
    return std::make_unique<Phantom>(msk::makePhantom(o));
  }();
  return *p;
}

PhantomOptions meshedOptions() {
  PhantomOptions o;
  o.seed = 5;
  o.spacing = {1.5, 1.5, 3.0};
  return o;
}
const Phantom& meshed() {
  static const std::unique_ptr<Phantom> p = std::make_unique<Phantom>(msk::makePhantom(meshedOptions()));
  return *p;
}

PhantomOptions obliqueOptions() {
  PhantomOptions o;
  o.seed = 11;
  o.spacing = {1.0, 1.5, 2.5};
  o.obliqueDegrees = {10, -15, 20};
  o.noise = 0;
  return o;
}
const Phantom& oblique() {
  static const std::unique_ptr<Phantom> p = std::make_unique<Phantom>(msk::makePhantom(obliqueOptions()));
  return *p;
}

size_t countLabel(const msk::LabelMap& m, int32_t label) {
  return static_cast<size_t>(std::count(m.data.begin(), m.data.end(), label));
}

double voxelVolume(const msk::Grid& g) { return g.spacing.prod(); }

// Mean distance from the vertices of `from` to the surface of `to` (brute force with bounding-sphere culling).
double meanVertexToSurface(const msk::TriangleMesh& from, const msk::TriangleMesh& to) {
  std::vector<Eigen::Vector3d> centre(static_cast<size_t>(to.faceCount()));
  std::vector<double> radius(centre.size());
  for (int f = 0; f < to.faceCount(); ++f) {
    const Eigen::Vector3d a = to.vertices.row(to.faces(f, 0)), b = to.vertices.row(to.faces(f, 1)),
                          c = to.vertices.row(to.faces(f, 2));
    centre[static_cast<size_t>(f)] = (a + b + c) / 3;
    radius[static_cast<size_t>(f)] =
        std::max({(a - centre[static_cast<size_t>(f)]).norm(), (b - centre[static_cast<size_t>(f)]).norm(),
                  (c - centre[static_cast<size_t>(f)]).norm()});
  }
  double sum = 0;
  for (int v = 0; v < from.vertexCount(); ++v) {
    const Eigen::Vector3d p = from.vertices.row(v);
    double best = INFINITY;
    for (int f = 0; f < to.faceCount(); ++f) {
      if ((p - centre[static_cast<size_t>(f)]).norm() - radius[static_cast<size_t>(f)] >= best) continue;
      best = std::min(
          best, (p - msk::closestPointOnTriangle(p, to.vertices.row(to.faces(f, 0)), to.vertices.row(to.faces(f, 1)),
                                                 to.vertices.row(to.faces(f, 2))))
                    .norm());
    }
    sum += best;
  }
  return sum / from.vertexCount();
}

void expectMeshesMatchLabels(const Phantom& p, double minDice) {
  ASSERT_EQ(p.objects.size(), 4u);
  for (const msk::PhantomObject& o : p.objects) {
    SCOPED_TRACE(o.name);
    ASSERT_EQ(msk::closedMeshProblem(o.truth), "");
    ASSERT_EQ(msk::closedMeshProblem(o.templ), "");
    EXPECT_GT(msk::enclosedVolume(o.truth), 0);
    EXPECT_NEAR(o.truth.vertexCount(), 3000, 300);
    const msk::LabelMap r = msk::rasterize(o.truth, p.labels.grid);
    const double d = labelDice(r, 1, p.labels, o.label);
    EXPECT_GE(d, minDice);
    const double labelVolume = static_cast<double>(countLabel(p.labels, o.label)) * voxelVolume(p.labels.grid);
    EXPECT_NEAR(msk::enclosedVolume(o.truth), labelVolume, 0.03 * labelVolume);
  }
}

}  // namespace

TEST(Phantom, SameSeedGivesIdenticalImageAndLabels) {
  const Phantom a = msk::makePhantom(coarse(7)), b = msk::makePhantom(coarse(7));
  ASSERT_TRUE(a.image.grid.sameGeometry(b.image.grid, 0));
  EXPECT_TRUE(a.image.data == b.image.data);
  EXPECT_TRUE(a.labels.data == b.labels.data);
  EXPECT_TRUE(a.tissues.data == b.tissues.data);
}

TEST(Phantom, DifferentSeedsGiveDifferentAnatomy) {
  const Phantom a = msk::makePhantom(coarse(7)), b = msk::makePhantom(coarse(8));
  ASSERT_TRUE(a.labels.grid.sameGeometry(b.labels.grid, 0));  // the grid does not depend on the seed
  size_t differ = 0;
  for (size_t n = 0; n < a.labels.data.size(); ++n) differ += a.labels.data[n] != b.labels.data[n];
  EXPECT_GT(differ, a.labels.data.size() / 100);
  const double moved = (labelCentroid(a.labels, 1) - labelCentroid(b.labels, 1)).norm();
  EXPECT_GT(moved, 0.5);
  EXPECT_LT(moved, 15.0);
  EXPECT_FALSE(a.image.data == b.image.data);
}

TEST(Phantom, LabelsGridAndObjects) {
  const PhantomOptions o = coarse(4);
  const Phantom p = msk::makePhantom(o);
  const msk::Grid& g = p.labels.grid;
  EXPECT_EQ(g.problem(), "");
  EXPECT_TRUE(g.sameGeometry(p.image.grid, 0));
  EXPECT_TRUE(g.sameGeometry(p.tissues.grid, 0));
  EXPECT_LT((g.spacing - o.spacing).norm(), 1e-12);
  EXPECT_LT((g.direction - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  // Field of view about 170 mm in-plane and 200 mm along z.
  const auto bounds = g.worldBounds();
  EXPECT_NEAR(bounds[1][0] - bounds[0][0], 170, 4);
  EXPECT_NEAR(bounds[1][2] - bounds[0][2], 200, 6);

  std::set<int32_t> present(p.labels.data.begin(), p.labels.data.end());
  EXPECT_EQ(present, (std::set<int32_t>{0, 1, 2, 3, 4}));
  ASSERT_EQ(p.objects.size(), 4u);
  const std::vector<std::string> names{"femur", "quadriceps", "hamstrings", "adductors"};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(p.objects[i].name, names[i]);
    EXPECT_EQ(p.objects[i].label, static_cast<int32_t>(i + 1));
    EXPECT_EQ(p.objects[i].kind, i == 0 ? "bone" : "muscle");
    EXPECT_EQ(p.objects[i].truth.vertexCount(), 0);  // meshes = false
    EXPECT_EQ(p.objects[i].touching.size(), 3u);
  }
  // Plausible volumes: femur ~ π·13²·160 mm + caps, each muscle compartment tens of cm³.
  const double femur = static_cast<double>(countLabel(p.labels, 1)) * voxelVolume(g);
  EXPECT_GT(femur, 60e3);
  EXPECT_LT(femur, 200e3);
  for (int32_t l = 2; l <= 4; ++l) {
    const double v = static_cast<double>(countLabel(p.labels, l)) * voxelVolume(g);
    EXPECT_GT(v, 40e3) << "label " << l;
    EXPECT_LT(v, 800e3) << "label " << l;
  }
  // The quadriceps is anterior (+y) of the hamstrings; the femur is closed inside the field of view (no label in the
  // end slices), and the limb is inside in-plane (air at the side borders of every slice).
  EXPECT_GT(labelCentroid(p.labels, 2)[1], labelCentroid(p.labels, 3)[1] + 20);
  for (int k : {0, g.dims[2] - 1})
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) ASSERT_EQ(p.labels.at(i, j, k), 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int t = 0; t < g.dims[0]; ++t) {
      ASSERT_EQ(p.tissues.at(t, 0, k), static_cast<int32_t>(PhantomTissue::Air));
      ASSERT_EQ(p.tissues.at(t, g.dims[1] - 1, k), static_cast<int32_t>(PhantomTissue::Air));
      ASSERT_EQ(p.tissues.at(0, t % g.dims[1], k), static_cast<int32_t>(PhantomTissue::Air));
      ASSERT_EQ(p.tissues.at(g.dims[0] - 1, t % g.dims[1], k), static_cast<int32_t>(PhantomTissue::Air));
    }
}

TEST(Phantom, TissueIntensitiesAreT1Weighted) {
  const Phantom& p = noiseFree();
  const msk::Grid& g = p.image.grid;
  // Mean intensity per tissue over voxels whose 6-neighbourhood is the same tissue (little partial volume).
  std::map<int32_t, std::pair<double, size_t>> acc;
  std::pair<double, size_t> muscleLabels{0, 0};
  for (int k = 1; k + 1 < g.dims[2]; ++k)
    for (int j = 1; j + 1 < g.dims[1]; ++j)
      for (int i = 1; i + 1 < g.dims[0]; ++i) {
        const int32_t t = p.tissues.at(i, j, k);
        const float v = p.image.at(i, j, k);
        if (p.labels.at(i, j, k) >= 2) muscleLabels.first += v, ++muscleLabels.second;
        if (p.tissues.at(i - 1, j, k) != t || p.tissues.at(i + 1, j, k) != t || p.tissues.at(i, j - 1, k) != t ||
            p.tissues.at(i, j + 1, k) != t || p.tissues.at(i, j, k - 1) != t || p.tissues.at(i, j, k + 1) != t)
          continue;
        acc[t].first += v;
        ++acc[t].second;
      }
  auto mean = [&](PhantomTissue t) {
    const auto& a = acc[static_cast<int32_t>(t)];
    EXPECT_GT(a.second, 0u) << "tissue " << static_cast<int>(t);
    return a.second ? a.first / static_cast<double>(a.second) : 0.0;
  };
  const double cortex = mean(PhantomTissue::Cortex), marrow = mean(PhantomTissue::Marrow),
               muscle = mean(PhantomTissue::Muscle), fat = mean(PhantomTissue::Fat), air = mean(PhantomTissue::Air);
  EXPECT_LT(cortex, muscle);
  EXPECT_LT(muscle, fat);
  EXPECT_GT(marrow, muscle);
  EXPECT_NEAR(fat, 1000, 30);
  EXPECT_NEAR(muscle, 350, 30);
  EXPECT_NEAR(marrow, 850, 40);
  EXPECT_LT(cortex, 150);
  EXPECT_NEAR(air, 0, 1);
  // Over the label map: muscles (including fat streaks and partial volume) stay far darker than fat.
  ASSERT_GT(muscleLabels.second, 0u);
  const double muscleByLabel = muscleLabels.first / static_cast<double>(muscleLabels.second);
  EXPECT_GT(muscleByLabel, cortex);
  EXPECT_LT(muscleByLabel, 0.6 * fat);
  // Intramuscular fat streaks exist and lie inside muscle labels.
  size_t streak = 0;
  for (size_t n = 0; n < p.tissues.data.size(); ++n)
    if (p.tissues.data[n] == static_cast<int32_t>(PhantomTissue::IntramuscularFat)) {
      ++streak;
      EXPECT_GE(p.labels.data[n], 2);
    }
  EXPECT_GT(streak, 20u);
}

TEST(Phantom, NoiseIsRicianAndBiasIsSmooth) {
  PhantomOptions o = coarse(9);
  o.noise = 0.05;
  o.bias = 0.3;
  const Phantom p = msk::makePhantom(o);
  double air = 0, fatLo = INFINITY, fatHi = -INFINITY;
  size_t nAir = 0;
  const msk::Grid& g = p.image.grid;
  for (size_t n = 0; n < p.image.data.size(); ++n) {
    EXPECT_GE(p.image.data[n], 0.f);  // magnitude image
    if (p.tissues.data[n] == static_cast<int32_t>(PhantomTissue::Air)) air += p.image.data[n], ++nAir;
  }
  // Rician floor of pure noise: σ·sqrt(π/2).
  EXPECT_NEAR(air / static_cast<double>(nAir), 1000 * 0.05 * std::sqrt(M_PI / 2), 5);
  // Fat, averaged over 3×3×3 blocks to suppress noise, varies with the bias field.
  for (int k = 1; k + 1 < g.dims[2]; k += 3)
    for (int j = 1; j + 1 < g.dims[1]; j += 3)
      for (int i = 1; i + 1 < g.dims[0]; i += 3) {
        double s = 0;
        bool allFat = true;
        for (int c = -1; c <= 1 && allFat; ++c)
          for (int b = -1; b <= 1 && allFat; ++b)
            for (int a = -1; a <= 1 && allFat; ++a) {
              allFat = p.tissues.at(i + a, j + b, k + c) == static_cast<int32_t>(PhantomTissue::Fat);
              s += p.image.at(i + a, j + b, k + c);
            }
        if (!allFat) continue;
        fatLo = std::min(fatLo, s / 27);
        fatHi = std::max(fatHi, s / 27);
      }
  EXPECT_GT(fatHi - fatLo, 100);
  EXPECT_LT(fatHi, 1000 * (1 + 0.3) + 60);
  EXPECT_GT(fatLo, 1000 * (1 - 0.3) - 60);
}

TEST(Phantom, SeptaAreMissingOverSomeStretchesOnly) {
  const Phantom& p = noiseFree();
  const msk::Grid& g = p.labels.grid;
  for (auto [a, b] : {std::pair<int32_t, int32_t>{2, 3}, {2, 4}, {3, 4}}) {
    SCOPED_TRACE("labels " + std::to_string(a) + "," + std::to_string(b));
    int touching = 0, separated = 0;
    for (int k = 0; k < g.dims[2]; ++k) {
      bool hasA = false, hasB = false, adjacent = false;
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i) {
          const int32_t l = p.labels.at(i, j, k);
          hasA = hasA || l == a;
          hasB = hasB || l == b;
          if (l != a) continue;
          for (auto [di, dj] : {std::pair<int, int>{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
            if (g.contains(i + di, j + dj, k) && p.labels.at(i + di, j + dj, k) == b) adjacent = true;
        }
      if (!(hasA && hasB)) continue;
      (adjacent ? touching : separated) += 1;
    }
    EXPECT_GE(touching, 3);   // a missing stretch: 20–40 % of ~150 mm at 3 mm slices
    EXPECT_GE(separated, 8);  // a fat septum elsewhere
  }
  // Where a septum is present its voxels are fat and belong to no object.
  size_t septumFat = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 1; j + 1 < g.dims[1]; ++j)
      for (int i = 1; i + 1 < g.dims[0]; ++i)
        if (p.labels.at(i, j, k) == 0 && p.tissues.at(i, j, k) == static_cast<int32_t>(PhantomTissue::Fat) &&
            p.labels.at(i - 1, j, k) >= 2 && p.labels.at(i + 1, j, k) >= 2 &&
            p.labels.at(i - 1, j, k) != p.labels.at(i + 1, j, k))
          ++septumFat;
  EXPECT_GT(septumFat, 50u);
}

TEST(Phantom, TruthMeshesAreClosedAndMatchLabels) { expectMeshesMatchLabels(meshed(), 0.98); }

TEST(Phantom, TruthMeshesMatchLabelsOnObliqueGrid) {
  const Phantom& p = oblique();
  EXPECT_LT((p.labels.grid.direction - msk::Grid::rotationXYZ({10, -15, 20})).norm(), 1e-12);
  expectMeshesMatchLabels(p, 0.98);
}

TEST(Phantom, TemplatesAreSeedIndependentAndCloseToTruth) {
  const Phantom &a = meshed(), &b = oblique();
  for (size_t i = 0; i < a.objects.size(); ++i) {
    SCOPED_TRACE(a.objects[i].name);
    EXPECT_TRUE(a.objects[i].templ.vertices == b.objects[i].templ.vertices);
    EXPECT_TRUE(a.objects[i].templ.faces == b.objects[i].templ.faces);
    const double d = meanVertexToSurface(a.objects[i].truth, a.objects[i].templ);
    EXPECT_GT(d, 0.3);  // the seed moved it
    EXPECT_LT(d, 6.0);  // but it stays a usable initialisation
  }
}

TEST(Phantom, ReportsProgress) {
  std::vector<std::pair<double, std::string>> calls;
  msk::makePhantom(coarse(2), [&](double f, const std::string& s) { calls.emplace_back(f, s); });
  ASSERT_GE(calls.size(), 3u);
  EXPECT_EQ(calls.front().first, 0.0);
  EXPECT_EQ(calls.front().second, "anatomy");
  EXPECT_EQ(calls.back().first, 1.0);
  std::set<std::string> stages;
  for (size_t i = 0; i < calls.size(); ++i) {
    stages.insert(calls[i].second);
    if (i > 0) {
      EXPECT_GE(calls[i].first, calls[i - 1].first);
    }
  }
  EXPECT_TRUE(stages.count("image"));
}

TEST(Phantom, InvalidOptionsThrowAndWriteNothing) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("phantom");
  std::vector<PhantomOptions> bad;
  auto add = [&](auto change) {
    PhantomOptions o = coarse(1);
    change(o);
    bad.push_back(o);
  };
  add([](PhantomOptions& o) { o.spacing[1] = 0; });
  add([](PhantomOptions& o) { o.spacing[2] = 10.5; });
  add([](PhantomOptions& o) { o.spacing[0] = NAN; });
  add([](PhantomOptions& o) { o.noise = -0.01; });
  add([](PhantomOptions& o) { o.noise = 1.5; });
  add([](PhantomOptions& o) { o.bias = 1.0; });
  add([](PhantomOptions& o) { o.bias = -0.1; });
  add([](PhantomOptions& o) { o.obliqueDegrees[2] = INFINITY; });
  add([](PhantomOptions& o) { o.meshVertices = 10; });
  add([](PhantomOptions& o) { o.fovZ = Eigen::Vector2d(20, 10); });
  add([](PhantomOptions& o) { o.fovZ = Eigen::Vector2d(NAN, 10); });
  for (const PhantomOptions& o : bad) {
    EXPECT_THROW(msk::makePhantom(o), msk::ParameterError);
    EXPECT_THROW(msk::writePhantom(meshed(), o, out), msk::ParameterError);
    EXPECT_FALSE(std::filesystem::exists(out));
  }
  // A phantom generated without meshes cannot be written as a scene.
  EXPECT_THROW(msk::writePhantom(msk::makePhantom(coarse(1)), coarse(1), out), msk::Error);
  EXPECT_FALSE(std::filesystem::exists(out));
}

// A short scan: --fov-z keeps the slab of world z it names; the femur and muscles run out of it (cut, as a real
// scan cuts them) with the same labels inside it as the whole phantom's, and posed phantoms are cut in world z too.
// A slab that leaves nothing of the phantom's field of view is refused.
TEST(Phantom, FieldOfViewInZCutsTheAnatomy) {
  PhantomOptions whole = coarse(2), cut = coarse(2);
  cut.fovZ = Eigen::Vector2d(-30, 40);
  const Phantom w = msk::makePhantom(whole), c = msk::makePhantom(cut);
  const msk::Grid& g = c.labels.grid;
  const auto box = g.worldBounds();
  EXPECT_GE(box[0].z(), -30 - g.spacing.z());
  EXPECT_LE(box[1].z(), 40 + g.spacing.z());
  EXPECT_LT(box[1].z() - box[0].z(), 70 + 2 * g.spacing.z());
  // Every object runs through both ends of the slab (cut), and the labels are the whole phantom's there (the grids'
  // lattices differ by a fraction of a voxel: the nearest voxel's label, the same but at a few boundary voxels).
  size_t labelled = 0, differing = 0;
  std::set<int32_t> atBottom, atTop;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const int32_t l = c.labels.at(i, j, k);
        if (k == 0) atBottom.insert(l);
        if (k == g.dims[2] - 1) atTop.insert(l);
        if (l == 0) continue;
        ++labelled;
        differing += msk::sampleNearest(w.labels, g.toWorld(Eigen::Vector3d(i, j, k))).value_or(-1) != l;
      }
  EXPECT_GT(labelled, g.voxelCount() / 10);
  EXPECT_LT(differing, labelled / 20);
  for (int32_t l : {1, 2, 3, 4}) {
    EXPECT_TRUE(atBottom.count(l)) << "label " << l;
    EXPECT_TRUE(atTop.count(l)) << "label " << l;
  }
  PhantomOptions posed = cut;
  posed.pose.rotationDegrees = Eigen::Vector3d(10, 0, 0);
  const auto posedBox = msk::makePhantom(posed).labels.grid.worldBounds();
  EXPECT_GE(posedBox[0].z(), -30 - g.spacing.z());
  EXPECT_LE(posedBox[1].z(), 40 + g.spacing.z());
  PhantomOptions empty = coarse(2);
  empty.fovZ = Eigen::Vector2d(400, 500);
  EXPECT_THROW(msk::makePhantom(empty), msk::ParameterError);
}

TEST(Phantom, WritePhantomWritesImageLabelsMeshesAndScene) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("nested/phantom");
  const Phantom& p = meshed();
  msk::writePhantom(p, meshedOptions(), out);
  const std::vector<std::string> names{"femur", "quadriceps", "hamstrings", "adductors"};
  std::set<std::string> expected{"image.nii.gz", "labels.nii.gz", "scene.json"};
  for (const auto& n : names) expected.insert({"truth_" + n + ".vtk", "template_" + n + ".vtk"});
  std::set<std::string> found;
  for (const auto& e : std::filesystem::directory_iterator(out)) found.insert(e.path().filename().string());
  EXPECT_EQ(found, expected);

  msk::NiftiInfo info;
  const msk::ImageF image = msk::readNifti<float>(out + "/image.nii.gz", &info);
  EXPECT_EQ(info.datatype, msk::DataType::Int16);
  ASSERT_TRUE(image.grid.sameGeometry(p.image.grid, 1e-3));
  for (size_t n = 0; n < image.data.size(); n += 97) EXPECT_NEAR(image.data[n], p.image.data[n], 0.5f);
  const msk::LabelMap labels = msk::readNifti<int32_t>(out + "/labels.nii.gz", &info);
  EXPECT_EQ(info.datatype, msk::DataType::UInt8);
  ASSERT_TRUE(labels.grid.sameGeometry(p.labels.grid, 1e-3));
  EXPECT_TRUE(labels.data == p.labels.data);
  const msk::TriangleMesh t = msk::readMesh(out + "/template_femur.vtk");
  EXPECT_EQ(t.vertexCount(), p.objects[0].templ.vertexCount());
  EXPECT_LT((t.vertices - p.objects[0].templ.vertices).cwiseAbs().maxCoeff(), 1e-3);

  const msk::Json scene = msk::readJsonFile(out + "/scene.json");
  ASSERT_TRUE(scene.is_object());
  const auto& objects = scene.at("objects");
  ASSERT_EQ(objects.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(objects[i].at("name").get<std::string>(), names[i]);
    EXPECT_EQ(objects[i].at("label").get<int>(), static_cast<int>(i + 1));
    EXPECT_EQ(objects[i].at("kind").get<std::string>(), i == 0 ? "bone" : "muscle");
    EXPECT_EQ(objects[i].at("template").get<std::string>(), "template_" + names[i] + ".vtk");
    EXPECT_EQ(objects[i].size(), 4u);  // minimal form
  }
  const auto& collisions = scene.at("collisions");
  EXPECT_EQ(collisions.size(), 6u);
  std::set<std::pair<std::string, std::string>> pairs;
  for (const auto& c : collisions) {
    ASSERT_EQ(c.size(), 2u);
    pairs.insert({c[0].get<std::string>(), c[1].get<std::string>()});
  }
  EXPECT_TRUE(pairs.count({"femur", "quadriceps"}));
  EXPECT_TRUE(pairs.count({"quadriceps", "hamstrings"}));
  const msk::Json& params = scene.at("provenance");
  EXPECT_EQ(params.at("seed").get<int>(), 5);
  EXPECT_EQ(params.at("spacing").size(), 3u);
  EXPECT_DOUBLE_EQ(params.at("spacing")[0].get<double>(), 1.5);
  EXPECT_EQ(params.at("oblique").size(), 3u);
  EXPECT_DOUBLE_EQ(params.at("noise").get<double>(), 0.03);
  EXPECT_DOUBLE_EQ(params.at("bias").get<double>(), 0.15);
  EXPECT_EQ(params.at("generator").get<std::string>(), "mskseg-phantom");
  EXPECT_GE(params.at("version").get<int>(), 1);
  EXPECT_EQ(scene.size(), 3u);
}
