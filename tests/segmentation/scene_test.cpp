#include "msk/segmentation/scene.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/transform_fit.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/phantom/phantom.h"
#include "msk/test/ball_scenarios.h"
#include "msk/test/files.h"

namespace {

using msk::test::ScratchDir;

// A folder with two closed templates (a.vtk, b.vtk) and an open one (open.obj) to point scenes at.
class SceneFiles {
 public:
  SceneFiles() {
    msk::writeMesh(dir_.file("a.vtk"), msk::makeIcosphere(10, 2));
    msk::writeMesh(dir_.file("b.vtk"), msk::makeIcosphere(5, 2, Eigen::Vector3d(30, 0, 0)), msk::MeshSpace::RAS);
    msk::test::writeBytes(dir_.file("open.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n");
  }
  std::string scene(const std::string& text, const std::string& name = "scene.json") const {
    msk::test::writeBytes(dir_.file(name), text);
    return dir_.file(name);
  }
  const ScratchDir& dir() const { return dir_; }

 private:
  ScratchDir dir_;
};

// Expects loadScene(path) to throw an IoError naming the scene file whose message contains every phrase.
void expectSceneError(const std::string& path, const std::vector<std::string>& phrases) {
  try {
    msk::loadScene(path);
    ADD_FAILURE() << "no error; wanted: " << phrases.front();
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), path);
    for (const auto& p : phrases)
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << "wanted '" << p << "' in: " << e.what();
  }
}

// Expects the three objects of `s` to read a per-object boolean model key (`key` picks it) as true, false and unset.
void expectTrueFalseUnset(const msk::Scene& s, const std::function<std::optional<bool>(const msk::ObjectModel&)>& key) {
  ASSERT_EQ(s.objects.size(), 3u);
  const std::optional<bool> a = key(s.objects[0].model), b = key(s.objects[1].model), c = key(s.objects[2].model);
  ASSERT_TRUE(a.has_value());
  EXPECT_TRUE(*a);
  ASSERT_TRUE(b.has_value());
  EXPECT_FALSE(*b);
  EXPECT_FALSE(c.has_value());
}

// Two valid objects with a collision pair; `extra` is spliced into the first object.
std::string twoObjects(const std::string& extra = "", const std::string& collisions = R"([["femur", "quadriceps"]])") {
  return R"({"objects": [
      {"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk")" +
         extra + R"(},
      {"name": "quadriceps", "label": 2, "kind": "muscle", "template": "b.vtk"}],
    "collisions": )" +
         collisions + "}";
}

}  // namespace

TEST(Scene, MinimalFormLoads) {
  SceneFiles f;
  const std::string path =
      f.scene(R"({"objects": [{"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk"}], "collisions": []})");
  const msk::Scene s = msk::loadScene(path);
  EXPECT_EQ(s.path, path);
  ASSERT_EQ(s.objects.size(), 1u);
  const msk::SceneObject& o = s.objects[0];
  EXPECT_EQ(o.name, "femur");
  EXPECT_EQ(o.label, 1);
  EXPECT_EQ(o.kind, msk::ObjectKind::Bone);
  EXPECT_STREQ(msk::objectKindName(o.kind), "bone");
  EXPECT_EQ(o.templatePath, f.dir().file("a.vtk"));
  EXPECT_EQ(msk::closedMeshProblem(o.templ), "");
  EXPECT_NEAR(msk::enclosedVolume(o.templ), msk::enclosedVolume(msk::makeIcosphere(10, 2)), 1e-6);
  EXPECT_FALSE(o.hasPolarity);
  EXPECT_FALSE(o.hasForce);
  EXPECT_TRUE(s.collisions.empty());

  // "collisions" is optional; the minimal form with valid names gives one pair.
  EXPECT_TRUE(
      msk::loadScene(f.scene(R"({"objects": [{"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk"}]})"))
          .collisions.empty());
  const msk::Scene two = msk::loadScene(f.scene(twoObjects()));
  ASSERT_EQ(two.objects.size(), 2u);
  EXPECT_EQ(two.objects[1].kind, msk::ObjectKind::Muscle);
  ASSERT_EQ(two.collisions.size(), 1u);
  const msk::CollisionPair& p = two.collisions[0];
  EXPECT_EQ(std::make_pair(p.a, p.b), std::make_pair(0, 1));
  // A pair given as ["a", "b"] takes the run's parameters.
  EXPECT_LT(p.gapMm, 0);
  EXPECT_LT(p.proximityMm, 0);
  EXPECT_LT(p.friction, 0);
  EXPECT_EQ(p.mode, msk::CollisionMode::Position);
  EXPECT_EQ(p.target, msk::CollisionTarget::Spring);
  EXPECT_FALSE(p.fromAuto);
  // Without "model", every object gets its kind's default model.
  for (const auto& o : two.objects) {
    const msk::ObjectModel d = msk::defaultModel(o.kind);
    EXPECT_EQ(o.model.shapeMemory, d.shapeMemory);
    EXPECT_EQ(o.model.imageForce, d.imageForce);
    EXPECT_EQ(o.model.medialAxis, d.medialAxis);
    EXPECT_EQ(o.model.volumetric, d.volumetric);
    EXPECT_EQ(o.model.globalPrior, d.globalPrior);
  }
}

// The short form of a collision pair (["a", "b"]) is parsed; names that are not objects of the scene are refused with
// the pair's place, the unknown name and the scene's object names.
TEST(Scene, ShortPairFormNamesUnknownCollisionObjects) {
  SceneFiles f;
  expectSceneError(f.scene(R"({"objects": [{"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk"}],
                               "collisions": [["a", "b"]]})"),
                   {"collisions[0]", "unknown object \"a\"", "objects: femur"});
}

TEST(Scene, TemplatesReadInTheirTaggedSpace) {
  SceneFiles f;
  const msk::Scene s = msk::loadScene(f.scene(twoObjects()));
  // b.vtk was written tagged RAS with its centre at x = +30 (RAS): read back at the same place.
  EXPECT_NEAR(s.objects[1].templ.vertices.col(0).mean(), 30.0, 0.5);
}

TEST(Scene, OptionalOverridesAndMetadata) {
  SceneFiles f;
  const std::string text = R"({"description": "two balls", "provenance": {"seed": 4},
    "objects": [
      {"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk", "polarity": "bright-inside", "force": "profile"},
      {"name": "other", "label": 300, "kind": "generic", "template": "b.vtk", "polarity": "auto", "force": "gradient"},
      {"name": "dark", "label": 32767, "kind": "muscle", "template": "a.vtk", "polarity": "dark-inside"}]})";
  const msk::Scene s = msk::loadScene(f.scene(text));
  ASSERT_EQ(s.objects.size(), 3u);
  EXPECT_TRUE(s.objects[0].hasPolarity);
  EXPECT_EQ(s.objects[0].polarity, msk::Polarity::BrightInside);
  EXPECT_TRUE(s.objects[0].hasForce);
  EXPECT_EQ(s.objects[0].force, msk::TargetMode::Profile);
  EXPECT_EQ(s.objects[1].polarity, msk::Polarity::Auto);
  EXPECT_EQ(s.objects[1].force, msk::TargetMode::Gradient);
  EXPECT_EQ(s.objects[1].kind, msk::ObjectKind::Generic);
  EXPECT_EQ(s.objects[2].polarity, msk::Polarity::DarkInside);
  EXPECT_FALSE(s.objects[2].hasForce);
  EXPECT_EQ(s.objects[2].label, 32767);
  EXPECT_EQ(s.description, "two balls");
  EXPECT_EQ(s.provenance.at("seed").get<int>(), 4);
}

namespace {

// The pairs of a scene as (a, b) index pairs, in scene order.
std::vector<std::pair<int, int>> indexPairs(const msk::Scene& s) {
  std::vector<std::pair<int, int>> v;
  for (const auto& p : s.collisions) v.emplace_back(p.a, p.b);
  return v;
}

}  // namespace

TEST(Scene, CollisionsAreOrderedPairsAndADuplicateIsAnError) {
  SceneFiles f;
  const std::string objects = R"({"objects": [
      {"name": "a", "label": 1, "kind": "bone", "template": "a.vtk"},
      {"name": "b", "label": 2, "kind": "muscle", "template": "b.vtk"},
      {"name": "c", "label": 3, "kind": "muscle", "template": "b.vtk"}],
    "collisions": )";
  const msk::Scene s = msk::loadScene(f.scene(objects + R"([["c", "a"], ["b", "a"], {"pair": ["c", "b"]}]})"));
  const std::vector<std::pair<int, int>> want = {{0, 2}, {0, 1}, {1, 2}};
  EXPECT_EQ(indexPairs(s), want);
  // The same pair twice (in either order, in either form) is ambiguous about its parameters: an error.
  expectSceneError(f.scene(objects + R"([["c", "a"], ["b", "c"], ["a", "c"]]})", "dup1.json"),
                   {"collisions[2] (a, c): pair declared twice (also collisions[0])"});
  expectSceneError(f.scene(objects + R"([["a", "b"], {"pair": ["b", "a"], "gap_mm": 1}]})", "dup2.json"),
                   {"collisions[1] (b, a): pair declared twice (also collisions[0])"});
}

TEST(Scene, EveryKindOfErrorNamesTheKeyAndTheObject) {
  SceneFiles f;
  struct Case {
    std::string text;
    std::vector<std::string> phrases;
  };
  const std::vector<Case> cases = {
      {"[1, 2]", {"must be a JSON object", "array"}},
      {R"({"objects": [], "bogus": 1})",
       {"unknown top-level key \"bogus\"", "known: objects, collisions, description, provenance"}},
      {R"({"collisions": []})", {"missing key \"objects\""}},
      {R"({"objects": {}})", {"\"objects\" must be an array", "object"}},
      {R"({"objects": []})", {"\"objects\" is empty"}},
      {R"({"objects": ["femur"]})", {"objects[0]", "expected an object, found string"}},
      // The example of scene.h: a misspelt key names the object and lists the known keys.
      {twoObjects(R"(, "lable": 3)"),
       {"objects[0] (femur): unknown key \"lable\" (known: name, label, kind, template, polarity, force, model, "
        "profiles_from, colour)"}},
      {twoObjects(R"(, "colour": [255, 0])"),
       {"objects[0] (femur): \"colour\" must be [r, g, b] with integers 0..255"}},
      {twoObjects(R"(, "colour": [255, 0, 256])"), {"objects[0] (femur)", "found [255,0,256]"}},
      {twoObjects(R"(, "colour": "red")"), {"objects[0] (femur)", "\"colour\" must be [r, g, b]"}},
      {R"({"objects": [{"label": 1, "kind": "bone", "template": "a.vtk"}]})", {"objects[0]: missing key \"name\""}},
      {R"({"objects": [{"name": 5, "label": 1, "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0]", "\"name\" must be a string, found number 5"}},
      {R"({"objects": [{"name": "", "label": 1, "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0]", "\"name\" must not be empty"}},
      {R"({"objects": [{"name": "x", "label": 1, "kind": "bone", "template": "a.vtk"},
                       {"name": "x", "label": 2, "kind": "bone", "template": "a.vtk"}]})",
       {"objects[1] (x): duplicate name \"x\" (also objects[0] (x))"}},
      {R"({"objects": [{"name": "femur", "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0] (femur): missing key \"label\""}},
      {R"({"objects": [{"name": "femur", "label": "1", "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0] (femur)", "\"label\" must be an integer in 1..32767, found \"1\""}},
      {R"({"objects": [{"name": "femur", "label": 2.5, "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0] (femur)", "\"label\" must be an integer in 1..32767, found 2.5"}},
      {R"({"objects": [{"name": "femur", "label": 0, "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0] (femur)", "in 1..32767, found 0"}},
      {R"({"objects": [{"name": "femur", "label": 32768, "kind": "bone", "template": "a.vtk"}]})",
       {"objects[0] (femur)", "found 32768"}},
      {R"({"objects": [{"name": "femur", "label": 3, "kind": "bone", "template": "a.vtk"},
                       {"name": "quad", "label": 3, "kind": "muscle", "template": "a.vtk"}]})",
       {"objects[1] (quad): duplicate label 3 (also objects[0] (femur))"}},
      {R"({"objects": [{"name": "femur", "label": 1, "template": "a.vtk"}]})",
       {"objects[0] (femur): missing key \"kind\""}},
      {R"({"objects": [{"name": "femur", "label": 1, "kind": "bones", "template": "a.vtk"}]})",
       {"objects[0] (femur): \"kind\" must be one of bone, muscle, generic, found \"bones\""}},
      {R"({"objects": [{"name": "femur", "label": 1, "kind": "bone"}]})",
       {"objects[0] (femur): missing key \"template\""}},
      {R"({"objects": [{"name": "femur", "label": 1, "kind": "bone", "template": ["a.vtk"]}]})",
       {"objects[0] (femur)", "\"template\" must be a string, found array"}},
      {twoObjects(R"(, "polarity": "dark")"),
       {"objects[0] (femur): \"polarity\" must be one of auto, dark-inside, bright-inside, found \"dark\""}},
      {twoObjects(R"(, "force": 1)"), {"objects[0] (femur)", "\"force\" must be a string"}},
      {twoObjects(R"(, "force": "edges")"), {"objects[0] (femur): \"force\" must be one of gradient, profile"}},
      {twoObjects("", "{}"), {"\"collisions\" must be an array or \"auto\", found object"}},
      {twoObjects("", R"([["femur"]])"), {"collisions[0]", "expected a pair of object names"}},
      {twoObjects("", R"([["femur", "quadriceps", "femur"]])"), {"collisions[0]", "expected a pair"}},
      {twoObjects("", R"([["femur", "quadriceps"], ["femur", 2]])"), {"collisions[1]", "expected a pair"}},
      {twoObjects("", R"([["femur", "quadricep"]])"),
       {"collisions[0] (femur, quadricep): unknown object \"quadricep\" (objects: femur, quadriceps)"}},
      {twoObjects("", R"([["femur", "femur"]])"), {"collisions[0]", "cannot collide with itself (\"femur\")"}},
  };
  for (size_t c = 0; c < cases.size(); ++c) {
    SCOPED_TRACE("case " + std::to_string(c) + ": " + cases[c].text);
    expectSceneError(f.scene(cases[c].text, "case" + std::to_string(c) + ".json"), cases[c].phrases);
  }
}

TEST(Scene, TemplateErrorsNameTheObjectAndTheTemplate) {
  SceneFiles f;
  const std::string missing =
      f.scene(R"({"objects": [{"name": "femur", "label": 1, "kind": "bone", "template": "nowhere.vtk"}]})");
  expectSceneError(missing, {"objects[0] (femur): template " + f.dir().file("nowhere.vtk")});
  const std::string open =
      f.scene(R"({"objects": [{"name": "patella", "label": 5, "kind": "bone", "template": "open.obj"}]})", "open.json");
  expectSceneError(open, {"objects[0] (patella): template " + f.dir().file("open.obj"), "closed"});
}

TEST(Scene, SyntaxErrorsGiveLineAndColumn) {
  SceneFiles f;
  expectSceneError(f.scene("{\"objects\": [\n  {\"name\": \"femur\",, }]}"), {"line 2, column"});
  expectSceneError(f.dir().file("absent.json"), {"cannot open"});
}

TEST(Scene, BundledPhantomSceneLoads) {
  const msk::Scene s = msk::loadScene(msk::test::bundledSample() + "scene.json");
  ASSERT_EQ(s.objects.size(), 4u);
  EXPECT_EQ(s.collisions.size(), 6u);
  EXPECT_EQ(s.objects[0].name, "femur");
  EXPECT_EQ(s.objects[0].kind, msk::ObjectKind::Bone);
  for (const auto& o : s.objects) {
    EXPECT_EQ(msk::closedMeshProblem(o.templ), "") << o.name;
    EXPECT_GT(msk::enclosedVolume(o.templ), 0) << o.name;
  }
  EXPECT_EQ(s.provenance.at("seed").get<int>(), 1);
}

TEST(Scene, GeneratedPhantomSceneLoads) {
  msk::PhantomOptions o;
  o.seed = 2;
  o.spacing = {2.0, 2.0, 4.0};
  o.meshSpacingMm = 2.0;
  o.meshVertices = 400;
  o.noise = 0;
  ScratchDir dir;
  msk::writePhantom(msk::makePhantom(o), o, dir.path());
  const msk::Scene s = msk::loadScene(dir.file("scene.json"));
  ASSERT_EQ(s.objects.size(), 4u);
  EXPECT_EQ(s.collisions.size(), 6u);
  const std::vector<std::pair<int, int>> pairs = indexPairs(s);
  std::set<std::pair<int, int>> distinct(pairs.begin(), pairs.end());
  EXPECT_EQ(distinct.size(), 6u);
  for (const auto& p : s.collisions) {
    EXPECT_LT(p.a, p.b);
    EXPECT_FALSE(p.fromAuto);
  }
  for (size_t i = 0; i < s.objects.size(); ++i) {
    EXPECT_EQ(s.objects[i].label, static_cast<int>(i) + 1);
    EXPECT_EQ(msk::closedMeshProblem(s.objects[i].templ), "") << s.objects[i].name;
  }
}

TEST(Scene, DefaultModelsKeepTodaysBehaviourForEveryKind) {
  for (msk::ObjectKind k : {msk::ObjectKind::Bone, msk::ObjectKind::Muscle, msk::ObjectKind::Generic}) {
    SCOPED_TRACE(msk::objectKindName(k));
    const msk::ObjectModel m = msk::defaultModel(k);
    ASSERT_TRUE(m.shapeMemory.has_value());
    EXPECT_EQ(*m.shapeMemory, msk::InternalMode::ShapeMemory);
    EXPECT_LT(m.internalStiffness, 0);
    EXPECT_TRUE(m.globalPrior);
    EXPECT_FALSE(m.priorTransform.has_value());
    EXPECT_EQ(m.imageForce, msk::TargetMode::Gradient);
    EXPECT_FALSE(m.medialAxis);
    EXPECT_LT(m.radialStiffness, 0);
    EXPECT_LT(m.axisSpacingMm, 0);
    EXPECT_FALSE(m.axisFirst.has_value());  // the run's default (SegmentOptions::axisFirst, off)
    EXPECT_FALSE(m.volumetric);
    EXPECT_LT(m.volumeStiffness, 0);
    EXPECT_FALSE(m.remesh.has_value());  // the run's (SegmentOptions::remeshTemplates; bones keep their mesh)
  }
}

TEST(Scene, EveryModelKeyIsReflectedInTheObject) {
  SceneFiles f;
  const std::string text = R"({"objects": [
      {"name": "quad", "label": 1, "kind": "muscle", "template": "a.vtk",
       "model": {"shape_memory": "smoothing", "internal_stiffness": 0.4, "global_prior": "affine",
                 "image_force": "profile", "medial_axis": true, "radial_stiffness": 0.6, "axis_spacing_mm": 3.5,
                 "volumetric": true, "volume_stiffness": 0.8}},
      {"name": "ham", "label": 2, "kind": "muscle", "template": "b.vtk",
       "model": {"shape_memory": false, "global_prior": false, "medial_axis": false, "volumetric": false}},
      {"name": "femur", "label": 3, "kind": "bone", "template": "a.vtk", "force": "profile",
       "model": {"shape_memory": "template", "global_prior": "rigid"}},
      {"name": "other", "label": 4, "kind": "generic", "template": "b.vtk", "model": {"global_prior": "similarity"}},
      {"name": "empty", "label": 5, "kind": "generic", "template": "b.vtk", "model": {}}]})";
  const msk::Scene s = msk::loadScene(f.scene(text));
  ASSERT_EQ(s.objects.size(), 5u);
  const msk::ObjectModel& q = s.objects[0].model;
  ASSERT_TRUE(q.shapeMemory.has_value());
  EXPECT_EQ(*q.shapeMemory, msk::InternalMode::Smoothing);
  EXPECT_DOUBLE_EQ(q.internalStiffness, 0.4);
  EXPECT_TRUE(q.globalPrior);
  ASSERT_TRUE(q.priorTransform.has_value());
  EXPECT_EQ(*q.priorTransform, msk::PriorTransform::Affine);
  EXPECT_EQ(q.imageForce, msk::TargetMode::Profile);
  EXPECT_TRUE(s.objects[0].hasForce);  // "image_force" is what the segmenter reads as the object's force
  EXPECT_EQ(s.objects[0].force, msk::TargetMode::Profile);
  EXPECT_TRUE(q.medialAxis);
  EXPECT_DOUBLE_EQ(q.radialStiffness, 0.6);
  EXPECT_DOUBLE_EQ(q.axisSpacingMm, 3.5);
  EXPECT_TRUE(q.volumetric);
  EXPECT_DOUBLE_EQ(q.volumeStiffness, 0.8);

  const msk::ObjectModel& h = s.objects[1].model;
  EXPECT_FALSE(h.shapeMemory.has_value());
  EXPECT_FALSE(h.globalPrior);
  EXPECT_FALSE(h.priorTransform.has_value());
  EXPECT_FALSE(h.medialAxis);
  EXPECT_FALSE(h.volumetric);
  EXPECT_FALSE(s.objects[1].hasForce);
  EXPECT_EQ(h.imageForce, msk::TargetMode::Gradient);

  // The object-level "force" is the same setting as "image_force".
  const msk::ObjectModel& b = s.objects[2].model;
  EXPECT_EQ(b.imageForce, msk::TargetMode::Profile);
  EXPECT_TRUE(s.objects[2].hasForce);
  EXPECT_EQ(*b.shapeMemory, msk::InternalMode::ShapeMemory);
  EXPECT_EQ(*b.priorTransform, msk::PriorTransform::Rigid);
  EXPECT_EQ(*s.objects[3].model.priorTransform, msk::PriorTransform::Similarity);
  // An empty "model" is the kind's default.
  EXPECT_EQ(s.objects[4].model.shapeMemory, msk::defaultModel(msk::ObjectKind::Generic).shapeMemory);
  EXPECT_FALSE(s.objects[4].model.priorTransform.has_value());
  EXPECT_LT(s.objects[4].model.internalStiffness, 0);
}

TEST(Scene, EveryKindOfBadModelOrPairValueNamesTheKeyAndTheObject) {
  SceneFiles f;
  struct Case {
    std::string text;
    std::vector<std::string> phrases;
  };
  const std::string m = R"(, "model": )";
  const std::vector<Case> cases = {
      {twoObjects(m + "[]"), {"objects[0] (femur) model: expected an object, found array"}},
      {twoObjects(m + R"({"shape_memmory": "template"})"),
       {"objects[0] (femur) model: unknown key \"shape_memmory\"", "known: shape_memory, internal_stiffness"}},
      {twoObjects(m + R"({"shape_memory": "memory"})"),
       {"objects[0] (femur) model: \"shape_memory\" must be \"template\", \"smoothing\" or false, found \"memory\""}},
      {twoObjects(m + R"({"shape_memory": true})"), {"objects[0] (femur) model", "\"shape_memory\"", "found true"}},
      {twoObjects(m + R"({"internal_stiffness": 1.5})"),
       {"objects[0] (femur) model: \"internal_stiffness\" must be a number in [0, 1], found 1.5"}},
      {twoObjects(m + R"({"internal_stiffness": -0.1})"),
       {"objects[0] (femur) model", "\"internal_stiffness\"", "-0.1"}},
      {twoObjects(m + R"({"internal_stiffness": "stiff"})"),
       {"objects[0] (femur) model", "\"internal_stiffness\" must be a number in [0, 1], found \"stiff\""}},
      {twoObjects(m + R"({"shape_memory": false, "internal_stiffness": 0.5})"),
       {"objects[0] (femur) model: \"internal_stiffness\" is given but \"shape_memory\" is false"}},
      {twoObjects(m + R"({"global_prior": "euclidean"})"),
       {"objects[0] (femur) model: \"global_prior\" must be one of rigid, similarity, affine or false, found "
        "\"euclidean\""}},
      {twoObjects(m + R"({"global_prior": true})"), {"objects[0] (femur) model", "\"global_prior\"", "found true"}},
      {twoObjects(m + R"({"image_force": "edges"})"),
       {"objects[0] (femur) model: \"image_force\" must be one of gradient, profile, found \"edges\""}},
      {twoObjects(R"(, "force": "gradient")" + m + R"({"image_force": "gradient"})"),
       {"objects[0] (femur): both \"force\" and model \"image_force\" are given"}},
      {twoObjects(m + R"({"medial_axis": "yes"})"),
       {"objects[0] (femur) model: \"medial_axis\" must be true or false, found string \"yes\""}},
      {twoObjects(m + R"({"medial_axis": true, "radial_stiffness": 2})"),
       {"objects[0] (femur) model: \"radial_stiffness\" must be a number in [0, 1], found 2"}},
      {twoObjects(m + R"({"medial_axis": true, "axis_spacing_mm": 0})"),
       {"objects[0] (femur) model: \"axis_spacing_mm\" must be a number in [0.5, 100], found 0"}},
      {twoObjects(m + R"({"radial_stiffness": 0.5})"),
       {"objects[0] (femur) model: \"radial_stiffness\" is given but the object has no medial axis"}},
      {twoObjects(m + R"({"axis_spacing_mm": 4})"),
       {"objects[0] (femur) model: \"axis_spacing_mm\" is given but the object has no medial axis"}},
      {twoObjects(m + R"({"volumetric": 1})"),
       {"objects[0] (femur) model: \"volumetric\" must be true or false, found number 1"}},
      {twoObjects(m + R"({"volumetric": true, "volume_stiffness": -1})"),
       {"objects[0] (femur) model: \"volume_stiffness\" must be a number in [0, 1], found -1"}},
      {twoObjects(m + R"({"volume_stiffness": 0.5})"),
       {"objects[0] (femur) model: \"volume_stiffness\" is given but the object has no volume model"}},
      // Collision entries.
      {twoObjects("", R"("manual")"), {"\"collisions\" must be an array or \"auto\", found \"manual\""}},
      {twoObjects("", R"([{"gap_mm": 1}])"), {"collisions[0]: an object entry needs \"pair\""}},
      {twoObjects("", R"([{"pair": ["femur"]}])"), {"collisions[0]", "expected a pair of object names"}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "gap": 1}])"),
       {"collisions[0] (femur, quadriceps): unknown key \"gap\" (known: pair, gap_mm, proximity_mm, friction, mode, "
        "target, resolution)"}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "gap_mm": -1}])"),
       {"collisions[0] (femur, quadriceps): \"gap_mm\" must be a number in [0, 10], found -1"}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "gap_mm": 1e300}])"),
       {"collisions[0] (femur, quadriceps): \"gap_mm\" must be a number in [0, 10], found 1e+300"}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "proximity_mm": 0}])"),
       {"collisions[0] (femur, quadriceps): \"proximity_mm\" must be a number in (0, 50], found 0"}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "friction": 1.5}])"),
       {"collisions[0] (femur, quadriceps): \"friction\" must be a number in [0, 1], found 1.5"}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "mode": "impulse"}])"),
       {"collisions[0] (femur, quadriceps): \"mode\" must be one of position, velocity, acceleration, found "
        "\"impulse\""}},
      {twoObjects("", R"([{"pair": ["femur", "quadriceps"], "target": "wall"}])"),
       {"collisions[0] (femur, quadriceps): \"target\" must be one of spring, reaction, reference, found \"wall\""}},
      {twoObjects("", R"([{"pair": ["femur", "quads"]}])"),
       {"collisions[0] (femur, quads): unknown object \"quads\" (objects: femur, quadriceps)"}},
      {twoObjects("", R"([{"auto": false}])"), {"collisions[0]: \"auto\" must be true", "found false"}},
      {twoObjects("", R"([{"auto": true, "pair": ["femur", "quadriceps"]}])"),
       {"collisions[0]: unknown key \"pair\" (known: auto, within_mm, gap_mm"}},
      {twoObjects("", R"([{"auto": true, "within_mm": -2}])"),
       {"collisions[0]: \"within_mm\" must be a number in [0, 100], found -2"}},
      {twoObjects("", R"([{"auto": true, "friction": 2}])"),
       {"collisions[0]: \"friction\" must be a number in [0, 1]"}},
      {twoObjects("", R"([{"auto": true}, ["femur", "quadriceps"], {"auto": true, "within_mm": 1}])"),
       {"collisions[2]: a second \"auto\" entry (also collisions[0])"}},
  };
  for (size_t c = 0; c < cases.size(); ++c) {
    SCOPED_TRACE("case " + std::to_string(c) + ": " + cases[c].text);
    expectSceneError(f.scene(cases[c].text, "model" + std::to_string(c) + ".json"), cases[c].phrases);
  }
}

TEST(Scene, PairParametersAreReflected) {
  SceneFiles f;
  const msk::Scene s = msk::loadScene(
      f.scene(twoObjects("", R"([{"pair": ["quadriceps", "femur"], "gap_mm": 0, "proximity_mm": 1.5, "friction": 0.25,
               "mode": "acceleration", "target": "reference"}])")));
  ASSERT_EQ(s.collisions.size(), 1u);
  const msk::CollisionPair& p = s.collisions[0];
  EXPECT_EQ(std::make_pair(p.a, p.b), std::make_pair(0, 1));
  EXPECT_EQ(p.gapMm, 0.0);
  EXPECT_EQ(p.proximityMm, 1.5);
  EXPECT_EQ(p.friction, 0.25);
  EXPECT_EQ(p.mode, msk::CollisionMode::Acceleration);
  EXPECT_EQ(p.target, msk::CollisionTarget::Reference);
  EXPECT_FALSE(p.fromAuto);
  EXPECT_STREQ(msk::collisionModeName(msk::CollisionMode::Velocity), "velocity");
  EXPECT_STREQ(msk::collisionModeName(p.mode), "acceleration");
  EXPECT_STREQ(msk::collisionTargetName(msk::CollisionTarget::Reaction), "reaction");
  EXPECT_STREQ(msk::collisionTargetName(p.target), "reference");
  EXPECT_STREQ(msk::collisionModeName(msk::CollisionMode::Position), "position");
  EXPECT_STREQ(msk::collisionTargetName(msk::CollisionTarget::Spring), "spring");
}

namespace {

// Three spheres of radius 10: "near1" at the origin, "near2" 21 mm away along x (1 mm apart), "far" 40 mm away
// along y (20 mm apart from near1).
std::string threeSpheres(const ScratchDir& dir, const std::string& collisions) {
  msk::writeMesh(dir.file("s1.vtk"), msk::makeIcosphere(10, 3), msk::MeshSpace::RAS);
  msk::writeMesh(dir.file("s2.vtk"), msk::makeIcosphere(10, 3, Eigen::Vector3d(21, 0, 0)), msk::MeshSpace::RAS);
  msk::writeMesh(dir.file("s3.vtk"), msk::makeIcosphere(10, 3, Eigen::Vector3d(0, 40, 0)), msk::MeshSpace::RAS);
  const std::string path = dir.file("three.json");
  msk::test::writeBytes(path, R"({"objects": [
      {"name": "near1", "label": 1, "kind": "bone", "template": "s1.vtk"},
      {"name": "far", "label": 2, "kind": "muscle", "template": "s3.vtk"},
      {"name": "near2", "label": 3, "kind": "muscle", "template": "s2.vtk"}],
    "collisions": )" + collisions +
                                  "}");
  return path;
}

}  // namespace

TEST(Scene, AutoPairsAreTheTemplatesWithinTheDistance) {
  ScratchDir dir;
  // The shorthand (within 2 mm) selects exactly the two touching spheres, with the run's parameters.
  const msk::Scene s = msk::loadScene(threeSpheres(dir, R"("auto")"));
  ASSERT_EQ(s.collisions.size(), 1u);
  const msk::CollisionPair& p = s.collisions[0];
  EXPECT_EQ(std::make_pair(p.a, p.b), std::make_pair(0, 2));
  EXPECT_TRUE(p.fromAuto);
  EXPECT_LT(p.gapMm, 0);
  EXPECT_LT(p.friction, 0);
  // Below the 1 mm between the near spheres: no pair. Within 21 mm: far (20 mm from near1) joins near1 but not
  // near2 (√(40² + 21²) − 20 ≈ 25.2 mm away); within 30 mm: every pair.
  EXPECT_TRUE(msk::loadScene(threeSpheres(dir, R"([{"auto": true, "within_mm": 0.5}])")).collisions.empty());
  const std::vector<std::pair<int, int>> wide = {{0, 1}, {0, 2}};
  EXPECT_EQ(indexPairs(msk::loadScene(threeSpheres(dir, R"([{"auto": true, "within_mm": 21}])"))), wide);
  const std::vector<std::pair<int, int>> all = {{0, 1}, {0, 2}, {1, 2}};
  EXPECT_EQ(indexPairs(msk::loadScene(threeSpheres(dir, R"([{"auto": true, "within_mm": 30}])"))), all);
}

TEST(Scene, ExplicitPairsOverrideAutoParameters) {
  ScratchDir dir;
  const msk::Scene s = msk::loadScene(threeSpheres(dir, R"([
      {"auto": true, "within_mm": 30, "gap_mm": 0.5, "friction": 0.3, "mode": "velocity", "target": "reaction"},
      {"pair": ["near2", "near1"], "gap_mm": 0.1},
      ["far", "near2"]])"));
  // Declared pairs first in file order, then the auto pairs not declared.
  const std::vector<std::pair<int, int>> want = {{0, 2}, {1, 2}, {0, 1}};
  ASSERT_EQ(indexPairs(s), want);
  const msk::CollisionPair &near = s.collisions[0], &declared = s.collisions[1], &found = s.collisions[2];
  EXPECT_FALSE(near.fromAuto);
  EXPECT_EQ(near.gapMm, 0.1);
  EXPECT_LT(near.friction, 0);  // not the auto entry's 0.3
  EXPECT_EQ(near.mode, msk::CollisionMode::Position);
  EXPECT_EQ(near.target, msk::CollisionTarget::Spring);
  EXPECT_FALSE(declared.fromAuto);
  EXPECT_LT(declared.gapMm, 0);
  EXPECT_TRUE(found.fromAuto);
  EXPECT_EQ(found.gapMm, 0.5);
  EXPECT_EQ(found.friction, 0.3);
  EXPECT_LT(found.proximityMm, 0);
  EXPECT_EQ(found.mode, msk::CollisionMode::Velocity);
  EXPECT_EQ(found.target, msk::CollisionTarget::Reaction);
}

TEST(Scene, AutoPairsOnTheGeneratedPhantomAreItsDeclaredPairs) {
  msk::PhantomOptions o;
  o.seed = 3;
  o.spacing = {2.0, 2.0, 2.0};
  o.meshSpacingMm = 2.0;
  o.meshVertices = 600;
  o.noise = 0;
  ScratchDir dir;
  msk::writePhantom(msk::makePhantom(o), o, dir.path());
  const msk::Scene declared = msk::loadScene(dir.file("scene.json"));
  // The same scene with "collisions": "auto": the thigh's compartments all touch (or overlap) each other and the
  // femur, so auto finds the same six pairs.
  msk::Json j = msk::readJsonFile(dir.file("scene.json"));
  j["collisions"] = msk::Json("auto");
  msk::writeJsonFile(dir.file("auto.json"), j);
  const msk::Scene found = msk::loadScene(dir.file("auto.json"));
  std::vector<std::pair<int, int>> want = indexPairs(declared), got = indexPairs(found);
  std::sort(want.begin(), want.end());
  EXPECT_EQ(got, want);
  for (const auto& p : found.collisions) EXPECT_TRUE(p.fromAuto);
}

TEST(Scene, ProfilesFromMirrorAndMatrix) {
  SceneFiles f;
  // Unset: no transform.
  EXPECT_FALSE(msk::loadScene(f.scene(twoObjects(R"(, "force": "profile")"))).objects[0].profileSource);
  // The mirror about x = 12.5 mm: x' = 25 − x.
  const msk::Scene m =
      msk::loadScene(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"mirror_x": 12.5})")));
  ASSERT_TRUE(m.objects[0].profileSource);
  Eigen::Matrix4d want = Eigen::Matrix4d::Identity();
  want(0, 0) = -1;
  want(0, 3) = 25;
  EXPECT_EQ(*m.objects[0].profileSource, want);
  EXPECT_FALSE(m.objects[1].profileSource);
  // A general affine map, row by row; "model": {"image_force": "profile"} is the same as "force".
  const msk::Scene a = msk::loadScene(f.scene(twoObjects(
      R"(, "model": {"image_force": "profile"},
          "profiles_from": {"matrix": [[0, -1, 0, 5], [2, 0, 0, -3], [0, 0, 1, 0.5], [0, 0, 0, 1]]})")));
  ASSERT_TRUE(a.objects[0].profileSource);
  want << 0, -1, 0, 5, 2, 0, 0, -3, 0, 0, 1, 0.5, 0, 0, 0, 1;
  EXPECT_EQ(*a.objects[0].profileSource, want);
}

TEST(Scene, ProfilesFromErrorsNameTheObjectAndTheProblem) {
  SceneFiles f;
  expectSceneError(f.scene(twoObjects(R"(, "profiles_from": {"mirror_x": 1})")),
                   {"objects[0] (femur)", "\"profiles_from\" is given but the image force is gradient"});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": 3)")),
                   {"objects[0] (femur) profiles_from", "expected {\"mirror_x\""});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"mirror": 3})")),
                   {"profiles_from", "unknown key \"mirror\""});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {})")),
                   {"give \"mirror_x\", \"matrix\" or \"image\""});
  expectSceneError(
      f.scene(twoObjects(
          R"(, "force": "profile", "profiles_from": {"mirror_x": 1, "matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})")),
      {"at most one of"});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"image": "missing.nii.gz"})")),
                   {"objects[0] (femur)", "profiles_from image", "missing.nii.gz"});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"mirror_x": "left"})")),
                   {"\"mirror_x\" must be a finite number"});
  expectSceneError(
      f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]})")),
      {"4 rows of 4"});
  expectSceneError(
      f.scene(
          twoObjects(R"(, "force": "profile", "profiles_from": {"matrix": [[1,0,0,0],[0,1,0],[0,0,1,0],[0,0,0,1]]})")),
      {"4 rows of 4"});
  expectSceneError(
      f.scene(twoObjects(
          R"(, "force": "profile", "profiles_from": {"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]})")),
      {"last row 0 0 0 1"});
  expectSceneError(
      f.scene(twoObjects(
          R"(, "force": "profile", "profiles_from": {"matrix": [[1,0,0,0],[0,1,0,0],[1,1,0,0],[0,0,0,1]]})")),
      {"singular"});
}

TEST(Scene, ProfilesFromSubjectsReadsEachImageOnceAndEachSurface) {
  SceneFiles f;
  msk::writeNifti(f.dir().file("s.nii.gz"), msk::ImageF(msk::test::boxGrid({1, 1, 1}, {4, 4, 4}), 1.f),
                  msk::DataType::Float32);
  msk::writeMesh(f.dir().file("fitted.vtk"), msk::makeIcosphere(12, 2, Eigen::Vector3d(1, 2, 3)));
  msk::writeMesh(f.dir().file("coarse.vtk"), msk::makeIcosphere(10, 1));
  const std::string two = R"(, "force": "profile", "profiles_from": {"subjects": [
      {"image": "s.nii.gz", "surface": "a.vtk"}, {"image": "s.nii.gz", "surface": "fitted.vtk"}]})";
  const msk::Scene s = msk::loadScene(f.scene(twoObjects(two)));
  const msk::SceneObject& o = s.objects[0];
  ASSERT_EQ(o.profileSubjects.size(), 2u);
  ASSERT_TRUE(o.profileSubjects[0].image);
  EXPECT_EQ(o.profileSubjects[0].image, o.profileSubjects[1].image);  // one file, read once
  EXPECT_EQ(o.profileImage, o.profileSubjects[0].image);              // the first subject's, as no "image" is given
  EXPECT_TRUE(msk::hasProfileSource(o));
  EXPECT_NEAR(o.profileSubjects[1].surface.vertices.row(0).norm(),
              (msk::makeIcosphere(12, 2).vertices.row(0) + Eigen::RowVector3d(1, 2, 3)).norm(), 1e-4);
  // Written and read back: the same subjects.
  msk::writeScene(s, f.dir().file("again.json"));
  const msk::Scene again = msk::loadScene(f.dir().file("again.json"));
  ASSERT_EQ(again.objects[0].profileSubjects.size(), 2u);
  EXPECT_EQ(again.objects[0].profileSubjects[1].surfacePath, f.dir().file("fitted.vtk"));

  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"subjects": [
      {"image": "s.nii.gz", "surface": "coarse.vtk"}]})")),
                   {"objects[0] (femur)", "coarse.vtk", "42 vertices, not the template's 162"});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"subjects": []})")),
                   {"profiles_from", "non-empty array"});
  expectSceneError(
      f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"subjects": [{"image": "s.nii.gz"}]})")),
      {"subjects[0]", "surface"});
  expectSceneError(f.scene(twoObjects(R"(, "force": "profile", "profiles_from": {"subjects": [
      {"image": "none.nii.gz", "surface": "a.vtk"}]})")),
                   {"objects[0] (femur)", "none.nii.gz"});
}

TEST(Scene, ToProfileSourceMirrorsPointsAndKeepsNormalsOutward) {
  msk::SceneObject obj;
  const msk::TriangleMesh ball = msk::makeIcosphere(10, 2, Eigen::Vector3d(-40, 5, 3));
  msk::Points positions = ball.vertices, normals = msk::vertexNormals(ball);
  // Unset: unchanged.
  msk::Points p = positions, n = normals;
  msk::toProfileSource(obj, p, n);
  EXPECT_EQ(p, positions);
  EXPECT_EQ(n, normals);
  // Mirrored about x = 0: the ball's centre goes to (40, 5, 3), every normal still points away from it.
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  obj.profileSource = mirror;
  msk::toProfileSource(obj, p, n);
  const Eigen::RowVector3d centre(40, 5, 3);
  for (Eigen::Index v = 0; v < p.rows(); ++v) {
    EXPECT_NEAR(p(v, 0), -positions(v, 0), 1e-12);
    EXPECT_NEAR(n.row(v).norm(), 1.0, 1e-12);
    EXPECT_GT(n.row(v).dot((p.row(v) - centre).normalized()), 0.95);
  }
  // A shear: normals follow A⁻ᵀ (still perpendicular to the mapped surface's edges) and stay outward.
  Eigen::Matrix4d shear = Eigen::Matrix4d::Identity();
  shear(0, 1) = 0.8;
  shear(2, 3) = 7;
  obj.profileSource = shear;
  p = positions;
  n = normals;
  msk::toProfileSource(obj, p, n);
  const Eigen::Matrix3d a = shear.topLeftCorner<3, 3>();
  for (Eigen::Index v = 0; v < p.rows(); ++v) {
    const Eigen::Vector3d tangent = Eigen::Vector3d(normals.row(v)).unitOrthogonal();  // a tangent of the ball
    EXPECT_NEAR(n.row(v).dot(a * tangent), 0.0, 1e-12);
    EXPECT_GT(n.row(v).dot(a * Eigen::Vector3d(normals.row(v))), 0.0);
  }
}

// "axis_first" (the axis-first coarse stage): read as given with a medial axis, unset otherwise (the run's default);
// given without a medial axis, or not a boolean, it is an error naming the key and the object.
TEST(Scene, AxisFirstNeedsAMedialAxisAndNamesTheKeyAndTheObject) {
  SceneFiles f;
  const std::string text = R"({"objects": [
      {"name": "quad", "label": 1, "kind": "muscle", "template": "a.vtk",
       "model": {"medial_axis": true, "axis_first": true}},
      {"name": "ham", "label": 2, "kind": "muscle", "template": "b.vtk",
       "model": {"medial_axis": true, "axis_first": false}},
      {"name": "add", "label": 3, "kind": "muscle", "template": "b.vtk", "model": {"medial_axis": true}}]})";
  expectTrueFalseUnset(msk::loadScene(f.scene(text)), [](const msk::ObjectModel& m) { return m.axisFirst; });

  const std::string m = R"(, "model": )";
  expectSceneError(
      f.scene(twoObjects(m + R"({"axis_first": true})"), "no_axis.json"),
      {"objects[0] (femur) model: \"axis_first\" is given but the object has no medial axis", "\"medial_axis\": true"});
  expectSceneError(f.scene(twoObjects(m + R"({"medial_axis": false, "axis_first": false})"), "axis_off.json"),
                   {"objects[0] (femur) model: \"axis_first\" is given but the object has no medial axis"});
  expectSceneError(f.scene(twoObjects(m + R"({"medial_axis": true, "axis_first": "yes"})"), "not_bool.json"),
                   {"objects[0] (femur) model: \"axis_first\" must be true or false, found string \"yes\""});
  expectSceneError(f.scene(twoObjects(m + R"({"medial_axis": true, "axis_frist": true})"), "typo.json"),
                   {"objects[0] (femur) model: unknown key \"axis_frist\"", "axis_first"});
}

namespace {
// A boolean model key `key` (read by `get`): true, false and unset on three objects; a value that is not a boolean is
// an error naming the key and the object.
void expectBooleanModelKeyPerObject(const std::string& key,
                                    const std::function<std::optional<bool>(const msk::ObjectModel&)>& get) {
  SceneFiles f;
  const std::string text = R"({"objects": [
      {"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk", "model": {")" +
                           key + R"(": true}},
      {"name": "quad", "label": 2, "kind": "muscle", "template": "b.vtk", "model": {")" +
                           key + R"(": false}},
      {"name": "ham", "label": 3, "kind": "muscle", "template": "b.vtk"}]})";
  expectTrueFalseUnset(msk::loadScene(f.scene(text)), get);
  expectSceneError(f.scene(twoObjects(R"(, "model": {")" + key + R"(": 1})"), "not_bool.json"),
                   {"objects[0] (femur) model: \"" + key + "\" must be true or false, found number"});
}
}  // namespace

// "refine" (the refinement pass): read as given, unset otherwise (the run's default).
TEST(Scene, RefineIsReadPerObject) {
  expectBooleanModelKeyPerObject("refine", [](const msk::ObjectModel& m) { return m.refine; });
}

// "remesh" (isotropic remeshing of the template): read as given, unset otherwise (the run's for muscles, kept for
// bones: segmenter.h).
TEST(Scene, RemeshIsReadPerObject) {
  expectBooleanModelKeyPerObject("remesh", [](const msk::ObjectModel& m) { return m.remesh; });
}

// writeScene() is parseScene()'s inverse: a scene using every key reads back as the same scene, and written again
// gives the same text.
TEST(Scene, WrittenSceneReadsBackTheSame) {
  SceneFiles f;
  const std::string path = f.scene(R"({"description": "every key", "provenance": {"generator": "test", "seed": 3},
    "objects": [
      {"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk", "polarity": "dark-inside",
       "colour": [241, 214, 145],
       "model": {"shape_memory": "smoothing", "internal_stiffness": 0.5, "global_prior": "affine", "refine": true,
                 "volumetric": true, "volume_stiffness": 0.3}},
      {"name": "quad", "label": 2, "kind": "muscle", "template": "b.vtk", "force": "profile",
       "profiles_from": {"mirror_x": 12.5},
       "model": {"medial_axis": true, "radial_stiffness": 0.2, "axis_spacing_mm": 6, "axis_first": false,
                 "global_prior": false, "remesh": false}},
      {"name": "other", "label": 300, "kind": "generic", "template": "a.vtk", "force": "profile",
       "profiles_from": {"matrix": [[1, 0, 0, 5], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1]]},
       "model": {"shape_memory": false}}],
    "collisions": [{"pair": ["femur", "quad"], "gap_mm": 0.5, "mode": "velocity", "resolution": "global"},
                   ["quad", "other"],
                   {"auto": true, "within_mm": 50, "friction": 0.25, "target": "reaction"}]})");
  const msk::Scene a = msk::loadScene(path);
  msk::writeScene(a, f.dir().file("written.json"));
  const msk::Scene b = msk::loadScene(f.dir().file("written.json"));
  ASSERT_EQ(a.objects.size(), b.objects.size());
  ASSERT_TRUE(a.objects[0].colour.has_value());
  EXPECT_EQ(*a.objects[0].colour, (std::array<int, 3>{241, 214, 145}));
  EXPECT_FALSE(a.objects[1].colour.has_value());
  for (size_t i = 0; i < a.objects.size(); ++i) {
    const msk::SceneObject &x = a.objects[i], &y = b.objects[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.label, y.label);
    EXPECT_EQ(x.kind, y.kind);
    EXPECT_EQ(x.colour, y.colour);
    EXPECT_EQ(x.templatePath, y.templatePath);
    EXPECT_EQ(x.hasPolarity, y.hasPolarity);
    EXPECT_EQ(x.polarity, y.polarity);
    EXPECT_EQ(x.hasForce, y.hasForce);
    EXPECT_EQ(x.force, y.force);
    EXPECT_EQ(x.profileSource.has_value(), y.profileSource.has_value());
    if (x.profileSource) {
      EXPECT_EQ(*x.profileSource, *y.profileSource) << x.name;
    }
    EXPECT_EQ(x.model.shapeMemory, y.model.shapeMemory) << x.name;
    EXPECT_EQ(x.model.internalStiffness, y.model.internalStiffness);
    EXPECT_EQ(x.model.globalPrior, y.model.globalPrior);
    EXPECT_EQ(x.model.priorTransform, y.model.priorTransform);
    EXPECT_EQ(x.model.medialAxis, y.model.medialAxis);
    EXPECT_EQ(x.model.radialStiffness, y.model.radialStiffness);
    EXPECT_EQ(x.model.axisSpacingMm, y.model.axisSpacingMm);
    EXPECT_EQ(x.model.axisFirst, y.model.axisFirst);
    EXPECT_EQ(x.model.refine, y.model.refine);
    EXPECT_EQ(x.model.remesh, y.model.remesh);
    EXPECT_EQ(x.model.volumetric, y.model.volumetric);
    EXPECT_EQ(x.model.volumeStiffness, y.model.volumeStiffness);
  }
  ASSERT_EQ(a.collisions.size(), b.collisions.size());
  for (size_t k = 0; k < a.collisions.size(); ++k) {
    const msk::CollisionPair &x = a.collisions[k], &y = b.collisions[k];
    EXPECT_EQ(x.a, y.a);
    EXPECT_EQ(x.b, y.b);
    EXPECT_EQ(x.gapMm, y.gapMm);
    EXPECT_EQ(x.friction, y.friction);
    EXPECT_EQ(x.mode, y.mode);
    EXPECT_EQ(x.target, y.target);
    EXPECT_EQ(x.resolution, y.resolution);
    EXPECT_EQ(x.fromAuto, y.fromAuto);
  }
  ASSERT_TRUE(b.autoCollisions.has_value());
  EXPECT_EQ(b.autoCollisions->withinMm, 50);
  EXPECT_EQ(b.description, "every key");
  EXPECT_EQ(b.provenance, a.provenance);
  EXPECT_EQ(msk::dumpJson(msk::sceneJson(a, f.dir().path())), msk::dumpJson(msk::sceneJson(b, f.dir().path())));
  // The plain auto entry is written in its short form.
  const msk::Scene plain = msk::loadScene(f.scene(twoObjects("", "\"auto\""), "plain.json"));
  EXPECT_EQ(msk::sceneJson(plain, f.dir().path()).at("collisions"), msk::Json("auto"));
}

// Object names name output files: anything but the safe set is refused when the scene is read, naming the object and
// showing the name in printable form.
TEST(Scene, UnsafeObjectNamesAreRefused) {
  SceneFiles f;
  auto named = [&](const std::string& jsonName) {
    std::string text = twoObjects("", "[]");
    text.replace(text.find("\"femur\""), 7, jsonName);
    return f.scene(text);
  };
  const std::string rule = "the name must be 1-64 characters";
  expectSceneError(named(R"("../../escaped_femur")"), {"objects[0] (../../escaped_femur)", rule});
  expectSceneError(named(R"("fe\u0000mur")"), {"objects[0] (fe\\x00mur)", rule});
  expectSceneError(named(R"("labels.nii.gz/x")"), {rule});
  expectSceneError(named(R"(".")"), {rule});
  expectSceneError(named(R"("..")"), {rule});
  expectSceneError(named(R"(".hidden")"), {rule});
  expectSceneError(named(R"("left femur")"), {rule});
  expectSceneError(named(R"("f\u00e9mur")"), {"objects[0] (f\\xc3\\xa9mur)", rule});
  expectSceneError(named("\"" + std::string(65, 'a') + "\""), {rule});
  EXPECT_NO_THROW(msk::loadScene(named("\"" + std::string(64, 'a') + "\"")));
  EXPECT_NO_THROW(msk::loadScene(named(R"("Femur_R.v2-final")")));
}
