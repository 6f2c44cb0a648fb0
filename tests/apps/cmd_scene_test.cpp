// mskseg scene: scene.json and templates from a label map's labels, ready for segment; mirroring; bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/scene.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::runCli;

namespace {
const std::string kSample = msk::test::bundledSample();
}

// Templates of the phantom's femur and quadriceps from its own labels: the scene loads, the templates enclose the
// labels' volumes, and `segment` runs on it (the templates start on the truth, so the result stays there).
TEST(SceneCli, BuildsASceneThatSegmentRuns) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("scene");
  auto r = runCli(
      {"scene", "--labels", kSample + "labels.nii.gz", "--objects", "femur:1:bone,quadriceps:2:muscle", "--out", out});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Scene scene = msk::loadScene(out + "/scene.json");
  ASSERT_EQ(scene.objects.size(), 2u);
  EXPECT_EQ(scene.objects[0].name, "femur");
  EXPECT_EQ(scene.objects[0].kind, msk::ObjectKind::Bone);
  EXPECT_EQ(scene.objects[1].label, 2);
  EXPECT_EQ(scene.objects[1].kind, msk::ObjectKind::Muscle);
  EXPECT_EQ(scene.collisions.size(), 1u) << "\"auto\": femur and quadriceps touch";
  const msk::Json json = msk::readJsonFile(out + "/scene.json");
  EXPECT_EQ(msk::jsonMember(json.at("objects")[0], "profiles_from"), nullptr) << "not mirrored: no profile source";

  r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", out + "/scene.json", "--out",
              dir.file("result"), "--quality", "fast", "--no-qc"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = runCli({"eval", "--result", dir.file("result/labels.nii.gz"), "--reference", kSample + "labels.nii.gz",
              "--labels", "1,2", "--json", dir.file("m.json")});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json metrics = msk::readJsonFile(dir.file("m.json"));
  for (const msk::Json& m : metrics.at("metrics"))
    EXPECT_GT(m.at("dice").get<double>(), 0.95) << m.at("object").get<std::string>();
}

// --mirror-x reflects every template across x = MM and gives each object the profile force learning where it came
// from; --refine-bones and --collisions all are written as asked.
TEST(SceneCli, MirroredTemplatesLearnTheirProfilesWhereTheyCameFrom) {
  msk::test::ScratchDir dir;
  const std::string plain = dir.file("plain"), mirrored = dir.file("mirrored");
  ASSERT_EQ(
      runCli({"scene", "--labels", kSample + "labels.nii.gz", "--objects", "femur:1:bone", "--out", plain}).exitCode,
      0);
  const auto r =
      runCli({"scene", "--labels", kSample + "labels.nii.gz", "--objects", "femur_other:7:1:bone,hamstrings:3:muscle",
              "--mirror-x", "10", "--collisions", "all", "--refine-bones", "--out", mirrored});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::TriangleMesh a = msk::readMesh(plain + "/templates/femur.vtk");
  const msk::TriangleMesh b = msk::readMesh(mirrored + "/templates/femur_other.vtk");
  ASSERT_EQ(a.vertexCount(), b.vertexCount());
  const double xa = a.vertices.col(0).mean(), xb = b.vertices.col(0).mean();
  EXPECT_NEAR(xb, 20.0 - xa, 1e-6) << "mirrored across x = 10 mm";
  EXPECT_NEAR(a.vertices.col(1).mean(), b.vertices.col(1).mean(), 1e-6);
  const msk::Json json = msk::readJsonFile(mirrored + "/scene.json");
  const msk::Json& femur = json.at("objects")[0];
  EXPECT_EQ(femur.at("label").get<int>(), 7);
  EXPECT_EQ(femur.at("force").get<std::string>(), "profile");
  EXPECT_DOUBLE_EQ(femur.at("profiles_from").at("mirror_x").get<double>(), 10.0);
  EXPECT_TRUE(femur.at("model").at("refine").get<bool>());
  EXPECT_EQ(msk::jsonMember(json.at("objects")[1], "model"), nullptr) << "a muscle does not refine";
  EXPECT_EQ(json.at("collisions").size(), 1u);
  const msk::Scene scene = msk::loadScene(mirrored + "/scene.json");
  EXPECT_EQ(scene.objects.size(), 2u);
}

// Bad input: one line, the right exit code, no output folder.
TEST(SceneCli, BadInputIsOneLineAndLeavesNoOutput) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("scene");
  auto check = [&](const std::vector<std::string>& extra, int code, const std::string& file,
                   const std::string& phrase) {
    std::vector<std::string> args = {"scene", "--labels", kSample + "labels.nii.gz", "--out", out};
    args.insert(args.end(), extra.begin(), extra.end());
    msk::test::expectOneLineError(runCli(args), code, file, phrase);
    EXPECT_FALSE(fs::exists(out)) << phrase;
  };
  check({"--objects", "femur:1:bone,tibia:9:bone"}, 1, "labels.nii.gz",
        "label 9 not found (labels present: 1, 2, 3, 4)");
  check({"--objects", "femur"}, 2, "", "NAME:LABEL");
  check({"--objects", "femur:1,quads:1"}, 2, "", "also femur's");
  check({"--objects", "femur:1:bone,femur:2"}, 2, "", "given twice");
  check({"--objects", "femur:1:bones"}, 2, "", "not a label");
  check({"--objects", "femur:1", "--mirror-x", "0", "--midline-label", "2"}, 2, "",
        "--mirror-x excludes --midline-label");
  check({"--objects", "femur:1", "--collisions", "some"}, 2, "", "--collisions");
}
