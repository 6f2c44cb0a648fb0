// mskseg collect: the cohort tables of cases segmented by separate `mskseg segment` runs (the jobs of the Snakemake
// workflow in workflow/, on one machine or a cluster), with the same case list and tables as `mskseg batch`.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "cohort.h"
#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/imaging/json.h"

namespace fs = std::filesystem;

namespace msk::cli {
namespace {

/// How case `c` ended, from what its job left in OUT: its report (ok), or its exit code and log (failed), or nothing
/// (not run yet).
void readCase(const CohortSettings& s, Case& c, bool scored) {
  if (c.status != "pending") return;  // no image, or no scene: as found
  if (fs::exists(c.reportPath)) {
    c.status = "ok";
    c.exitCode = 0;
    readResults(c, scored);
    try {
      c.seconds = readJsonFile(c.reportPath).at("timing").at("total_s").get<double>();
    } catch (const std::exception&) {
    }
    return;
  }
  std::ifstream code(exitCodePath(s, c));
  int rc = -1;
  if (code >> rc) {
    c.status = "failed";
    c.exitCode = rc;
    c.message = errorLine(c.log);
    return;
  }
  c.status = "not-run";
  c.message = "no result and no exit code: its job has not run (or was stopped)";
}

}  // namespace

int cmdCollect(const std::vector<std::string>& argv) {
  CohortSettings s;
  bool list = false;
  CommandLine app(
      "collect",
      "Gathers a cohort segmented case by case with `mskseg segment --out OUT/<case>` (each case's log "
      "in OUT/logs/<case>.log and the exit code of a failed run in OUT/logs/<case>.exit, as the Snakemake "
      "workflow in workflow/ writes them) into the tables `mskseg batch` writes: OUT/summary.csv (status "
      "ok, failed, not-run, skipped), OUT/report.html (the cohort's QC page) and, with --reference, OUT/metrics.csv. "
      "Removes what stopped runs "
      "left half-written. With --list, prints the cases (JSON) instead. Exit code 0 once the tables are written, "
      "whatever the cases' statuses.");
  app.add_option("--cases", s.casesDir, "the cohort folder")->required();
  CLI::Option* sceneOpt = app.add_option("--scene", s.scene, "the scene of every case without a scene.json of its own");
  app.add_option("--atlas", s.atlas, "an atlas folder, instead of a scene")->excludes(sceneOpt);
  app.add_option("--out", s.out, "the output folder of the cases")->required();
  addCaseFileOptions(app, s);
  app.add_flag(
      "--list", list,
      "print the cases that can run as a JSON array of {case, image, scene or atlas, reference if any, out, log} "
      "and write "
      "nothing");
  if (!parseArgs(app, argv)) return 0;
  checkCasePattern("--image", s.imageName);
  if (!s.referenceName.empty()) checkCasePattern("--reference", s.referenceName);
  std::error_code ec;
  if (!fs::is_directory(s.casesDir, ec))
    throw IoError(s.casesDir, fs::exists(s.casesDir, ec) ? "is not a folder" : "no such folder");
  if (!s.scene.empty()) {
    if (!fs::is_regular_file(s.scene, ec)) throw IoError(s.scene, "no such file");
    s.scene = fs::absolute(s.scene).string();
  }
  if (!s.atlas.empty()) s.atlas = fs::absolute(s.atlas).string();
  checkOutputFolder(s.out);
  s.outAbs = fs::absolute(s.out).lexically_normal();

  std::vector<Case> cases;
  findCases(s, cases);
  if (list) {
    Json out = Json::array();
    for (const Case& c : cases) {
      if (c.status != "pending") continue;
      Json j;
      j["case"] = c.name;
      j["image"] = c.image;
      if (c.atlas.empty())
        j["scene"] = c.scene;
      else
        j["atlas"] = c.atlas;
      if (!c.reference.empty()) j["reference"] = c.reference;
      j["out"] = c.out;
      j["log"] = c.log;
      out.push_back(j);
    }
    std::cout << dumpJson(out, 1) << "\n";
    return 0;
  }

  if (!fs::is_directory(s.outAbs, ec)) throw IoError(s.out, "no such folder: no case has been segmented into it");
  fs::create_directories(s.outAbs / "logs", ec);
  removeStaleStaging(s.outAbs, cases);
  const bool scored = !s.referenceName.empty();
  long ok = 0, failed = 0, notRun = 0, skipped = 0;
  for (Case& c : cases) {
    readCase(s, c, scored);
    ok += c.status == "ok";
    failed += c.status == "failed";
    notRun += c.status == "not-run";
    skipped += c.status == "skipped";
  }
  writeSummary(s.outAbs.string(), cases, scored);
  writeCohortPage(s.outAbs.string(), cases, s.casesDir);
  std::cout << "collect: " << ok << " ok, " << failed << " failed, " << notRun << " not run, " << skipped << " without "
            << s.imageName << " -> " << s.outAbs.string() << "/summary.csv\n";
  return 0;
}

}  // namespace msk::cli
