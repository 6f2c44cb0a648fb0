// Collision response chosen per scene pair (mode, target, "resolution"): the scene validates the resolution key, and
// the bundled thigh scene segmented with velocity-mode contacts and with the global resolution keeps its objects
// apart and as accurate as the default (position, spring, sequential), and report settings say what each pair used.
// The thigh runs are shared with bench/phantom_bench.cpp, which reports their figures (BM_ThighSceneCollisionModes).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segment_report.h"
#include "msk/segmentation/segmenter.h"
#include "msk/test/files.h"
#include "msk/test/phantom_scenarios.h"

namespace {

std::string twoObjects(const std::string& collisions) {
  return R"({"objects": [
      {"name": "femur", "label": 1, "kind": "bone", "template": "a.vtk"},
      {"name": "quadriceps", "label": 2, "kind": "muscle", "template": "b.vtk"}],
    "collisions": )" +
         collisions + "}";
}

}  // namespace

// "resolution" per pair (and per auto entry): "sequential" or "global"; anything else names the key, the entry and
// the pair; unset leaves it to the run.
TEST(CollisionResponseScene, ResolutionKeyIsReadAndValidated) {
  msk::test::ScratchDir dir;
  msk::writeMesh(dir.file("a.vtk"), msk::makeIcosphere(10, 2));
  msk::writeMesh(dir.file("b.vtk"), msk::makeIcosphere(5, 2, Eigen::Vector3d(30, 0, 0)));
  auto write = [&](const std::string& text) {
    msk::test::writeBytes(dir.file("scene.json"), text);
    return dir.file("scene.json");
  };
  const msk::Scene plain = msk::loadScene(write(twoObjects(R"([["femur", "quadriceps"]])")));
  ASSERT_EQ(plain.collisions.size(), 1u);
  EXPECT_FALSE(plain.collisions[0].resolution.has_value());
  const msk::Scene global = msk::loadScene(write(twoObjects(
      R"([{"pair": ["femur", "quadriceps"], "mode": "velocity", "target": "reaction", "resolution": "global"}])")));
  ASSERT_EQ(global.collisions.size(), 1u);
  EXPECT_EQ(global.collisions[0].resolution, msk::CollisionResolution::Global);
  EXPECT_EQ(global.collisions[0].mode, msk::CollisionMode::Velocity);
  EXPECT_EQ(global.collisions[0].target, msk::CollisionTarget::Reaction);
  const msk::Scene autoScene =
      msk::loadScene(write(twoObjects(R"([{"auto": true, "within_mm": 30, "resolution": "sequential"}])")));
  ASSERT_EQ(autoScene.collisions.size(), 1u);
  EXPECT_EQ(autoScene.collisions[0].resolution, msk::CollisionResolution::Sequential);

  struct Bad {
    std::string collisions, phrase;
  };
  const std::vector<Bad> bad = {
      {R"([{"pair": ["femur", "quadriceps"], "resolution": "parallel"}])",
       "collisions[0] (femur, quadriceps): \"resolution\" must be one of sequential, global, found \"parallel\""},
      {R"([{"pair": ["femur", "quadriceps"], "resolution": 2}])",
       "collisions[0] (femur, quadriceps): \"resolution\" must be a string"},
      {R"([{"auto": true, "resolution": "Global"}])",
       "collisions[0]: \"resolution\" must be one of sequential, global"},
      {R"([{"pair": ["femur", "quadriceps"], "resolve": "global"}])",
       "collisions[0] (femur, quadriceps): unknown key \"resolve\""},
  };
  for (const Bad& b : bad) {
    const std::string path = write(twoObjects(b.collisions));
    try {
      msk::loadScene(path);
      ADD_FAILURE() << "no error for " << b.collisions;
    } catch (const msk::IoError& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_NE(std::string(e.what()).find(b.phrase), std::string::npos)
          << "wanted '" << b.phrase << "' in: " << e.what();
    }
  }
}

// The bundled thigh scene with every pair in velocity mode, and with every pair resolved globally: no voxel carries
// two labels, Dice per object stays at the default's level (femur 0.978, quadriceps 0.968, hamstrings 0.968, adductors
// 0.972 with position, spring, sequential; docs/measurements.md), and the settings written to report.json name each
// pair's response.
TEST(CollisionResponseScene, ThighSceneUnderVelocityModeAndGlobalResolution) {
  const msk::test::BundledThigh thigh = msk::test::loadBundledThigh();
  const double defaultDice[4] = {0.978, 0.968, 0.968, 0.972};
  for (const msk::test::ThighCollisionCase& c : msk::test::thighCollisionCases()) {
    msk::Scene scene = thigh.scene;
    ASSERT_EQ(scene.collisions.size(), 6u);
    for (msk::CollisionPair& p : scene.collisions) p.mode = c.mode;
    msk::SegmentOptions opts;
    opts.collision.resolution = c.resolution;  // no pair sets its own
    const msk::test::ThighRun run = msk::test::segmentThigh(thigh, scene, opts);
    const msk::SegmentationResult& res = run.res;
    for (size_t i = 0; i < 4; ++i)
      EXPECT_GT(run.dice[i], defaultDice[i] - 0.01) << c.name << " " << res.objects[i].name;
    EXPECT_EQ(res.overlapVoxels, 0u) << c.name;
    for (double d : res.pairPenetrationMm) EXPECT_LE(d, 0.1) << c.name;
    const msk::Json j = msk::settingsJson(opts, res);
    const msk::Json& modes = j.at("collision_mode");
    ASSERT_TRUE(modes.is_array());
    ASSERT_EQ(modes.size(), 6u);
    for (const msk::Json& m : modes) {
      EXPECT_EQ(m.at("mode").get<std::string>(), msk::collisionModeName(c.mode));
      EXPECT_EQ(m.at("target").get<std::string>(), "spring");
      EXPECT_EQ(m.at("resolution").get<std::string>(), msk::collisionResolutionName(c.resolution));
    }
    EXPECT_EQ(modes[0].at("objects")[0].get<std::string>(), "femur");
  }
}
