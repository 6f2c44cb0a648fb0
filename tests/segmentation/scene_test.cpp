#include "msk/segmentation/scene.h"

#include <gtest/gtest.h>

#include <functional>
#include <set>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/phantom.h"
#include "test_support.h"

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
  EXPECT_EQ(two.collisions[0], std::make_pair(0, 1));
}

TEST(Scene, IssueExampleNamesUnknownCollisionObjects) {
  // The form of the issue's example is accepted; its collision names "a", "b" are not objects of the scene.
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
  const std::string text = R"({"description": "two balls", "phantom": {"seed": 4},
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
  EXPECT_EQ(s.metadata.at("description").asString(), "two balls");
  EXPECT_EQ(s.metadata.at("phantom").at("seed").asInt(), 4);
}

TEST(Scene, DuplicateCollisionsCollapseToOrderedPairs) {
  SceneFiles f;
  const std::string text = R"({"objects": [
      {"name": "a", "label": 1, "kind": "bone", "template": "a.vtk"},
      {"name": "b", "label": 2, "kind": "muscle", "template": "b.vtk"},
      {"name": "c", "label": 3, "kind": "muscle", "template": "b.vtk"}],
    "collisions": [["c", "a"], ["a", "c"], ["b", "a"], ["c", "a"], ["b", "c"]]})";
  const msk::Scene s = msk::loadScene(f.scene(text));
  const std::vector<std::pair<int, int>> want = {{0, 2}, {0, 1}, {1, 2}};
  EXPECT_EQ(s.collisions, want);
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
       {"unknown top-level key \"bogus\"", "known: objects, collisions, phantom, description"}},
      {R"({"collisions": []})", {"missing key \"objects\""}},
      {R"({"objects": {}})", {"\"objects\" must be an array", "object"}},
      {R"({"objects": []})", {"\"objects\" is empty"}},
      {R"({"objects": ["femur"]})", {"objects[0]", "expected an object, found string"}},
      // The example of scene.h: a misspelt key names the object and lists the known keys.
      {twoObjects(R"(, "lable": 3)"),
       {"objects[0] (femur): unknown key \"lable\" (known: name, label, kind, template, polarity, force)"}},
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
      {twoObjects("", "{}"), {"\"collisions\" must be an array, found object"}},
      {twoObjects("", R"([["femur"]])"), {"collisions[0]", "expected a pair of object names"}},
      {twoObjects("", R"([["femur", "quadriceps", "femur"]])"), {"collisions[0]", "expected a pair"}},
      {twoObjects("", R"([["femur", "quadriceps"], ["femur", 2]])"), {"collisions[1]", "expected a pair"}},
      {twoObjects("", R"([["femur", "quadricep"]])"),
       {"collisions[0]: unknown object \"quadricep\" (objects: femur, quadriceps)"}},
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
  const msk::Scene s = msk::loadScene(MSK_SOURCE_DIR "/data-samples/thigh-seed1/scene.json");
  ASSERT_EQ(s.objects.size(), 4u);
  EXPECT_EQ(s.collisions.size(), 6u);
  EXPECT_EQ(s.objects[0].name, "femur");
  EXPECT_EQ(s.objects[0].kind, msk::ObjectKind::Bone);
  for (const auto& o : s.objects) {
    EXPECT_EQ(msk::closedMeshProblem(o.templ), "") << o.name;
    EXPECT_GT(msk::enclosedVolume(o.templ), 0) << o.name;
  }
  EXPECT_EQ(s.metadata.at("phantom").at("seed").asInt(), 1);
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
  std::set<std::pair<int, int>> distinct(s.collisions.begin(), s.collisions.end());
  EXPECT_EQ(distinct.size(), 6u);
  for (const auto& p : s.collisions) EXPECT_LT(p.first, p.second);
  for (size_t i = 0; i < s.objects.size(); ++i) {
    EXPECT_EQ(s.objects[i].label, static_cast<int>(i) + 1);
    EXPECT_EQ(msk::closedMeshProblem(s.objects[i].templ), "") << s.objects[i].name;
  }
}
