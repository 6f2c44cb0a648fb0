// mskseg segment end to end: outputs, report contents, and bad input.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "msk/core/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/tet_mesh_io.h"
#include "test_support.h"

namespace fs = std::filesystem;
using msk::test::runCli;

namespace {
const std::string kSample = std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1/";

std::string femurScene(const msk::test::ScratchDir& dir, const std::string& extra = "") {
  const std::string path = dir.file("scene.json");
  msk::test::writeBytes(path, "{\"objects\": [{\"name\": \"femur\", \"label\": 1, \"kind\": \"bone\", \"template\": \"" +
                                  kSample + "template_femur.vtk\"" + extra + "}]}");
  return path;
}
}  // namespace

TEST(SegmentCli, WritesMeshesLabelsReportAndPictures) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", femurScene(dir), "--out", out,
                         "--quality", "fast", "--mesh-space", "ras"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("level 1/1"), std::string::npos) << "progress on stderr";  // fast: one level
  for (const char* f : {"femur.vtk", "labels.nii.gz", "report.json", "qc/femur_axial.png", "qc/femur_coronal.png",
                        "qc/femur_sagittal.png"})
    EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
  msk::MeshSpace space = msk::MeshSpace::LPS;
  const msk::TriangleMesh m = msk::readMesh(out + "/femur.vtk", &space);
  EXPECT_EQ(space, msk::MeshSpace::RAS);
  EXPECT_EQ(m.pointData.count("displacement_mm"), 1u);
  EXPECT_EQ(m.pointData.count("image_residual_mm"), 1u);
  const msk::Json rep = msk::Json::readFile(out + "/report.json");
  EXPECT_EQ(rep.at("mskseg_version").asString(), MSK_VERSION);
  EXPECT_EQ(rep.at("parameters").at("quality").asString(), "fast");
  EXPECT_GT(rep.at("objects").asArray()[0].at("steps").asInt(), 0);
  EXPECT_GT(rep.at("objects").asArray()[0].at("volume_mm3").asNumber(), 50000.0);
  EXPECT_TRUE(rep.at("objects").asArray()[0].at("seconds_per_constraint_family").find("simplex-internal"));
  // The label map sits on the input grid with the input's affine, exactly.
  msk::Grid in, lab;
  const msk::NiftiInfo a = msk::readNiftiHeader(kSample + "image.nii.gz", &in);
  const msk::NiftiInfo b = msk::readNiftiHeader(out + "/labels.nii.gz", &lab);
  EXPECT_TRUE(in.sameGeometry(lab, 0.0));
  EXPECT_EQ(a.sform, b.sform);
}

TEST(SegmentCli, BadInputIsOneLineAndLeavesNoOutput) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  auto check = [&](const std::vector<std::string>& args, int code, const std::string& phrase) {
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, code) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(phrase), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
  };
  const std::string scene = femurScene(dir);
  check({"segment", "--image", dir.file("none.nii.gz"), "--scene", scene, "--out", out}, 1, "none.nii.gz");
  msk::test::writeBytes(dir.file("bad.json"), "{\"objects\": [{\"name\": \"femur\", \"lable\": 1}]}");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", dir.file("bad.json"), "--out", out}, 1, "lable");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--internal-stiffness", "-1"},
        2, "--internal-stiffness");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--quality", "ultra"}, 2,
        "ultra");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--collision-resolution",
         "parallel"},
        2, "--collision-resolution");
}

// A volumetric object (scene "model": {"volumetric": true}) also gets its tet mesh written as an LPS-tagged .vtu
// when none of its tets is inverted (else a warning and the count in the report, and no file); the report says what
// was built; without the key nothing volumetric is built.
TEST(SegmentCli, VolumetricObjectWritesItsTetMesh) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene",
                         femurScene(dir, ", \"model\": {\"volumetric\": true, \"volume_stiffness\": 0.5}"), "--out", out});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json rep = msk::Json::readFile(out + "/report.json");
  EXPECT_EQ(rep.at("volume_models_built").asInt(), 1);
  const msk::Json& vm = rep.at("objects").asArray()[0].at("volume_model");
  EXPECT_GT(vm.at("tets").asInt(), 1000);
  const int inverted = vm.at("inverted_tets").asInt();
  std::printf("femur volume model: %d tets, %d inverted, volume change %+.2f %%\n", vm.at("tets").asInt(), inverted,
              vm.at("volume_change_percent").asNumber());
  EXPECT_LT(inverted, vm.at("tets").asInt() / 100);
  if (inverted == 0) {
    msk::MeshSpace space = msk::MeshSpace::RAS;
    const msk::TetMesh tets = msk::readTetMesh(out + "/femur.vtu", &space);
    EXPECT_EQ(space, msk::MeshSpace::LPS);
    EXPECT_EQ(msk::tetMeshProblem(tets), "");
    EXPECT_EQ(vm.at("mesh").asString(), "femur.vtu");
  } else {
    EXPECT_FALSE(fs::exists(out + "/femur.vtu"));
    EXPECT_NE(r.err.find("femur.vtu not written"), std::string::npos) << r.err;
  }
  const auto plain = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", femurScene(dir), "--out",
                             dir.file("plain"), "--quality", "fast"});
  ASSERT_EQ(plain.exitCode, 0) << plain.err;
  EXPECT_FALSE(fs::exists(dir.file("plain") + "/femur.vtu"));
  EXPECT_EQ(msk::Json::readFile(dir.file("plain") + "/report.json").at("volume_models_built").asInt(), 0);
}
