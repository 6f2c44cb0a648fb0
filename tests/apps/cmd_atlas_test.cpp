// End-to-end tests of `mskseg atlas` and `mskseg segment --atlas`: a complete, checked atlas folder from the bundled
// sample; an atlas folder that is incomplete, of another format version or changed after it was built refused with
// one line naming the file and nothing written; malformed object lists and labels refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "msk/imaging/checksum.h"
#include "msk/imaging/json.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::CliResult;
using msk::test::expectOneLineError;
using msk::test::runCli;
using msk::test::ScratchDir;

namespace {

const std::string kSample = msk::test::bundledSample();
const std::string kObjects = "femur:1:bone,quadriceps:2:muscle,hamstrings:3:muscle,adductors:4:muscle";

/// Builds an atlas of the bundled sample with small templates into `dir`/atlas.
std::string buildSampleAtlas(const ScratchDir& dir) {
  const std::string out = dir.file("atlas");
  const CliResult r = runCli({"atlas", "--image", kSample + "image.nii.gz", "--labels", kSample + "labels.nii.gz",
                              "--objects", kObjects, "--vertices", "600", "--out", out, "--quiet"});
  EXPECT_EQ(r.exitCode, 0) << r.err;
  return out;
}

}  // namespace

TEST(AtlasCli, SampleAtlasIsCompleteWithChecksumsAndAReadableScene) {
  ScratchDir dir;
  const std::string atlas = buildSampleAtlas(dir);
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(atlas)) files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files,
            (std::vector<std::string>{"atlas.json", "reference.nii.gz", "scene.json", "template_adductors.vtk",
                                      "template_femur.vtk", "template_hamstrings.vtk", "template_quadriceps.vtk"}));
  const msk::Json meta = msk::readJsonFile(atlas + "/atlas.json");
  EXPECT_EQ(meta["format"], "mskseg-atlas");
  EXPECT_EQ(meta["format_version"], 1);
  EXPECT_EQ(meta["modality"], "mr");
  ASSERT_EQ(meta["objects"].size(), 4u);
  EXPECT_EQ(meta["objects"][0]["name"], "femur");
  EXPECT_EQ(meta["objects"][0]["kind"], "bone");
  EXPECT_EQ(meta["objects"][0]["colour"].size(), 3u);
  EXPECT_EQ(meta["sources"][0]["labels_sha256"], msk::sha256File(kSample + "labels.nii.gz"));
  for (const auto& kv : meta["files_sha256"].items())
    EXPECT_EQ(kv.value(), msk::sha256File(atlas + "/" + kv.key())) << kv.key();
  EXPECT_EQ(meta["files_sha256"].size(), 6u);
  // The reference is the image cropped to the objects plus the margin: smaller, same voxel size.
  const msk::ImageF image = msk::readNifti<float>(kSample + "image.nii.gz");
  const msk::ImageF reference = msk::readNifti<float>(atlas + "/reference.nii.gz");
  EXPECT_LE(reference.grid.voxelCount(), image.grid.voxelCount());
  EXPECT_TRUE(reference.grid.spacing.isApprox(image.grid.spacing, 1e-6));
  // The scene learns every object's profiles on the reference.
  const msk::Json scene = msk::readJsonFile(atlas + "/scene.json");
  for (const msk::Json& o : scene["objects"]) {
    EXPECT_EQ(o["force"], "profile") << o["name"];
    EXPECT_EQ(o["profiles_from"]["image"], "reference.nii.gz") << o["name"];
  }
  EXPECT_EQ(scene["collisions"], "auto");
}

TEST(AtlasCli, BrokenAtlasFoldersAreOneLineNamingTheFileAndNothingIsWritten) {
  ScratchDir dir;
  const std::string atlas = buildSampleAtlas(dir);
  const std::string out = dir.file("result");
  auto segment = [&](const std::string& folder) {
    return runCli({"segment", "--image", kSample + "image.nii.gz", "--atlas", folder, "--out", out});
  };
  auto copyOf = [&](const std::string& name) {
    const std::string copy = dir.file(name);
    fs::copy(atlas, copy, fs::copy_options::recursive);
    return copy;
  };
  // Incomplete: a template missing.
  const std::string incomplete = copyOf("incomplete");
  fs::remove(incomplete + "/template_hamstrings.vtk");
  expectOneLineError(segment(incomplete), 1, "template_hamstrings.vtk", "missing from the atlas");
  // Another format version.
  const std::string future = copyOf("future");
  msk::Json meta = msk::readJsonFile(future + "/atlas.json");
  meta["format_version"] = 2;
  msk::writeJsonFile(future + "/atlas.json", meta);
  expectOneLineError(segment(future), 1, "atlas.json", "format version 2");
  // A file changed after the atlas was built.
  const std::string changed = copyOf("changed");
  msk::Json scene = msk::readJsonFile(changed + "/scene.json");
  scene["objects"][0]["polarity"] = "bright-inside";
  msk::writeJsonFile(changed + "/scene.json", scene);
  expectOneLineError(segment(changed), 1, "scene.json", "checksum does not match");
  // Not an atlas at all.
  expectOneLineError(segment(dir.file("nowhere")), 1, "nowhere", "not a folder");
  EXPECT_FALSE(fs::exists(out)) << "partial output";
}

TEST(AtlasCli, BadObjectListsAndLabelsAreRefused) {
  ScratchDir dir;
  const std::string out = dir.file("atlas");
  auto atlas = [&](const std::string& objects, const std::string& labels) {
    return runCli(
        {"atlas", "--image", kSample + "image.nii.gz", "--labels", labels, "--objects", objects, "--out", out});
  };
  const std::string labels = kSample + "labels.nii.gz";
  expectOneLineError(atlas("femur", labels), 2, "--objects", "NAME:LABEL");
  expectOneLineError(atlas("femur:0:bone", labels), 2, "--objects", "1..32767");
  expectOneLineError(atlas("femur:1:cartilage", labels), 2, "--objects", "bone, muscle or generic");
  expectOneLineError(atlas("femur:1,femur:2", labels), 2, "--objects", "duplicate name");
  expectOneLineError(atlas("../femur:1", labels), 2, "--objects", "names are");
  expectOneLineError(atlas("femur:9", labels), 1, "labels.nii.gz", "label 9 (femur) not found");
  // Labels on another grid than the image.
  msk::LabelMap other = msk::readNifti<int32_t>(labels);
  other.grid.origin.x() += 5;
  msk::writeNifti(dir.file("shifted.nii.gz"), other, msk::DataType::UInt8);
  expectOneLineError(atlas("femur:1", dir.file("shifted.nii.gz")), 1, "shifted.nii.gz", "not on the grid");
  EXPECT_FALSE(fs::exists(out)) << "partial output";
}

TEST(AtlasCli, BatchPlacesTheAtlasInEveryCase) {
  ScratchDir dir;
  const std::string atlas = buildSampleAtlas(dir);
  fs::create_directories(dir.file("cohort/a"));
  fs::copy_file(kSample + "image.nii.gz", dir.file("cohort/a/image.nii.gz"));
  const std::string out = dir.file("results");
  const CliResult r = runCli({"batch", "--cases", dir.file("cohort"), "--out", out, "--quiet", "--", "--atlas", atlas,
                              "--quality", "fast", "--no-qc"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json report = msk::readJsonFile(out + "/a/report.json");
  EXPECT_EQ(report["atlas"], fs::absolute(atlas).string());
  ASSERT_EQ(report["placement"]["objects"].size(), 4u);
  EXPECT_TRUE(fs::exists(out + "/a/placement.tfm"));
  EXPECT_EQ(msk::readJsonFile(out + "/batch.json")["atlas"], fs::absolute(atlas).string());
  // --atlas and --scene together is a usage error.
  const CliResult both = runCli({"batch", "--cases", dir.file("cohort"), "--out", dir.file("other"), "--atlas", atlas,
                                 "--scene", kSample + "scene.json"});
  EXPECT_EQ(both.exitCode, 2) << both.err;
  EXPECT_FALSE(fs::exists(dir.file("other")));
}
