// mskseg batch: one scene segmented in every case of a cohort folder. Each case runs `mskseg segment` in a child
// process of its own (a crash or an out-of-memory in one case ends that case only), its output folder appearing
// whole or not at all; a rerun skips the cases already done, so an interrupted overnight batch resumes where it
// stopped. The summary table is rewritten (atomically) as each case ends.
#include <fcntl.h>
#include <fnmatch.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "batch_bids.h"
#include "cohort.h"
#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/checksum.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/atlas.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/scene.h"

namespace fs = std::filesystem;

namespace msk::cli {
namespace {

std::string isoTime(std::time_t t) {
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

/// Whether `option` (e.g. "--threads") is among the options after --, as "--option VALUE" or "--option=VALUE".
bool forwardedSets(const std::vector<std::string>& forwarded, const std::string& option) {
  return std::any_of(forwarded.begin(), forwarded.end(),
                     [&](const std::string& a) { return a == option || a.rfind(option + "=", 0) == 0; });
}

/// Starts `mskseg segment` for case `c` with its stdout and stderr in the case's log; returns the child's pid. Unless
/// the options after -- set --threads, each case gets an equal share of the cores among the `jobs` cases run at once;
/// unless they set --template-cache, the cases share `templateCache` (results depend on neither, so neither is part of
/// the case's fingerprint).
pid_t startCase(const std::string& exe, const Case& c, const std::vector<std::string>& forwarded, int jobs,
                const std::string& templateCache) {
  std::vector<std::string> args = {exe, "segment", "--image", c.image, "--out", c.out};
  if (c.atlas.empty()) {
    args.insert(args.end(), {"--scene", c.scene});
  } else {
    args.insert(args.end(), {"--atlas", c.atlas});
  }
  if (!c.reference.empty()) args.insert(args.end(), {"--qc-reference", c.reference});  // drawn in its QC pictures
  args.insert(args.end(), forwarded.begin(), forwarded.end());
  if (!forwardedSets(forwarded, "--threads")) {
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    args.insert(args.end(), {"--threads", std::to_string(std::max(1, cores / std::max(1, jobs)))});
  }
  if (!forwardedSets(forwarded, "--template-cache")) args.insert(args.end(), {"--template-cache", templateCache});
  std::vector<char*> cargs;
  for (std::string& a : args) cargs.push_back(a.data());
  cargs.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  std::cout.flush();
  std::cerr.flush();
  const pid_t parent = ::getpid();
  const pid_t pid = fork();
  if (pid < 0) throw Error("batch: cannot start a process for case " + c.name);
  if (pid == 0) {
    // The case ends with the batch, however the batch ends (kill -9 included): no orphan keeps running.
    if (::prctl(PR_SET_PDEATHSIG, SIGTERM) != 0 || ::getppid() != parent) _exit(125);
    const int fd = ::open(c.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0 || ::dup2(fd, 1) < 0 || ::dup2(fd, 2) < 0) _exit(126);
    ::close(fd);
    ::execv(exe.c_str(), cargs.data());
    _exit(127);
  }
  return pid;
}

void say(const std::string& line) {
  if (log::level() <= LogLevel::Info) std::cerr << "mskseg batch: " << printableText(line) << std::endl;
}

/// The signal that asked the batch to stop (SIGTERM, SIGINT, SIGHUP), 0 while none has.
volatile std::sig_atomic_t stopSignal = 0;

extern "C" void onStopSignal(int sig) { stopSignal = sig; }

/// Catches SIGTERM, SIGINT and SIGHUP for the batch's lifetime (restoring the previous handlers after), so that the
/// batch stops its cases and writes its summary before it ends.
class StopSignals {
 public:
  StopSignals() {
    struct sigaction sa {};
    sa.sa_handler = onStopSignal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: a wait is interrupted
    for (int i = 0; i < 3; ++i) ::sigaction(kSignals[i], &sa, &old_[i]);
  }
  ~StopSignals() {
    for (int i = 0; i < 3; ++i) ::sigaction(kSignals[i], &old_[i], nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  static constexpr int kSignals[3] = {SIGTERM, SIGINT, SIGHUP};
  struct sigaction old_[3];
};

/// The batch's command line; the options after "--" are checked as `mskseg segment` would (a mistake in them stops
/// the batch before anything runs or is written). Returns false if --help was asked.
bool parseBatch(const std::vector<std::string>& argvIn, CohortSettings& b) {
  std::vector<std::string> argv;
  const auto dash = std::find(argvIn.begin(), argvIn.end(), std::string("--"));
  argv.assign(argvIn.begin(), dash);
  if (dash != argvIn.end()) b.forwarded.assign(dash + 1, argvIn.end());
  CommandLine app(
      "batch",
      "Segments every case of a cohort with one scene or atlas: each subfolder of --cases holding the image is a case "
      "(a case folder's own scene.json, if present, replaces --scene for it), or with --bids each image of a BIDS "
      "dataset. Each case runs `mskseg segment` in a process of its own (a failing case ends alone) and writes "
      "OUT/<case>/ (with --bids: OUT/sub-<label>/[ses-<label>/]anat/ and figures/, entity-named files, and "
      "OUT/dataset_description.json) whole or not at all; its log goes to OUT/logs/<case>.log. A rerun skips the "
      "cases already done by the same program version, scene or atlas, image and options (OUT/logs/<case>.json), "
      "runs those done with other ones again (unless --keep-stale), and runs everything again with --redo.");
  CLI::Option* casesOpt = app.add_option("--cases", b.casesDir, "the cohort folder");
  app.add_option("--bids", b.bids.dataset,
                 "a BIDS dataset instead of --cases: each sub-<label>/[ses-<label>/]anat/*_<suffix>.nii[.gz] is a "
                 "case, its results go to OUT/sub-<label>/[ses-<label>/]anat/ as a BIDS derivative")
      ->excludes(casesOpt);
  app.add_option("--participant-label", b.bids.participants,
                 "with --bids: only these subjects (labels, with or without sub-, comma-separated)")
      ->delimiter(',');
  app.add_option("--session", b.bids.sessions,
                 "with --bids: only these sessions (labels, with or without ses-, comma-separated)")
      ->delimiter(',');
  app.add_option("--suffix", b.bids.suffix, "with --bids: the images' suffix (default T1w)");
  CLI::Option* sceneOpt = app.add_option("--scene", b.scene, "the scene of every case without a scene.json of its own");
  app.add_option("--atlas", b.atlas,
                 "an atlas folder (mskseg atlas) placed in every case by registration, instead of a scene")
      ->excludes(sceneOpt);
  app.add_option("--out", b.out, "output folder")->required();
  addCaseFileOptions(app, b);
  app.add_option("--jobs", b.jobs, "cases run at once, 1..64 (default 1; each case's --threads come after --)");
  app.add_flag("--redo", b.redo, "run the cases already done again");
  app.add_flag("--keep-stale", b.keepStale,
               "keep (and mark stale) the cases done earlier by another version, scene, atlas, image or options, "
               "instead of running them again");
  app.footer(
      "-- OPTIONS: passed to every `mskseg segment`, e.g. -- --quality fast --no-qc (checked before any case runs). "
      "Writes OUT/summary.csv (one row per case: status (ok, failed, done by an earlier run, stale: done earlier with "
      "other inputs and kept by --keep-stale, skipped: no image, elsewhere: another batch on OUT is running it, "
      "interrupted: the batch was stopped while it ran, not-started: the batch was stopped first), quality (ok, "
      "doubtful or failed: the segmentation's status judged from the image alone, the report's \"status\"), exit "
      "code, seconds, peak memory, the checks that need no reference: largest mean image residual and volume change "
      "of an object, voxels inside two objects; Dice; message), rewritten as each case ends; at the end "
      "OUT/report.html "
      "(the cohort's QC page: a row per case, sortable and filterable, volume outliers marked, thumbnails opening "
      "each case's QC mosaic); OUT/metrics.csv with --reference; OUT/batch.json (the command, version, counts, times). "
      "Exit code 0 if every case ends ok, 1 if "
      "any case failed (the others still run), 2 for a usage error. SIGTERM, SIGINT or SIGHUP end the running cases "
      "and remove what they had half-written, write the summary and exit 128 + the signal; the cases also end if the "
      "batch is killed outright (a rerun removes what they left). Several batches may share OUT, on one machine or "
      "several sharing its file system: each case is claimed by one (a lock on OUT/logs/.<case>.claim, which names "
      "the host and process holding it).");
  if (!parseArgs(app, argv)) return false;
  b.useBids = !b.bids.dataset.empty();
  if (!b.useBids && b.casesDir.empty()) throw UsageError("give the cohort: --cases FOLDER or --bids DATASET");
  if (b.useBids) {
    for (const char* own : {"--image", "--reference"})
      if (app.count(own) > 0)
        throw UsageError(std::string(own) + " with --bids: the images are the dataset's *_<suffix>.nii[.gz]");
    b.casesDir = b.bids.dataset;
  } else {
    for (const char* bidsOnly : {"--participant-label", "--session", "--suffix"})
      if (app.count(bidsOnly) > 0) throw UsageError(std::string(bidsOnly) + " needs --bids");
    checkCasePattern("--image", b.imageName);
    if (!b.referenceName.empty()) checkCasePattern("--reference", b.referenceName);
  }
  if (b.redo && b.keepStale) throw UsageError("--redo and --keep-stale ask for opposite things");
  // `-- --atlas DIR` is the batch's --atlas given after the separator.
  if (auto it = std::find(b.forwarded.begin(), b.forwarded.end(), std::string("--atlas")); it != b.forwarded.end()) {
    if (it + 1 == b.forwarded.end()) throw UsageError("--atlas after -- needs a folder");
    if (!b.atlas.empty() || !b.scene.empty()) throw UsageError("--atlas after -- and --atlas or --scene before it");
    b.atlas = *(it + 1);
    b.forwarded.erase(it, it + 2);
  }
  {
    CommandLine segment("segment", "");
    SegmentOptions opts;
    SegmentOutputs outputs;
    addSegmentOptions(segment, opts, outputs);
    // The atlas options of `segment` are checked there; here they are only passed on.
    for (const char* flag : {"--no-register", "--no-object-register"}) segment.add_flag(flag);
    segment.add_option("--metric")->check(CLI::IsMember({"auto", "ncc", "mi"}));
    segment.add_option("--starts")->check(CLI::IsMember({"each", "reference"}));
    for (const char* own : {"--image", "--scene", "--out", "--help", "-h"})
      if (std::find(b.forwarded.begin(), b.forwarded.end(), own) != b.forwarded.end())
        throw UsageError(std::string("option ") + own + " after --: the batch sets it for each case");
    try {
      parseArgs(segment, b.forwarded);
    } catch (const UsageError& e) {
      throw UsageError(std::string(e.what()) + " (after --)");
    }
    checkSegmentOptions(opts);
  }
  if (b.jobs < 1 || b.jobs > 64) throw ParameterError("--jobs", std::to_string(b.jobs), "must be 1..64");
  std::error_code ec;
  if (!fs::is_directory(b.casesDir, ec))
    throw IoError(b.casesDir, fs::exists(b.casesDir, ec) ? "is not a folder" : "no such folder");
  if (!b.scene.empty()) {
    if (!fs::is_regular_file(b.scene, ec)) throw IoError(b.scene, "no such file");
    b.scene = fs::absolute(b.scene).string();
  }
  if (!b.atlas.empty()) {
    loadAtlas(b.atlas);  // a broken atlas stops the batch before any case runs
    b.atlas = fs::absolute(b.atlas).string();
  }
  checkOutputFolder(b.out);
  b.outAbs = fs::absolute(b.out).lexically_normal();
  return true;
}

/// OUT/logs/<case>.json: how a finished case ended and what produced it, read back by a rerun that skips the case.
std::string recordPath(const CohortSettings& b, const Case& c) {
  return fileInFolder((b.outAbs / "logs").string(), c.name + ".json");
}

void writeRecord(const CohortSettings& b, const Case& c) {
  Json j;
  j["status"] = c.status;
  j["exit_code"] = c.exitCode;
  j["seconds"] = c.seconds;
  j["peak_rss_mib"] = c.peakRssMiB;
  j["fingerprint"] = c.fingerprint;
  j["finished"] = isoTime(std::time(nullptr));
  writeJsonFile(recordPath(b, c), j);
}

/// Restores the figures of an earlier run of the case from its record; returns that run's fingerprint ("" if there
/// is no readable record).
std::string readRecord(const CohortSettings& b, Case& c) {
  try {
    const Json j = readJsonFile(recordPath(b, c));
    c.exitCode = jsonInt(j.at("exit_code"));
    c.seconds = j.at("seconds").get<double>();
    c.peakRssMiB = j.at("peak_rss_mib").get<double>();
    return j.at("fingerprint").get<std::string>();
  } catch (const std::exception&) {
    return "";
  }
}

/// A digest of what produces the case's result: the program's version, the scene and its templates (or the atlas,
/// whose atlas.json holds its files' checksums), the options passed to `segment`, and the image. Empty if an input
/// cannot be read (the case then runs and fails on its own). `scenes` caches the scenes' part.
std::string fingerprintOf(const CohortSettings& b, const Case& c, std::map<std::string, std::string>& scenes) {
  try {
    std::string text = std::string("mskseg ") + MSK_VERSION + "\n";
    if (!c.atlas.empty()) {
      text += "atlas " + sha256File(c.atlas + "/atlas.json") + "\n";
    } else {
      auto it = scenes.find(c.scene);
      if (it == scenes.end()) {
        std::string part = "scene " + sha256File(c.scene);
        for (const SceneObject& o : loadScene(c.scene).objects) part += " " + sha256File(o.templatePath);
        it = scenes.emplace(c.scene, part).first;
      }
      text += it->second + "\n";
    }
    // The options after --, less a template cache's folder (it changes no result).
    for (size_t i = 0; i < b.forwarded.size(); ++i) {
      const std::string& a = b.forwarded[i];
      if (a.rfind("--template-cache=", 0) == 0) continue;
      if (a == "--template-cache") {
        ++i;
        continue;
      }
      text += a + '\x1f';
    }
    text += "\nimage " + sha256File(c.image) + "\n";
    return sha256Text(text).substr(0, 16);
  } catch (const Error&) {
    return "";
  }
}

/// Whether case `c`, found finished, is left as it is: `done` (its record's fingerprint matches, or there is no record
/// to compare), or `stale` with --keep-stale; false if it must run again (with --redo, or when what produces it has
/// changed).
bool keepFinished(const CohortSettings& b, Case& c, bool scored) {
  if (b.redo || !fs::exists(c.reportPath)) return false;
  const std::string was = readRecord(b, c);
  if (!was.empty() && !c.fingerprint.empty() && was != c.fingerprint) {
    if (!b.keepStale) {
      c.exitCode = -1;
      c.seconds = c.peakRssMiB = 0;
      say(c.name +
          ": runs again: its result came from another version, scene, atlas, image or options "
          "(--keep-stale keeps it)");
      return false;
    }
    c.status = "stale";
    readResults(c, scored);
    c.message = "done by an earlier run with another version, scene, atlas, image or options";
    return true;
  }
  c.status = "done";
  readResults(c, scored);
  return true;
}

/// Records how a case's process ended (and its results if it succeeded; with --bids, after publishing them into the
/// derivative's layout); returns the line to report.
std::string caseEnded(const CohortSettings& b, Case& c, int status, const struct rusage& ru, const std::string& exe,
                      bool scored) {
  c.peakRssMiB = static_cast<double>(ru.ru_maxrss) / 1024.0;
  c.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (WIFEXITED(status) && c.exitCode == 0) {
    c.status = "ok";
    try {
      if (c.bids) publishBidsCase(c.out, b.outAbs.string(), c.bidsCase, b.bids.suffix);
      readResults(c, scored);
      writeRecord(b, c);
    } catch (const Error& e) {
      c.status = "failed";
      c.message = e.what();
    }
  } else {
    c.status = "failed";
    c.message = WIFSIGNALED(status) ? "killed by signal " + std::to_string(WTERMSIG(status)) +
                                          (WTERMSIG(status) == SIGKILL ? " (out of memory?)" : "")
                : c.exitCode == 127 ? "could not run " + exe
                                    : errorLine(c.log);
  }
  std::string line = c.name + " " + c.status + " in " + fixed(c.seconds, 1) + " s, " + fixed(c.peakRssMiB, 0) + " MiB";
  if (!c.quality.empty() && c.quality != "ok") line += ", segmentation " + c.quality;
  if (!c.scores.empty()) line += ", Dice mean " + fixed(c.meanDice, 3) + " min " + fixed(c.minDice, 3);
  if (!c.message.empty()) line += ": " + c.message;
  if (c.status == "failed") line += " (log " + c.log + ")";
  return line;
}

/// Runs the cases `todo`, b.jobs at a time, rewriting the summary as each ends. A case another batch has claimed is
/// left to it; one that batch finished meanwhile counts as done. A usage error in the forwarded options would fail
/// every case alike: the batch stops starting cases at the first one and throws it. SIGTERM, SIGINT or SIGHUP stop
/// the batch: its running cases are ended (their outputs never appear half-written) and marked failed, the summary
/// is written, and the signal's number is returned (0 when every case ran).
int runCases(const CohortSettings& b, std::vector<Case>& cases, const std::vector<size_t>& todo, int& doneEarlier) {
  std::error_code ec;
  const std::string exe = fs::read_symlink("/proc/self/exe", ec).string();
  if (ec) throw Error("batch: cannot find the mskseg program itself (/proc/self/exe)");
  const bool scored = !b.referenceName.empty();
  struct Running {
    size_t index;
    std::chrono::steady_clock::time_point start;
    std::unique_ptr<Claim> claim;
  };
  std::map<pid_t, Running> running;
  size_t next = 0, finished = 0;
  std::string usageError;
  const StopSignals signals;
  stopSignal = 0;
  bool stopping = false;
  while (next < todo.size() || !running.empty()) {
    if (stopSignal != 0 && !stopping) {
      stopping = true;
      say("stopping (signal " + std::to_string(stopSignal) + "): ending " + std::to_string(running.size()) +
          " running case(s)");
      for (const auto& r : running) ::kill(r.first, SIGTERM);
    }
    while (!stopping && usageError.empty() && next < todo.size() && static_cast<int>(running.size()) < b.jobs) {
      const size_t i = todo[next++];
      Case& c = cases[i];
      auto claim = std::make_unique<Claim>(b.outAbs / "logs", c.name);
      if (!claim->held()) {
        c.status = "elsewhere";
        c.message = "another batch on " + b.outAbs.string() + " is running it";
        say(c.name + ": " + c.status + ": " + c.message);
        continue;
      }
      if (keepFinished(b, c, scored)) {  // finished by another batch since the cases were listed
        ++doneEarlier;
        continue;
      }
      if (c.bids) fs::remove_all(c.out, ec);  // what a batch killed while publishing left
      fs::remove(exitCodePath(b, c), ec);
      running[startCase(exe, c, b.forwarded, b.jobs, (b.outAbs / ".template-cache").string())] = {
          i, std::chrono::steady_clock::now(), std::move(claim)};
    }
    if (running.empty()) break;
    int status = 0;
    struct rusage ru {};
    const pid_t pid = ::wait4(-1, &status, WNOHANG, &ru);
    if (pid == 0 || (pid < 0 && errno == EINTR)) {
      ::usleep(100000);  // a signal cuts the sleep short
      continue;
    }
    if (pid < 0) throw Error("batch: lost track of the case processes");
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    Case& c = cases[it->second.index];
    c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.start).count();
    running.erase(it);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)  // a case ended mid-write leaves its staging folder
      fs::remove_all(fs::path(c.out).parent_path() / ("." + c.name + ".partial" + std::to_string(pid)), ec);
    std::string line = caseEnded(b, c, status, ru, exe, scored);
    if (stopping && c.status == "failed") {
      c.status = "interrupted";
      c.message = "stopped: the batch was asked to stop (signal " + std::to_string(stopSignal) + ")";
      line = c.name + " " + c.status + ": " + c.message;
    }
    if (c.status != "interrupted") writeExitCode(b, c);
    if (c.exitCode == 2 && usageError.empty() && !stopping) usageError = c.name + ": " + c.message;
    say("[" + std::to_string(++finished) + "/" + std::to_string(todo.size()) + "] " + line);
    writeSummary(b.outAbs.string(), cases, scored);
  }
  // Cases another batch was running when this one reached them: those it has finished since count as done here, so
  // that whichever batch ends last leaves a summary of the whole cohort.
  for (const size_t i : todo) {
    Case& c = cases[i];
    if (c.status != "elsewhere" || !fs::exists(c.reportPath)) continue;
    const Claim claim(b.outAbs / "logs", c.name);
    if (!claim.held()) continue;  // still being written
    c.message.clear();
    if (keepFinished(b, c, scored)) ++doneEarlier;
  }
  writeSummary(b.outAbs.string(), cases, scored);
  if (stopping) {
    for (size_t k = next; k < todo.size(); ++k) {
      Case& c = cases[todo[k]];
      c.status = "not-started";
      c.message = "the batch was stopped first";
    }
    writeSummary(b.outAbs.string(), cases, scored);
    return stopSignal;
  }
  if (!usageError.empty()) throw UsageError("case " + usageError);
  return 0;
}

/// How the cases ended.
struct CaseCounts {
  long ok = 0, failed = 0, skipped = 0, doneEarlier = 0, stale = 0, elsewhere = 0, interrupted = 0, notStarted = 0;
  long doubtful = 0, qualityFailed = 0;  ///< cases that ran (or were done earlier) with that quality status
};

CaseCounts countCases(const std::vector<Case>& cases, int doneEarlier) {
  CaseCounts n;
  for (const Case& c : cases) {
    n.ok += c.status == "ok";
    n.failed += c.status == "failed";
    n.skipped += c.status == "skipped";
    n.elsewhere += c.status == "elsewhere";
    n.interrupted += c.status == "interrupted";
    n.stale += c.status == "stale";
    n.notStarted += c.status == "not-started";
    n.doubtful += c.quality == "doubtful";
    n.qualityFailed += c.quality == "failed";
  }
  n.doneEarlier = doneEarlier - n.stale;
  return n;
}

/// OUT/batch.json: the command, version, inputs, counts and times.
void writeBatchJson(const CohortSettings& b, const std::vector<std::string>& argvIn, const CaseCounts& n,
                    std::time_t started, double wallSeconds) {
  Json counts;
  counts["ok"] = n.ok;
  counts["failed"] = n.failed;
  counts["done_earlier"] = n.doneEarlier;
  counts["stale_kept"] = n.stale;
  counts["skipped_no_image"] = n.skipped;
  counts["running_elsewhere"] = n.elsewhere;
  counts["interrupted"] = n.interrupted;
  counts["not_started"] = n.notStarted;
  counts["quality_doubtful"] = n.doubtful;
  counts["quality_failed"] = n.qualityFailed;
  Json j;
  j["mskseg_version"] = MSK_VERSION;
  j["command"] = commandLineJson("batch", argvIn);
  j["cases_folder"] = fs::absolute(b.casesDir).string();
  j["scene"] = b.scene;
  if (!b.atlas.empty()) j["atlas"] = b.atlas;
  j["image_name"] = b.imageName;
  if (!b.referenceName.empty()) j["reference_name"] = b.referenceName;
  j["segment_options"] = b.forwarded;
  j["jobs"] = b.jobs;
  j["started"] = isoTime(started);
  j["finished"] = isoTime(std::time(nullptr));
  j["wall_s"] = wallSeconds;
  j["cases"] = counts;
  writeJsonFile(b.outAbs.string() + "/batch.json", j);
}

}  // namespace

int cmdBatch(const std::vector<std::string>& argvIn) {
  CohortSettings b;
  if (!parseBatch(argvIn, b)) return 0;
  std::vector<Case> cases;
  const int runnable = findCases(b, cases);
  std::error_code ec;
  for (const fs::path& dir : {b.outAbs / "logs", b.outAbs / ".work"}) {
    if (dir.filename() == ".work" && !b.useBids) continue;
    fs::create_directories(dir, ec);
    if (ec) throw IoError(dir.string(), "cannot create folder: " + ec.message());
  }
  removeStaleStaging(b.outAbs, cases);
  if (b.useBids) {
    std::string line = "mskseg batch";
    for (const std::string& a : argvIn) line += " " + a;
    writeBidsDescription(b.outAbs.string(), b.bids.dataset, line);
  }

  // Cases done by an earlier run keep their results (and get scored, so the summary covers the whole cohort).
  const bool scored = !b.referenceName.empty();
  std::vector<size_t> todo;
  int doneEarlier = 0;
  std::map<std::string, std::string> scenes;
  for (size_t i = 0; i < cases.size(); ++i) {
    Case& c = cases[i];
    if (c.status != "pending") continue;
    c.fingerprint = fingerprintOf(b, c, scenes);
    if (keepFinished(b, c, scored))
      ++doneEarlier;
    else
      todo.push_back(i);
  }
  say(std::to_string(runnable) + " case(s) in " + b.casesDir +
      (doneEarlier ? ", " + std::to_string(doneEarlier) + " done by an earlier run (--redo runs them again)"
                   : std::string()) +
      ", " + std::to_string(todo.size()) + " to run, " + std::to_string(b.jobs) + " at a time");
  for (const Case& c : cases)
    if (c.status == "skipped" || c.status == "failed") say(c.name + ": " + c.status + ": " + c.message);
  writeSummary(b.outAbs.string(), cases, scored);

  const std::time_t started = std::time(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  const int stoppedBy = runCases(b, cases, todo, doneEarlier);
  fs::remove(b.outAbs / ".work", ec);  // only if it is empty
  const CaseCounts n = countCases(cases, doneEarlier);
  writeBatchJson(b, argvIn, n, started, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  writeCohortPage(b.outAbs.string(), cases, b.casesDir);
  if (stoppedBy != 0) {
    std::cerr << "mskseg batch: stopped by signal " << stoppedBy << "; " << n.ok << " case(s) ok; a rerun goes on "
              << "from there -> " << b.outAbs.string() << "/summary.csv\n";
    return 128 + stoppedBy;
  }
  std::cout << "batch: " << n.ok << " ok, " << n.failed << " failed, " << n.doneEarlier << " done earlier, "
            << n.skipped << " without " << (b.useBids ? "an image" : b.imageName)
            << (n.elsewhere ? ", " + std::to_string(n.elsewhere) + " left to another batch running them" : "")
            << (n.stale ? ", " + std::to_string(n.stale) + " stale kept" : "") << "; segmentation doubtful in "
            << n.doubtful << ", failed in " << n.qualityFailed << " -> " << b.outAbs.string() << "/summary.csv\n";
  return n.failed > 0 ? 1 : 0;
}

}  // namespace msk::cli
