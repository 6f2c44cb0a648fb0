// End-to-end tests of `mskseg atlas` and `mskseg segment --atlas`: a complete, checked atlas folder from the bundled
// sample, and one of two subjects; an atlas folder that is incomplete, of another format version or changed after it
// was built refused with one line naming the file and nothing written; malformed object lists and labels refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "msk/imaging/checksum.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
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
  EXPECT_EQ(meta["format_version"], 2);
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
  meta["format_version"] = 3;
  msk::writeJsonFile(future + "/atlas.json", meta);
  expectOneLineError(segment(future), 1, "atlas.json", "format version 3");
  // Version 1 (one subject, the same files) is still read.
  const std::string older = copyOf("older");
  meta["format_version"] = 1;
  msk::writeJsonFile(older + "/atlas.json", meta);
  const CliResult v1 = runCli({"segment", "--image", kSample + "image.nii.gz", "--atlas", older, "--out",
                               dir.file("from_v1"), "--quality", "fast", "--no-qc", "--quiet"});
  EXPECT_EQ(v1.exitCode, 0) << v1.err;
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

// The atlas's muscle templates are remeshed once per case, before the placement, through the template cache: a
// second case with the same cache reads them instead (three hits, no miss) and writes the same bytes; the report says
// each muscle's template was remeshed, the femur's not. The placed templates' coarser levels, which no other case
// would read, are not stored: the cache holds the three remeshed templates only.
TEST(AtlasCli, TemplatesAreRemeshedOnceThroughTheTemplateCache) {
  ScratchDir dir;
  const std::string atlas = buildSampleAtlas(dir), cache = dir.file("cache");
  auto segment = [&](const std::string& out) {
    const CliResult r = runCli({"segment", "--image", kSample + "image.nii.gz", "--atlas", atlas, "--out", out,
                                "--starts", "reference", "--no-qc", "--template-cache", cache, "--quiet"});
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return msk::readJsonFile(out + "/report.json");
  };
  const msk::Json first = segment(dir.file("first")), second = segment(dir.file("second"));
  EXPECT_EQ(first["template_cache"]["misses"], 3) << first["template_cache"].dump();
  EXPECT_EQ(first["template_cache"]["hits"], 0) << first["template_cache"].dump();
  EXPECT_EQ(second["template_cache"]["misses"], 0) << second["template_cache"].dump();
  EXPECT_EQ(second["template_cache"]["hits"], 3) << second["template_cache"].dump();
  for (const msk::Json& o : second["objects"]) EXPECT_EQ(o["template_remeshed"], o["name"] != "femur") << o["name"];
  EXPECT_EQ(msk::sha256File(dir.file("first") + "/labels.nii.gz"),
            msk::sha256File(dir.file("second") + "/labels.nii.gz"));
  size_t entries = 0;
  for (const auto& e : fs::recursive_directory_iterator(cache)) entries += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(entries, 3u);
}

// Two subjects: the bundled sample and phantom seed 3 posed. Every object gets a fitted template on the second subject
// (close to its labels' surface), the femur the two subjects' mean shape, the muscles the reference's own; the scene
// learns its profiles on both; every file is checksummed, a changed subject surface is refused, and the atlas
// segments the sample.
TEST(AtlasCli, AnAtlasOfTwoSubjectsFitsEachTemplateOntoTheSecondAndSegments) {
  ScratchDir dir;
  const std::string second = dir.file("seed3");
  ASSERT_EQ(runCli({"phantom", "--seed", "3", "--pose", "5,-4,6,8,-6,5,1.04", "--out", second, "--quiet"}).exitCode, 0);
  const std::string atlas = dir.file("atlas2");
  CliResult r = runCli({"atlas", "--image", kSample + "image.nii.gz", "--labels", kSample + "labels.nii.gz", "--image",
                        second + "/image.nii.gz", "--labels", second + "/labels.nii.gz", "--objects", kObjects,
                        "--vertices", "600", "--out", atlas, "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("from 2 subject(s)"), std::string::npos) << r.out;
  const msk::Json meta = msk::readJsonFile(atlas + "/atlas.json");
  EXPECT_EQ(meta["sources"].size(), 2u);
  EXPECT_EQ(meta["sources"][1]["labels_sha256"], msk::sha256File(second + "/labels.nii.gz"));
  EXPECT_EQ(meta["sources"][1]["stored_as"], "subject_2.nii.gz");
  for (const msk::Json& o : meta["objects"]) {
    ASSERT_EQ(o["subjects"].size(), 2u) << o["name"];
    const msk::Json& fit = o["subjects"][1];
    EXPECT_LT(fit["fit_mean_mm"].get<double>(), 0.5) << o["name"];  // templates of 600 vertices
    EXPECT_LT(fit["fit_reverse_mean_mm"].get<double>(), 0.5) << o["name"];
    EXPECT_NEAR(fit["fit_volume_ratio"].get<double>(), 1.0, 0.02) << o["name"];
    EXPECT_EQ(fit["fit_self_intersections"], 0) << o["name"];
    EXPECT_EQ(o["shape"].get<std::string>().rfind(o["kind"] == "bone" ? "the mean" : "the reference", 0), 0u)
        << o["name"];
  }
  // 4 templates, 2 subjects' surfaces of each, the second subject's image, the reference and the scene.
  EXPECT_EQ(meta["files_sha256"].size(), 4u + 8u + 3u);
  for (const auto& kv : meta["files_sha256"].items())
    EXPECT_EQ(kv.value(), msk::sha256File(atlas + "/" + kv.key())) << kv.key();
  const msk::Json scene = msk::readJsonFile(atlas + "/scene.json");
  for (const msk::Json& o : scene["objects"]) {
    ASSERT_EQ(o["profiles_from"]["subjects"].size(), 2u) << o["name"];
    EXPECT_EQ(o["profiles_from"]["subjects"][1]["image"], "subject_2.nii.gz");
  }
  // The mean femur differs from the reference's own; each surface keeps the template's vertices.
  const msk::TriangleMesh femur = msk::readMesh(atlas + "/template_femur.vtk");
  const msk::TriangleMesh own = msk::readMesh(atlas + "/subject_1_femur.vtk");
  const msk::TriangleMesh fitted = msk::readMesh(atlas + "/subject_2_femur.vtk");
  ASSERT_EQ(femur.vertexCount(), own.vertexCount());
  ASSERT_EQ(femur.vertexCount(), fitted.vertexCount());
  EXPECT_GT((femur.vertices - own.vertices).rowwise().norm().maxCoeff(), 0.1);

  const std::string out = dir.file("result");
  r = runCli(
      {"segment", "--image", kSample + "image.nii.gz", "--atlas", atlas, "--out", out, "--quality", "fast", "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json report = msk::readJsonFile(out + "/report.json");
  EXPECT_EQ(report["status"], "ok");
  // A run from each subject; on the reference's own image every object keeps the reference's start (its own
  // templates match its own appearance best).
  const msk::Json& starts = report["placement"]["starts"];
  ASSERT_EQ(starts["runs"].size(), 2u) << report["placement"].dump();
  for (const msk::Json& run : starts["runs"]) {
    ASSERT_EQ(run["objects"].size(), 4u);
    for (const auto& kv : run["objects"].items()) EXPECT_GT(kv.value()["profile_match"].get<double>(), 0.5) << kv.key();
  }
  for (const auto& kv : starts["start_of_each_object"].items()) EXPECT_EQ(kv.value(), 1) << kv.key();
  r = runCli({"eval", "--result", out + "/labels.nii.gz", "--reference", kSample + "labels.nii.gz"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::istringstream table(r.out);
  std::string line;
  int scored = 0;
  std::getline(table, line);  // the header
  while (std::getline(table, line)) {
    std::istringstream row(line);
    std::string name;
    double dice = 0;
    if (row >> name >> dice) {
      EXPECT_GE(dice, 0.9) << line;
      ++scored;
    }
  }
  EXPECT_EQ(scored, 4) << r.out;

  // --starts reference: one run, from the reference.
  const std::string one = dir.file("one");
  r = runCli({"segment", "--image", kSample + "image.nii.gz", "--atlas", atlas, "--out", one, "--quality", "fast",
              "--starts", "reference", "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_FALSE(msk::readJsonFile(one + "/report.json")["placement"].contains("starts"));

  // A subject's surface changed after the atlas was built is refused, naming it.
  const std::string changed = dir.file("changed");
  fs::copy(atlas, changed, fs::copy_options::recursive);
  msk::TriangleMesh moved = fitted;
  moved.vertices.col(0).array() += 1.0;
  msk::writeMesh(changed + "/subject_2_femur.vtk", moved, msk::MeshSpace::LPS);
  expectOneLineError(
      runCli({"segment", "--image", kSample + "image.nii.gz", "--atlas", changed, "--out", dir.file("refused")}), 1,
      "subject_2_femur.vtk", "checksum does not match");
  EXPECT_FALSE(fs::exists(dir.file("refused")));
  // --image and --labels in pairs.
  expectOneLineError(runCli({"atlas", "--image", kSample + "image.nii.gz", "--labels", kSample + "labels.nii.gz",
                             "--image", second + "/image.nii.gz", "--objects", kObjects, "--out", dir.file("odd")}),
                     2, "--labels", "one per --image");
  EXPECT_FALSE(fs::exists(dir.file("odd")));
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
  // segment's --starts passed on, checked before any case runs.
  const CliResult starts = runCli(
      {"batch", "--cases", dir.file("cohort"), "--out", dir.file("other"), "--", "--atlas", atlas, "--starts", "all"});
  EXPECT_EQ(starts.exitCode, 2) << starts.err;
  EXPECT_NE(starts.err.find("--starts"), std::string::npos) << starts.err;
  EXPECT_FALSE(fs::exists(dir.file("other")));
}
