// mskseg batch end to end: every case of a cohort folder, per-case failures, resuming, the summary tables.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
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
  EXPECT_EQ(rows[1][1], "failed");
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
