// The 24-structure phantom (both thighs and lower legs): objects, labels, touching pairs, meshes, determinism.
#include "msk/phantom/multi_phantom.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>

#include "msk/core/error.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/rasterize.h"
#include "msk/test/volumes.h"

namespace {

using msk::Phantom;
using msk::PhantomOptions;
using msk::test::labelDice;

PhantomOptions coarse(uint32_t seed) {
  PhantomOptions o;
  o.seed = seed;
  o.spacing = Eigen::Vector3d(2.4, 2.4, 4.0);
  o.meshes = false;
  return o;
}

// Meshed once for the file (coarse meshes to stay fast).
const Phantom& meshed() {
  static const std::unique_ptr<Phantom> p = [] {
    PhantomOptions o = coarse(3);
    o.spacing = Eigen::Vector3d(2.0, 2.0, 3.0);
    o.meshes = true;
    o.meshSpacingMm = 1.2;
    o.meshVertices = 1000;
    return std::make_unique<Phantom>(msk::makeMultiPhantom(o));
  }();
  return *p;
}

// Unordered label pairs that are 6-adjacent somewhere in the label map (labels > 0 only).
std::set<std::pair<int, int>> adjacentLabels(const msk::LabelMap& l) {
  std::set<std::pair<int, int>> s;
  const Eigen::Vector3i d = l.grid.dims;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i) {
        const int a = l.at(i, j, k);
        if (a == 0) continue;
        const int nb[3] = {i + 1 < d[0] ? l.at(i + 1, j, k) : 0, j + 1 < d[1] ? l.at(i, j + 1, k) : 0,
                           k + 1 < d[2] ? l.at(i, j, k + 1) : 0};
        for (int b : nb)
          if (b != 0 && b != a) s.insert({std::min(a, b), std::max(a, b)});
      }
  return s;
}

}  // namespace

TEST(MultiPhantom, FourBonesTwentyMusclesWithTheirLabels) {
  const Phantom p = msk::makeMultiPhantom(coarse(1));
  ASSERT_EQ(p.objects.size(), static_cast<size_t>(msk::kMultiPhantomStructures));
  EXPECT_EQ(p.generator, "mskseg-multi-phantom");
  int bones = 0, muscles = 0;
  std::set<std::string> names;
  std::map<int, size_t> voxels;
  for (int32_t v : p.labels.data) ++voxels[v];
  for (size_t i = 0; i < p.objects.size(); ++i) {
    const msk::PhantomObject& o = p.objects[i];
    SCOPED_TRACE(o.name);
    EXPECT_EQ(o.label, static_cast<int>(i) + 1);
    names.insert(o.name);
    (o.kind == "bone" ? bones : muscles) += 1;
    EXPECT_TRUE(o.kind == "bone" || o.kind == "muscle");
    EXPECT_GT(voxels[o.label], 1000u);    // every structure is present in the label map
    EXPECT_EQ(o.truth.vertexCount(), 0);  // meshes = false
  }
  EXPECT_EQ(bones, 4);
  EXPECT_EQ(muscles, 20);
  EXPECT_EQ(names.size(), 24u);
  EXPECT_EQ(voxels.size(), 25u);  // background + 24 labels, nothing else
  EXPECT_TRUE(names.count("r_femur") && names.count("l_femur") && names.count("r_tibia") && names.count("l_tibia"));
  EXPECT_TRUE(p.image.grid.sameGeometry(p.labels.grid, 0));
  EXPECT_TRUE(p.tissues.grid.sameGeometry(p.labels.grid, 0));
}

TEST(MultiPhantom, TouchingPairsAreDeclaredBothWaysAndMatchTheLabels) {
  const Phantom p = msk::makeMultiPhantom(coarse(2));
  std::map<std::string, int> label;
  for (const msk::PhantomObject& o : p.objects) label[o.name] = o.label;
  std::set<std::pair<int, int>> declared;
  for (const msk::PhantomObject& o : p.objects) {
    SCOPED_TRACE(o.name);
    EXPECT_EQ(o.touching.size(), o.kind == "bone" ? 5u : 3u);  // bone: its 5 muscles; muscle: bone + 2 neighbours
    for (const std::string& t : o.touching) {
      ASSERT_TRUE(label.count(t)) << t;
      const auto& back = p.objects[static_cast<size_t>(label[t] - 1)].touching;
      EXPECT_NE(std::find(back.begin(), back.end(), o.name), back.end()) << t << " does not touch back";
      declared.insert({std::min(o.label, label[t]), std::max(o.label, label[t])});
    }
  }
  EXPECT_EQ(declared.size(), 40u);  // 4 segments × (5 bone–muscle + 5 muscle–muscle)
  // Structures that meet in the label map are declared pairs, and muscle neighbours do meet (septa are thin and
  // missing over a stretch). Bones and muscles stay 1 mm apart (periosteal fat), so they need not meet on this grid.
  const std::set<std::pair<int, int>> adjacent = adjacentLabels(p.labels);
  for (const auto& pr : adjacent) EXPECT_TRUE(declared.count(pr)) << pr.first << "|" << pr.second << " undeclared";
  for (const auto& pr : declared) {
    const bool boneInvolved = (pr.first - 1) % 6 == 0;
    if (!boneInvolved) {
      EXPECT_TRUE(adjacent.count(pr)) << pr.first << "|" << pr.second << " never meet";
    }
  }
}

TEST(MultiPhantom, SameSeedSameOutputOtherSeedOtherAnatomy) {
  const Phantom a = msk::makeMultiPhantom(coarse(5)), b = msk::makeMultiPhantom(coarse(5)),
                c = msk::makeMultiPhantom(coarse(6));
  EXPECT_TRUE(a.image.data == b.image.data);
  EXPECT_TRUE(a.labels.data == b.labels.data);
  EXPECT_FALSE(a.labels.data == c.labels.data);
  for (int l = 1; l <= 24; ++l) EXPECT_LT(labelDice(a.labels, l, c.labels, l), 0.995) << "label " << l;
}

TEST(MultiPhantom, TruthMeshesMatchLabelsAndStayInTheirSegment) {
  const Phantom& p = meshed();
  for (const msk::PhantomObject& o : p.objects) {
    SCOPED_TRACE(o.name);
    ASSERT_EQ(msk::closedMeshProblem(o.truth), "");
    ASSERT_EQ(msk::closedMeshProblem(o.templ), "");
    EXPECT_GT(msk::enclosedVolume(o.truth), 0);
    const msk::LabelMap r = msk::rasterize(o.truth, p.labels.grid);
    EXPECT_GE(labelDice(r, 1, p.labels, o.label), 0.93);  // coarse grid: partial voxels weigh more
    // Right limbs at x > 0, left at x < 0; thighs above the knee plane z = 0, lower legs below.
    const bool right = o.name.rfind("r_", 0) == 0;
    const bool thigh = o.label <= 12;
    for (int v = 0; v < o.truth.vertexCount(); ++v) {
      const Eigen::Vector3d x = o.truth.vertices.row(v).transpose();
      ASSERT_GT(right ? x[0] : -x[0], 0.0);
      ASSERT_GT(thigh ? x[2] : -x[2], 0.0);
    }
  }
}

TEST(MultiPhantom, TemplatesAreMeanAnatomyDisplacedFromTruth) {
  const Phantom& p = meshed();
  PhantomOptions o = coarse(4);
  o.spacing = Eigen::Vector3d(8, 8, 8);  // only its meshes are used
  o.meshes = true;
  o.meshSpacingMm = 1.2;
  o.meshVertices = 1000;
  const Phantom q = msk::makeMultiPhantom(o);
  for (size_t i = 0; i < p.objects.size(); ++i) {
    SCOPED_TRACE(p.objects[i].name);
    EXPECT_TRUE(p.objects[i].templ.vertices == q.objects[i].templ.vertices);  // seed-independent
    EXPECT_FALSE(p.objects[i].truth.vertices == q.objects[i].truth.vertices);
    const msk::LabelMap t = msk::rasterize(p.objects[i].templ, p.labels.grid);
    const double d = labelDice(t, 1, p.labels, p.objects[i].label);
    EXPECT_LT(d, 0.985);  // the seed moved the truth away from the mean
    EXPECT_GT(d, 0.5);    // but the template stays a usable initialisation
  }
}

TEST(MultiPhantom, InvalidOptionsThrow) {
  PhantomOptions o = coarse(1);
  o.spacing[1] = 0;
  EXPECT_THROW(msk::makeMultiPhantom(o), msk::ParameterError);
  o = coarse(1);
  o.noise = -1;
  EXPECT_THROW(msk::makeMultiPhantom(o), msk::ParameterError);
}
