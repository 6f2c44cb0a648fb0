// mskseg batch end to end: every case of a cohort folder, per-case failures, resuming, the summary tables.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "msk/imaging/json.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::runCli;

namespace {
const std::string kSample = msk::test::bundledSample();

std::string femurScene(const std::string& path, const std::string& name) {
  msk::test::writeBytes(path, "{\"objects\": [{\"name\": \"" + name + "\", \"label\": 1, \"kind\": \"bone\", " +
                                  "\"template\": \"" + kSample + "template_femur.vtk\"}]}");
  return path;
}

/// A case folder holding the bundled sample's image and labels (links, not copies).
void sampleCase(const std::string& dir) {
  fs::create_directories(dir);
  fs::create_symlink(kSample + "image.nii.gz", dir + "/image.nii.gz");
  fs::create_symlink(kSample + "labels.nii.gz", dir + "/labels.nii.gz");
}

/// The rows of a CSV file (no quoted commas in the fields read here), header first.
std::vector<std::vector<std::string>> csvRows(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(msk::test::readBytes(path));
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::istringstream l(line);
    std::string f;
    while (std::getline(l, f, ',')) fields.push_back(f);
    if (!line.empty() && line.back() == ',') fields.push_back("");
    rows.push_back(fields);
  }
  return rows;
}
}  // namespace

// Four folders: two good cases (one with its own scene.json), a truncated image, a folder without an image. The good
// cases are segmented and scored, the bad one fails alone with the reader's message and leaves no output folder, the
// empty one is listed; a rerun skips what is done and runs the repaired case.
TEST(BatchCli, RunsEveryCaseReportsFailuresAndResumes) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  sampleCase(cases + "/p01");
  sampleCase(cases + "/p02");
  femurScene(cases + "/p02/scene.json", "femur_own_scene");
  fs::create_directories(cases + "/p03");
  const std::string image = msk::test::readBytes(kSample + "image.nii.gz");
  msk::test::writeBytes(cases + "/p03/image.nii.gz", image.substr(0, image.size() / 3));
  fs::create_directories(cases + "/notes");
  const std::string scene = femurScene(dir.file("scene.json"), "femur");

  const std::vector<std::string> args = {"batch", "--cases", cases,         "--scene",       scene,
                                         "--out", out,       "--reference", "labels.nii.gz", "--jobs",
                                         "2",     "--",      "--quality",   "fast",          "--no-qc"};
  auto r = runCli(args);
  EXPECT_EQ(r.exitCode, 1) << r.err;  // one case failed
  EXPECT_NE(r.err.find("[3/3]"), std::string::npos) << "progress per case on stderr:\n" << r.err;
  auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[0][0], "case");
  EXPECT_EQ(rows[1][0], "notes");
  EXPECT_EQ(rows[1][1], "skipped");
  EXPECT_EQ(rows[0][2], "quality");
  for (size_t i : {2u, 3u}) {
    EXPECT_EQ(rows[i][1], "ok") << rows[i][0];
    EXPECT_EQ(rows[i][2], "ok") << rows[i][0] << ": the segmentation's quality status";
    EXPECT_EQ(rows[i][3], "0");
    EXPECT_GT(std::stod(rows[i][6]), 0.0) << "the largest mean image residual, read from the case's report";
    EXPECT_EQ(rows[i][8], "0") << "voxels inside two objects";
    EXPECT_GT(std::stod(rows[i][10]), 0.95) << "mean Dice of " << rows[i][0];
  }
  EXPECT_EQ(rows[4][0], "p03");
  EXPECT_EQ(rows[4][1], "failed");
  EXPECT_EQ(rows[4][3], "1");
  EXPECT_NE(rows[4][12].find("p03/image.nii.gz"), std::string::npos) << rows[4][12];
  EXPECT_NE(rows[4][12].find("truncated"), std::string::npos) << rows[4][12];
  EXPECT_TRUE(fs::exists(out + "/p01/report.json"));
  EXPECT_TRUE(fs::exists(out + "/p02/femur_own_scene.vtk"));  // the case's own scene
  EXPECT_FALSE(fs::exists(out + "/p03"));
  EXPECT_TRUE(fs::exists(out + "/logs/p03.log"));
  const auto metrics = csvRows(out + "/metrics.csv");
  ASSERT_EQ(metrics.size(), 3u);
  EXPECT_EQ(metrics[2][1], "femur_own_scene");
  const msk::Json report = msk::readJsonFile(out + "/p01/report.json");
  EXPECT_EQ(report.at("parameters").at("quality").get<std::string>(),
            "fast");  // the forwarded options reached the case
  const msk::Json batch = msk::readJsonFile(out + "/batch.json");
  EXPECT_EQ(batch.at("cases").at("ok").get<int>(), 2);
  EXPECT_EQ(batch.at("cases").at("failed").get<int>(), 1);
  EXPECT_EQ(batch.at("cases").at("skipped_no_image").get<int>(), 1);

  // Repair p03 and rerun: p01 and p02 are not run again (their results stay as they were), p03 now succeeds; the
  // staging folder a killed run would have left for p03 is removed.
  const auto written = fs::last_write_time(out + "/p01/report.json");
  fs::create_directories(out + "/.p03.partial999999999/qc");
  fs::remove(cases + "/p03/image.nii.gz");
  fs::create_symlink(kSample + "image.nii.gz", cases + "/p03/image.nii.gz");
  r = runCli(args);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("2 done by an earlier run"), std::string::npos) << r.err;
  EXPECT_EQ(fs::last_write_time(out + "/p01/report.json"), written);
  rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[2][1], "done");
  EXPECT_GT(std::stod(rows[2][10]), 0.95) << "a case done earlier is still scored";
  EXPECT_EQ(rows[4][1], "ok");
  EXPECT_TRUE(fs::exists(out + "/p03/report.json"));
  EXPECT_FALSE(fs::exists(out + "/.p03.partial999999999"));
  // The cases share one template cache in the output folder (a bone's template at the fast preset derives nothing;
  // SegmentCli.MuscleTemplatesAreRemeshedAndTheReportCountsCrossingFaces reuses a remeshed muscle).
  const msk::Json cache = msk::readJsonFile(out + "/p03/report.json").at("template_cache");
  EXPECT_EQ(fs::path(cache.at("folder").get<std::string>()), fs::absolute(out) / ".template-cache") << cache.dump();
}

// A mistake in the batch's own options or in those it forwards to every case is one line, exit code 2 (1 for a
// missing folder), before any case runs or anything is written.
TEST(BatchCli, BadOptionsStopBeforeAnythingIsWritten) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  sampleCase(cases + "/p01");
  const std::string scene = femurScene(dir.file("scene.json"), "femur");
  auto check = [&](std::vector<std::string> extra, int code, const std::string& phrase) {
    std::vector<std::string> args = {"batch", "--cases", cases, "--scene", scene, "--out", out};
    args.insert(args.end(), extra.begin(), extra.end());
    msk::test::expectOneLineError(runCli(args), code, "", phrase);
    EXPECT_FALSE(fs::exists(out)) << phrase;
  };
  check({"--", "--quality", "ultra"}, 2, "ultra");
  check({"--", "--internal-stiffness", "-1"}, 2, "--internal-stiffness");
  check({"--", "--out", dir.file("x")}, 2, "--out");
  check({"--", "--no-such-option"}, 2, "--no-such-option");
  check({"--jobs", "0"}, 2, "--jobs");
  msk::test::expectOneLineError(runCli({"batch", "--cases", dir.file("none"), "--scene", scene, "--out", out}), 1,
                                "none", "no such folder");
  msk::test::expectOneLineError(runCli({"batch", "--cases", cases, "--scene", dir.file("none.json"), "--out", out}), 1,
                                "none.json", "no such file");
  msk::test::expectOneLineError(runCli({"batch", "--cases", cases, "--out", out}), 2, "", "--scene");
  fs::create_directories(dir.file("empty"));
  msk::test::expectOneLineError(runCli({"batch", "--cases", dir.file("empty"), "--scene", scene, "--out", out}), 1,
                                "empty", "no case");
  EXPECT_FALSE(fs::exists(out));
}

// --image and --reference may be shell patterns matching one file per case: a folder with none is skipped, one with
// two is a failed case naming both.
TEST(BatchCli, ImagePatternsFindOneFilePerCase) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  fs::create_directories(cases + "/sub-01");
  fs::create_symlink(kSample + "image.nii.gz", cases + "/sub-01/sub-01_T1w.nii.gz");
  fs::create_symlink(kSample + "labels.nii.gz", cases + "/sub-01/sub-01_dseg.nii.gz");
  fs::create_directories(cases + "/sub-02");
  fs::create_symlink(kSample + "image.nii.gz", cases + "/sub-02/sub-02_run-1_T1w.nii.gz");
  fs::create_symlink(kSample + "image.nii.gz", cases + "/sub-02/sub-02_run-2_T1w.nii.gz");
  fs::create_directories(cases + "/sub-03");
  msk::test::writeBytes(cases + "/sub-03/notes.txt", "no scan");
  const auto r =
      runCli({"batch", "--cases", cases, "--scene", femurScene(dir.file("scene.json"), "femur"), "--out", out,
              "--image", "*_T1w.nii.gz", "--reference", "*_dseg.nii.gz", "--", "--quality", "fast", "--no-qc"});
  EXPECT_EQ(r.exitCode, 1) << r.err;
  const auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1][1], "ok");
  EXPECT_GT(std::stod(rows[1][10]), 0.95) << "scored against the file matching *_dseg.nii.gz";
  EXPECT_EQ(rows[2][1], "failed");
  EXPECT_NE(rows[2][12].find("2 files match"), std::string::npos) << rows[2][12];
  EXPECT_EQ(rows[3][1], "skipped");
  EXPECT_NE(rows[3][12].find("no file matches"), std::string::npos) << rows[3][12];
}

// A pattern may name a subfolder of the case folder (BIDS-like anat/); one that would leave the case folder is refused.
TEST(BatchCli, ImagePatternsMayNameSubfolders) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  fs::create_directories(cases + "/sub-01/anat");
  fs::create_symlink(kSample + "image.nii.gz", cases + "/sub-01/anat/sub-01_T1w.nii.gz");
  const std::string scene = femurScene(dir.file("scene.json"), "femur");
  auto r = runCli({"batch", "--cases", cases, "--scene", scene, "--out", out, "--image", "anat/*_T1w.nii.gz", "--",
                   "--quality", "fast", "--no-qc"});
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(out + "/sub-01/report.json"));
  for (const std::string bad : {"../sub-01/anat/sub-01_T1w.nii.gz", "/etc/passwd"}) {
    r = runCli({"batch", "--cases", cases, "--scene", scene, "--out", dir.file("out2"), "--image", bad});
    EXPECT_EQ(r.exitCode, 2) << bad << ": " << r.err;
    EXPECT_NE(r.err.find("inside each case folder"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out2")));
  }
}

// A rerun keeps the figures of the cases it skips; a case whose inputs changed (here the options passed to segment)
// runs again, or with --keep-stale is kept and marked stale, never silently kept.
TEST(BatchCli, RerunsKeepFiguresAndRedoWhatOtherInputsProduced) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  sampleCase(cases + "/p01");
  const std::vector<std::string> base = {
      "batch", "--cases", cases, "--scene", femurScene(dir.file("scene.json"), "femur"), "--out", out};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  auto r = runCli(with({"--", "--quality", "fast", "--no-qc"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto first = csvRows(out + "/summary.csv");
  ASSERT_EQ(first.size(), 2u);
  const auto written = fs::last_write_time(out + "/p01/report.json");

  r = runCli(with({"--", "--quality", "fast", "--no-qc"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto rows = csvRows(out + "/summary.csv");
  EXPECT_EQ(rows[1][1], "done");
  for (size_t col : {3u, 4u, 5u}) EXPECT_EQ(rows[1][col], first[1][col]) << "column " << rows[0][col] << " kept";
  EXPECT_EQ(fs::last_write_time(out + "/p01/report.json"), written);

  r = runCli(with({"--keep-stale", "--", "--quality", "fast", "--no-qc", "--steps", "3"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  rows = csvRows(out + "/summary.csv");
  EXPECT_EQ(rows[1][1], "stale");
  EXPECT_EQ(fs::last_write_time(out + "/p01/report.json"), written);
  EXPECT_EQ(msk::readJsonFile(out + "/batch.json").at("cases").at("stale_kept").get<int>(), 1);

  r = runCli(with({"--", "--quality", "fast", "--no-qc", "--steps", "3"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("p01: runs again"), std::string::npos) << r.err;
  rows = csvRows(out + "/summary.csv");
  EXPECT_EQ(rows[1][1], "ok");
  EXPECT_EQ(msk::readJsonFile(out + "/p01/report.json").at("parameters").at("max_steps_per_level").get<int>(), 3);
}

namespace {
/// The entities of a BIDS file name ("sub-01_ses-2_label-femur_desc-mskseg_dseg.nii.gz" -> sub=01, ses=2, label=femur,
/// desc=mskseg, and "suffix" = dseg, "extension" = .nii.gz); empty if the name does not follow the rules (key-value
/// pairs of letters and digits joined by _, then a suffix, then an extension).
std::map<std::string, std::string> bidsEntities(const std::string& name) {
  std::map<std::string, std::string> out;
  const size_t dot = name.find('.');
  if (dot == std::string::npos) return {};
  out["extension"] = name.substr(dot);
  std::vector<std::string> parts;
  std::istringstream in(name.substr(0, dot));
  std::string part;
  while (std::getline(in, part, '_')) parts.push_back(part);
  if (parts.size() < 2) return {};
  auto alnum = [](const std::string& v) {
    return !v.empty() &&
           std::all_of(v.begin(), v.end(), [](char ch) { return std::isalnum(static_cast<unsigned char>(ch)); });
  };
  for (size_t i = 0; i + 1 < parts.size(); ++i) {
    const size_t dash = parts[i].find('-');
    if (dash == std::string::npos) return {};
    const std::string key = parts[i].substr(0, dash), value = parts[i].substr(dash + 1);
    if (!alnum(key) || !alnum(value) || out.count(key)) return {};
    out[key] = value;
  }
  if (!alnum(parts.back())) return {};
  out["suffix"] = parts.back();
  if (parts[0].rfind("sub-", 0) != 0) return {};
  return out;
}
}  // namespace

// A BIDS dataset of three subjects, one with two sessions: every image is a case, the results follow the derivatives
// layout (each file name parses back into entities that match its folder), with dataset_description.json, a dseg.tsv
// and a sidecar naming the raw image; --participant-label and --session select; a missing participant is one line.
TEST(BatchCli, BidsDatasetBecomesADerivative) {
  msk::test::ScratchDir dir;
  const std::string raw = dir.file("raw"), out = dir.file("derivatives/mskseg");
  fs::create_directories(dir.file("derivatives"));
  for (const std::string f : {"sub-01/anat/sub-01_T1w.nii.gz", "sub-02/ses-1/anat/sub-02_ses-1_T1w.nii.gz",
                              "sub-02/ses-2/anat/sub-02_ses-2_T1w.nii.gz", "sub-03/anat/sub-03_T1w.nii.gz"}) {
    fs::create_directories(fs::path(raw + "/" + f).parent_path());
    fs::create_symlink(kSample + "image.nii.gz", raw + "/" + f);
  }
  fs::create_symlink(kSample + "labels.nii.gz", raw + "/sub-01/anat/sub-01_dseg.nii.gz");  // not a T1w: no case
  msk::test::writeBytes(raw + "/dataset_description.json", "{\"Name\": \"Thighs\", \"BIDSVersion\": \"1.9.0\"}");
  const std::string scene = femurScene(dir.file("scene.json"), "femur_left");
  auto r = runCli({"batch", "--bids", raw, "--scene", scene, "--out", out, "--", "--quality", "fast"});
  ASSERT_EQ(r.exitCode, 0) << r.err;

  const msk::Json description = msk::readJsonFile(out + "/dataset_description.json");
  EXPECT_EQ(description.at("DatasetType").get<std::string>(), "derivative");
  EXPECT_EQ(description.at("GeneratedBy")[0].at("Name").get<std::string>(), "mskseg");
  EXPECT_FALSE(description.at("GeneratedBy")[0].at("Version").get<std::string>().empty());
  EXPECT_NE(description.at("Name").get<std::string>().find("Thighs"), std::string::npos);
  const auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 5u);
  const std::vector<std::string> names = {"sub-01", "sub-02_ses-1", "sub-02_ses-2", "sub-03"};
  for (size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(rows[i + 1][0], names[i]);
    EXPECT_EQ(rows[i + 1][1], "ok");
  }

  // Every file below sub-*: its name parses into entities, sub (and ses) match the folders, and each case has its
  // label map, dseg.tsv, sidecar, mesh and pictures.
  std::map<std::string, std::set<std::string>> kinds;  // case -> "<suffix><extension>" (and label) of its files
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    const fs::path rel = fs::relative(e.path(), out);
    if (e.is_directory() || rel.begin()->string().rfind("sub-", 0) != 0) continue;
    const auto ent = bidsEntities(e.path().filename().string());
    ASSERT_FALSE(ent.empty()) << "not a BIDS name: " << rel;
    std::vector<std::string> folders;
    for (const fs::path& p : rel.parent_path()) folders.push_back(p.string());
    ASSERT_GE(folders.size(), 2u) << rel;
    EXPECT_EQ(folders[0], "sub-" + ent.at("sub")) << rel;
    if (ent.count("ses")) {
      EXPECT_EQ(folders[1], "ses-" + ent.at("ses")) << rel;
    }
    EXPECT_TRUE(folders.back() == "anat" || folders.back() == "figures") << rel;
    const std::string key = "sub-" + ent.at("sub") + (ent.count("ses") ? "_ses-" + ent.at("ses") : "");
    kinds[key].insert((ent.count("label") ? ent.at("label") + ":" : "") + ent.at("suffix") + ent.at("extension"));
  }
  ASSERT_EQ(kinds.size(), 4u);
  for (const auto& [key, files] : kinds) {
    for (const std::string want : {"dseg.nii.gz", "dseg.tsv", "dseg.json", "dseg.ctbl", "statistics.json",
                                   "femurleft:mesh.vtk", "femurleft:qc.png", "qc.png"})
      EXPECT_TRUE(files.count(want)) << key << " has no " << want;
  }
  const std::string anat = out + "/sub-02/ses-2/anat/sub-02_ses-2_";
  EXPECT_EQ(msk::test::readBytes(anat + "desc-mskseg_dseg.tsv"), "index\tname\tcolor\n1\tfemur_left\t#ff2828\n");
  const msk::Json sidecar = msk::readJsonFile(anat + "desc-mskseg_dseg.json");
  EXPECT_EQ(sidecar.at("Sources")[0].get<std::string>(), "bids:raw:sub-02/ses-2/anat/sub-02_ses-2_T1w.nii.gz");
  EXPECT_EQ(sidecar.at("objects")[0].at("name").get<std::string>(), "femur_left");
  const msk::LabelMap labels = msk::readNifti<int32_t>(anat + "desc-mskseg_dseg.nii.gz");
  EXPECT_GT(std::count(labels.data.begin(), labels.data.end(), 1), 1000);
  EXPECT_FALSE(fs::exists(out + "/.work"));

  // Selection: one session of one subject, into another folder.
  const std::string some = dir.file("some");
  r = runCli({"batch", "--bids", raw, "--scene", scene, "--out", some, "--participant-label", "sub-02", "--session",
              "2", "--", "--quality", "fast", "--no-qc"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(csvRows(some + "/summary.csv").size(), 2u);
  EXPECT_TRUE(fs::exists(some + "/sub-02/ses-2/anat/sub-02_ses-2_desc-mskseg_dseg.nii.gz"));
  EXPECT_FALSE(fs::exists(some + "/sub-02/ses-1"));
  EXPECT_FALSE(fs::exists(some + "/sub-02/ses-2/figures"));

  r = runCli({"batch", "--bids", raw, "--scene", scene, "--out", dir.file("none"), "--participant-label", "09"});
  EXPECT_EQ(r.exitCode, 2) << r.err;
  EXPECT_NE(r.err.find("has no folder sub-09"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("none")));
}

// A case whose segmentation cannot have worked (flat but for one corner voxel: no edge) ends ok as a process, its
// outputs written, and the summary's quality column says "failed"; batch.json counts it and the batch's exit code stays
// 0.
TEST(BatchCli, SummaryHasTheQualityStatusOfEachCase) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  fs::create_directories(cases + "/flat");
  msk::NiftiInfo info;
  msk::ImageF image = msk::readNifti<float>(kSample + "image.nii.gz", &info);
  std::fill(image.data.begin(), image.data.end(), 300.f);
  image.at(0, 0, 0) = 0.f;  // one dark corner voxel, far from the templates: not constant, yet no edge to find
  msk::NiftiWriteOptions wo;
  wo.like = &info;
  msk::writeNifti(cases + "/flat/image.nii.gz", image, msk::DataType::Int16, wo);
  const auto r = runCli({"batch", "--cases", cases, "--scene", femurScene(dir.file("scene.json"), "femur"), "--out",
                         out, "--", "--quality", "fast", "--no-qc"});
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("segmentation failed"), std::string::npos) << r.err;
  const auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0][2], "quality");
  EXPECT_EQ(rows[1][1], "ok");
  EXPECT_EQ(rows[1][2], "failed");
  EXPECT_EQ(msk::readJsonFile(out + "/batch.json").at("cases").at("quality_failed").get<int>(), 1);
}

namespace {
/// Waits until `path` exists (at most `seconds`).
bool waitForFile(const std::string& path, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!fs::exists(path)) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

/// Waits until no process mentions `text` (at most `seconds`); returns those still there.
std::vector<int> waitForNoProcess(const std::string& text, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  std::vector<int> left;
  while (!(left = msk::test::processesMentioning(text)).empty() && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  return left;
}

/// Two sample cases, each long enough (a step cap of 50,000 that no tolerance ends early) to be caught running.
std::vector<std::string> slowBatch(const msk::test::ScratchDir& dir, const std::string& cases, const std::string& out) {
  sampleCase(cases + "/p01");
  sampleCase(cases + "/p02");
  return {"batch",     "--cases", cases,         "--scene",   femurScene(dir.file("scene.json"), "femur"),
          "--out",     out,       "--",          "--quality", "fast",
          "--steps",   "50000",   "--tolerance", "1e-9",      "--no-qc",
          "--threads", "1"};
}
}  // namespace

// SIGTERM stops a batch: the running case ends and leaves nothing half-written, the next is not started, the summary
// says so, the exit code is 128 + 15, and no case process is left behind.
TEST(BatchCli, TermStopsTheRunningCasesAndWritesTheSummary) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  const auto args = slowBatch(dir, cases, out);
  const msk::test::CliProcess batch = msk::test::startCli(args, dir.file("stdout"), dir.file("stderr"));
  ASSERT_TRUE(waitForFile(out + "/logs/p01.log", 60));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ::kill(batch.pid, SIGTERM);
  EXPECT_EQ(msk::test::waitCli(batch, 30), 128 + SIGTERM) << msk::test::readBytes(batch.errFile);
  EXPECT_TRUE(waitForNoProcess(cases, 10).empty()) << "a case outlived its batch";
  const auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1][1], "interrupted");
  EXPECT_NE(rows[1].back().find("asked to stop"), std::string::npos) << rows[1].back();
  EXPECT_EQ(rows[2][1], "not-started");
  for (const auto& e : fs::directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().find(".p01.partial"), std::string::npos) << e.path();
  EXPECT_FALSE(fs::exists(out + "/p01"));
  EXPECT_NE(msk::test::readBytes(batch.errFile).find("stopped by signal 15"), std::string::npos);
}

// A batch killed outright (SIGKILL, no chance to clean up) takes its running case with it; a batch started on the
// same output folder while another runs leaves the other's case alone and runs the rest.
TEST(BatchCli, KilledBatchLeavesNoOrphanAndConcurrentBatchesShareTheCases) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  const auto args = slowBatch(dir, cases, out);
  const msk::test::CliProcess first = msk::test::startCli(args, dir.file("stdout"), dir.file("stderr"));
  ASSERT_TRUE(waitForFile(out + "/logs/p01.log", 60));
  std::vector<std::string> second(args.begin(), std::find(args.begin(), args.end(), std::string("--")));
  second.insert(second.end(), {"--", "--quality", "fast", "--no-qc"});
  const auto r = runCli(second);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("p01: elsewhere: another batch"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(out + "/p02/report.json")) << r.err;
  EXPECT_FALSE(fs::exists(out + "/p01/report.json"));

  ::kill(first.pid, SIGKILL);
  EXPECT_EQ(msk::test::waitCli(first, 30), 128 + SIGKILL);
  EXPECT_TRUE(waitForNoProcess(cases, 10).empty()) << "a case outlived its batch";
  // A rerun finds p01 free again (the claim went with the killed batch) and removes what it had half-written.
  const auto rerun = runCli(second);
  EXPECT_EQ(rerun.exitCode, 0) << rerun.err;
  EXPECT_TRUE(fs::exists(out + "/p01/report.json")) << rerun.err;
  for (const auto& e : fs::directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
}

// `mskseg collect` gathers cases segmented one by one (as the Snakemake workflow's jobs do): the same case list as
// batch (--list), a finished case ok and scored, a refused one failed with its error, one not run yet listed so.
TEST(CollectCli, GathersCasesSegmentedOneByOne) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  sampleCase(cases + "/p01");
  fs::create_directories(cases + "/p02");
  const std::string image = msk::test::readBytes(kSample + "image.nii.gz");
  msk::test::writeBytes(cases + "/p02/image.nii.gz", image.substr(0, image.size() / 3));
  sampleCase(cases + "/p03");
  const std::string scene = femurScene(dir.file("scene.json"), "femur");
  const std::vector<std::string> base = {"collect", "--cases", cases, "--scene", scene, "--out", out};

  auto r = runCli({"collect", "--cases", cases, "--scene", scene, "--out", out, "--list"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json listed = msk::parseJson(r.out);
  ASSERT_EQ(listed.size(), 3u);
  EXPECT_EQ(listed[1].at("case").get<std::string>(), "p02");
  EXPECT_EQ(listed[1].at("scene").get<std::string>(), fs::absolute(scene).string());
  EXPECT_EQ(listed[1].at("out").get<std::string>(), out + "/p02");

  fs::create_directories(out + "/logs");
  for (const std::string c : {"p01", "p02"}) {
    r = runCli({"segment", "--image", cases + "/" + c + "/image.nii.gz", "--scene", scene, "--out", out + "/" + c,
                "--quality", "fast", "--no-qc"});
    msk::test::writeBytes(out + "/logs/" + c + ".log", r.err);
    msk::test::writeBytes(out + "/logs/" + c + ".exit", std::to_string(r.exitCode) + "\n");
  }
  fs::create_directories(out + "/.p03.partial999999999");  // what a cancelled job left
  r = runCli({"collect", "--cases", cases, "--scene", scene, "--out", out, "--reference", "labels.nii.gz"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1][1], "ok");
  EXPECT_GT(std::stod(rows[1][10]), 0.95);
  EXPECT_GT(std::stod(rows[1][4]), 0.0) << "seconds, from the case's report";
  EXPECT_EQ(rows[2][1], "failed");
  EXPECT_EQ(rows[2][3], "1");
  EXPECT_NE(rows[2][12].find("truncated"), std::string::npos) << rows[2][12];
  EXPECT_EQ(rows[3][1], "not-run");
  EXPECT_EQ(csvRows(out + "/metrics.csv").size(), 2u);
  EXPECT_FALSE(fs::exists(out + "/.p03.partial999999999"));
}

namespace {
/// The results of a batch's output folder that must not depend on how the batch got there: per case the summary's
/// result columns (quality, residual, volume change, overlap, scores) and the bytes of its label map and mesh.
std::map<std::string, std::string> batchResults(const std::string& out) {
  std::map<std::string, std::string> r;
  const auto rows = csvRows(out + "/summary.csv");
  for (size_t i = 1; i < rows.size(); ++i) {
    std::string cols;
    for (size_t k : {2u, 6u, 7u, 8u, 9u, 10u, 11u}) cols += rows[i][k] + ";";
    r[rows[i][0] + " summary"] = cols;
    for (const std::string f : {"labels.nii.gz", "femur.vtk"})
      r[rows[i][0] + " " + f] = msk::test::readBytes(out + "/" + rows[i][0] + "/" + f);
  }
  return r;
}
}  // namespace

// A batch, or one of its case processes, killed outright (SIGKILL) at a random moment: the rerun completes with the
// results of an uninterrupted run and leaves nothing half-written. Several moments per run (seeded, reproducible).
TEST(BatchCli, KilledAtRandomMomentsTheRerunGivesTheUninterruptedResults) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases");
  sampleCase(cases + "/p01");
  sampleCase(cases + "/p02");
  const std::string scene = femurScene(dir.file("scene.json"), "femur");
  auto args = [&](const std::string& out) {
    return std::vector<std::string>{"batch", "--cases", cases,       "--scene", scene,     "--out",     out, "--jobs",
                                    "2",     "--",      "--quality", "fast",    "--no-qc", "--threads", "1"};
  };
  const auto clean = runCli(args(dir.file("clean")));
  ASSERT_EQ(clean.exitCode, 0) << clean.err;
  const auto expected = batchResults(dir.file("clean"));
  ASSERT_EQ(expected.size(), 6u);

  // A random moment while a case runs: once a case process is seen, a uniform delay of up to 0.3 s. A batch that
  // finished within that delay leaves nothing to test in that trial; most trials must hit.
  std::mt19937 random(20261126);
  int hits = 0;
  for (int trial = 0; trial < 6; ++trial) {
    const bool killCase = trial % 2 == 1;  // the batch itself, or one of its case processes
    const double delay = std::uniform_real_distribution<double>(0.0, 0.3)(random);
    SCOPED_TRACE("trial " + std::to_string(trial) + (killCase ? ": a case killed" : ": the batch killed") + " " +
                 std::to_string(delay) + " s after a case started");
    const std::string out = dir.file("run" + std::to_string(trial));
    const msk::test::CliProcess batch =
        msk::test::startCli(args(out), dir.file("stdout" + std::to_string(trial)), dir.file("stderr"));
    const auto giveUp = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (msk::test::processesMentioning(out + "/p0").empty() && std::chrono::steady_clock::now() < giveUp)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
    bool hit = false;
    if (killCase) {
      for (int pid : msk::test::processesMentioning(out + "/p0"))
        if (pid != batch.pid) hit = ::kill(pid, SIGKILL) == 0 || hit;
    } else {
      ::kill(batch.pid, SIGKILL);
    }
    const int ended = msk::test::waitCli(batch, 60);
    if (!killCase) hit = ended == 128 + SIGKILL;
    if (killCase && hit) {
      EXPECT_EQ(ended, 1) << "the killed case failed, the batch went on";
    }
    hits += hit;
    EXPECT_TRUE(waitForNoProcess(out + "/", 10).empty()) << "a case outlived its batch";
    const auto rerun = runCli(args(out));
    EXPECT_EQ(rerun.exitCode, 0) << rerun.err;
    EXPECT_EQ(batchResults(out), expected) << "the rerun's results differ from an uninterrupted run's";
    for (const auto& e : fs::recursive_directory_iterator(out))
      EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
  }
  EXPECT_GE(hits, 4) << "too few trials killed something while it ran";
}

// Two batches started together on one output folder of six cases: each case runs exactly once (in one batch or the
// other), and the summary the later one leaves covers the whole cohort.
TEST(BatchCli, TwoConcurrentBatchesRunEachCaseOnce) {
  msk::test::ScratchDir dir;
  const std::string cases = dir.file("cases"), out = dir.file("out");
  const std::vector<std::string> names = {"p01", "p02", "p03", "p04", "p05", "p06"};
  for (const std::string& n : names) sampleCase(cases + "/" + n);
  const std::vector<std::string> args = {
      "batch",   "--cases",   cases, "--scene",   femurScene(dir.file("scene.json"), "femur"),
      "--out",   out,         "--",  "--quality", "fast",
      "--no-qc", "--threads", "1"};
  const msk::test::CliProcess a = msk::test::startCli(args, dir.file("a.out"), dir.file("a.err"));
  const msk::test::CliProcess b = msk::test::startCli(args, dir.file("b.out"), dir.file("b.err"));
  ASSERT_EQ(msk::test::waitCli(a, 300), 0) << msk::test::readBytes(a.errFile);
  ASSERT_EQ(msk::test::waitCli(b, 300), 0) << msk::test::readBytes(b.errFile);
  const std::string saidA = msk::test::readBytes(a.errFile), saidB = msk::test::readBytes(b.errFile);
  EXPECT_NE(saidA.find(" ok in"), std::string::npos) << "the first batch ran no case:\n" << saidA;
  EXPECT_NE(saidB.find(" ok in"), std::string::npos) << "the second batch ran no case:\n" << saidB;
  const std::string said = saidA + saidB;
  for (const std::string& n : names) {
    size_t runs = 0;
    for (size_t at = said.find("] " + n + " ok in"); at != std::string::npos;
         at = said.find("] " + n + " ok in", at + 1))
      ++runs;
    EXPECT_EQ(runs, 1u) << n << " ran " << runs << " times:\n" << said;
  }
  const auto rows = csvRows(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 7u);
  for (size_t i = 1; i < rows.size(); ++i) {
    EXPECT_TRUE(rows[i][1] == "ok" || rows[i][1] == "done") << rows[i][0] << ": " << rows[i][1];
    EXPECT_FALSE(rows[i][6].empty()) << rows[i][0] << " has its results in the summary";
  }
}
