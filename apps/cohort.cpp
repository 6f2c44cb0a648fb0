#include "cohort.h"

#include <fcntl.h>
#include <fnmatch.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/imaging/json.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/metrics.h"

namespace fs = std::filesystem;

namespace msk::cli {

namespace {

std::string orEmpty(double v, int digits) { return std::isfinite(v) ? fixed(v, digits) : ""; }

}  // namespace

void addCaseFileOptions(CLI::App& app, CohortSettings& s) {
  app.add_option("--image", s.imageName,
                 "the image file in each case folder (default image.nii.gz), or a path inside it whose parts may be "
                 "shell patterns, matching one file: '*_T1w.nii.gz', 'anat/*_T1w.nii.gz' (quoted)");
  app.add_option("--reference", s.referenceName,
                 "a label map in each case folder (a name or a pattern, as --image): each object's Dice, ASSD and "
                 "HD95 against it for the object's label (OUT/metrics.csv)");
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
  return q + "\"";
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

/// The last line of the case's log that reports an error (what `mskseg segment` printed before failing), else its
/// last non-empty line.
std::string errorLine(const std::string& logPath) {
  std::ifstream in(logPath);
  std::string line, lastError, last;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    last = line;
    if (line.find("error") != std::string::npos) lastError = line;
  }
  return lastError.empty() ? last : lastError;
}

/// The file of case folder `dir` named `pattern`: a path inside the folder whose parts may be shell patterns, such as
/// "*_T1w.nii.gz" or "anat/*_T1w.nii.gz", matching exactly one file. Empty with `problem` set if there is none or more
/// than one.
std::string caseFile(const fs::path& dir, const std::string& pattern, std::string& problem) {
  problem.clear();
  std::vector<std::string> parts;
  for (const fs::path& part : fs::path(pattern))
    if (!part.empty() && part != ".") parts.push_back(part.string());
  std::vector<fs::path> at = {fs::path()};  // matches so far, relative to dir
  std::error_code ec;
  for (size_t k = 0; k < parts.size(); ++k) {
    const bool last = k + 1 == parts.size();
    std::vector<fs::path> next;
    for (const fs::path& base : at) {
      if (parts[k].find_first_of("*?[") == std::string::npos) {
        const fs::path candidate = base / parts[k];
        if (last ? fs::is_regular_file(dir / candidate, ec) : fs::is_directory(dir / candidate, ec))
          next.push_back(candidate);
        continue;
      }
      std::vector<fs::path> hits;
      for (const auto& e : fs::directory_iterator(dir / base, ec))
        if ((last ? e.is_regular_file() : e.is_directory()) &&
            ::fnmatch(parts[k].c_str(), e.path().filename().c_str(), FNM_PERIOD) == 0)
          hits.push_back(base / e.path().filename());
      std::sort(hits.begin(), hits.end());
      next.insert(next.end(), hits.begin(), hits.end());
    }
    at = next;
  }
  if (at.size() == 1 && !parts.empty()) return fs::absolute(dir / at[0]).lexically_normal().string();
  if (at.empty() || parts.empty())
    problem = pattern.find_first_of("*?[") == std::string::npos ? "no " + pattern : "no file matches " + pattern;
  else
    problem = std::to_string(at.size()) + " files match " + pattern + " (" + at[0].string() + ", " + at[1].string() +
              (at.size() > 2 ? ", ..." : "") + ")";
  return "";
}

/// Refuses a --image or --reference pattern that could name a file outside the case folder.
void checkCasePattern(const std::string& option, const std::string& pattern) {
  const fs::path p(pattern);
  bool up = false;
  for (const fs::path& part : p) up = up || part == "..";
  if (pattern.empty() || p.is_absolute() || up)
    throw ParameterError(option, pattern, "must name a file inside each case folder (no leading / and no ..)");
}

/// Reads a finished case's results once: the reference-free checks from its report.json (left NaN if it cannot be
/// read) and, with `scored`, each object's scores (the names and labels the report lists) against the reference.
void readResults(Case& c, bool scored) {
  Json report;
  try {
    report = readJsonFile(c.reportPath);
    double residual = 0, change = 0;
    for (const Json& o : report.at("objects")) {
      residual = std::max(residual, o.at("mean_image_residual_mm").get<double>());
      const double v = o.at("volume_mm3").get<double>(), v0 = o.at("template_volume_mm3").get<double>();
      if (v0 > 0) change = std::max(change, 100.0 * std::abs(v / v0 - 1.0));
      c.volumesMl.emplace_back(o.at("name").get<std::string>(), v / 1000.0);
    }
    c.worstResidualMm = residual;
    c.worstVolumeChangePct = change;
    c.overlapVoxels = report.at("overlap_voxels").get<double>();
    c.quality = report.at("status").get<std::string>();
  } catch (const std::exception& e) {
    c.message = std::string("report not read: ") + e.what();
  }
  if (!scored) return;
  if (c.reference.empty()) {
    c.message = c.referenceProblem;
    return;
  }
  try {
    const LabelMap result = readNifti<int32_t>(c.labelsPath);
    const LabelMap reference = readNifti<int32_t>(c.reference);
    for (const Json& o : report.at("objects")) {
      ObjectScore s;
      s.name = o.at("name").get<std::string>();
      s.label = o.at("label").get<int>();
      const SegmentationMetrics m = labelMetrics(result, s.label, reference, s.label);
      s.dice = m.dice;
      s.assdMm = m.assd;
      s.hd95Mm = m.hd95;
      c.scores.push_back(s);
    }
    if (!c.scores.empty()) {
      double sum = 0, low = 1;
      for (const ObjectScore& s : c.scores) {
        sum += s.dice;
        low = std::min(low, s.dice);
      }
      c.meanDice = sum / static_cast<double>(c.scores.size());
      c.minDice = low;
    }
  } catch (const std::exception& e) {
    c.scores.clear();
    c.message = std::string("not scored: ") + e.what();
  }
}

void writeSummary(const std::string& out, const std::vector<Case>& cases, bool scored) {
  writeAtomically(out + "/summary.csv", [&](const std::string& tmp) {
    std::ofstream f(tmp);
    f << "case,status,quality,exit_code,seconds,peak_rss_mib,max_residual_mm,max_volume_change_pct,overlap_voxels,"
         "objects_scored,mean_dice,min_dice,message\n";
    for (const Case& c : cases) {
      f << csvField(c.name) << ',' << c.status << ',' << c.quality << ','
        << (c.exitCode >= 0 ? std::to_string(c.exitCode) : "") << ',' << (c.seconds > 0 ? fixed(c.seconds, 2) : "")
        << ',' << (c.peakRssMiB > 0 ? fixed(c.peakRssMiB, 1) : "") << ',' << orEmpty(c.worstResidualMm, 3) << ','
        << orEmpty(c.worstVolumeChangePct, 2) << ',' << orEmpty(c.overlapVoxels, 0) << ',' << c.scores.size() << ','
        << orEmpty(c.meanDice, 4) << ',' << orEmpty(c.minDice, 4) << ',' << csvField(c.message) << '\n';
    }
    if (!f.flush()) throw IoError(out + "/summary.csv", "cannot write");
  });
  if (!scored) return;
  writeAtomically(out + "/metrics.csv", [&](const std::string& tmp) {
    std::ofstream f(tmp);
    f << "case,object,label,dice,assd_mm,hd95_mm\n";
    for (const Case& c : cases)
      for (const ObjectScore& s : c.scores)
        f << csvField(c.name) << ',' << csvField(s.name) << ',' << s.label << ',' << fixed(s.dice, 4) << ','
          << fixed(s.assdMm, 3) << ',' << fixed(s.hd95Mm, 3) << '\n';
    if (!f.flush()) throw IoError(out + "/metrics.csv", "cannot write");
  });
}

/// The cases: subfolders holding the image, in name order; hidden folders and the output folder are not cases.
/// Returns how many can run.
int findCases(const CohortSettings& b, std::vector<Case>& cases) {
  std::error_code ec;
  if (b.useBids) {
    for (const BidsCase& bc : findBidsCases(b.bids)) {
      Case c;
      c.name = bc.prefix;
      c.image = bc.image;
      c.bids = true;
      c.bidsCase = bc;
      c.atlas = b.atlas;
      c.scene = b.scene;
      c.out = (b.outAbs / ".work" / c.name).string();
      c.log = (b.outAbs / "logs" / (c.name + ".log")).string();
      c.reportPath = bidsReportPath(b.outAbs.string(), bc);
      c.labelsPath = bidsLabelsPath(b.outAbs.string(), bc);
      c.mosaicPath =
          (b.outAbs / fs::path(bc.folder).parent_path() / "figures" / (bc.prefix + "_desc-mosaic_qc.png")).string();
      cases.push_back(c);
    }
    if (cases.empty())
      throw IoError(b.bids.dataset,
                    "no case: no selected sub-*/[ses-*/]anat/ folder holds a *_" + b.bids.suffix + ".nii[.gz] image");
    if (b.scene.empty() && b.atlas.empty()) throw UsageError("missing required option --scene or --atlas");
    return static_cast<int>(cases.size());
  }
  std::vector<fs::path> folders;
  for (const auto& e : fs::directory_iterator(b.casesDir, ec))
    if (e.is_directory() && e.path().filename().string()[0] != '.' &&
        fs::absolute(e.path()).lexically_normal() != b.outAbs)
      folders.push_back(e.path());
  if (ec) throw IoError(b.casesDir, "cannot list: " + ec.message());
  std::sort(folders.begin(), folders.end());
  int runnable = 0;
  for (const fs::path& f : folders) {
    Case c;
    c.name = f.filename().string();
    std::string problem;
    c.image = caseFile(f, b.imageName, problem);
    if (!b.referenceName.empty()) c.reference = caseFile(f, b.referenceName, c.referenceProblem);
    c.atlas = b.atlas;
    if (b.atlas.empty()) c.scene = fs::exists(f / "scene.json") ? fs::absolute(f / "scene.json").string() : b.scene;
    c.out = (b.outAbs / c.name).string();
    c.log = (b.outAbs / "logs" / (c.name + ".log")).string();
    c.reportPath = c.out + "/report.json";
    c.labelsPath = c.out + "/labels.nii.gz";
    c.mosaicPath = c.out + "/qc/mosaic.png";
    if (c.image.empty() && problem.rfind("no ", 0) == 0) {
      c.status = "skipped";
      c.message = problem;
    } else if (c.image.empty()) {
      c.status = "failed";
      c.message = problem;
    } else if (c.scene.empty() && c.atlas.empty()) {
      c.status = "failed";
      c.message = "no scene: give --scene or put a scene.json in the case folder";
      c.exitCode = 2;
    } else {
      ++runnable;
    }
    cases.push_back(c);
  }
  if (b.scene.empty() && b.atlas.empty() &&
      std::none_of(cases.begin(), cases.end(), [](const Case& c) { return !c.scene.empty(); }))
    throw UsageError("missing required option --scene or --atlas (no case folder has a scene.json of its own)");
  if (runnable == 0 && std::none_of(cases.begin(), cases.end(), [](const Case& c) { return c.status == "failed"; }))
    throw IoError(b.casesDir, "no case: no subfolder holds " + b.imageName);
  return runnable;
}

std::string exitCodePath(const CohortSettings& s, const Case& c) {
  return fileInFolder((s.outAbs / "logs").string(), c.name + ".exit");
}

void writeExitCode(const CohortSettings& s, const Case& c) {
  const std::string path = exitCodePath(s, c);
  writeAtomically(path, [&](const std::string& tmp) {
    std::ofstream f(tmp);
    f << c.exitCode << '\n';
    if (!f.flush()) throw IoError(path, "cannot write");
  });
}

Claim::Claim(const fs::path& logs, const std::string& caseName) {
  const std::string path = fileInFolder(logs.string(), "." + caseName + ".claim");
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw IoError(path, std::string("cannot open the claim file: ") + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    fd_ = -1;
    return;
  }
  // Who holds it, for a person looking at the folder (the lock itself is what counts).
  char host[256] = "";
  ::gethostname(host, sizeof host - 1);
  const std::string who = std::string(host) + " " + std::to_string(::getpid()) + "\n";
  const bool noted = ::ftruncate(fd_, 0) == 0 && ::write(fd_, who.data(), who.size()) > 0;
  (void)noted;
}

Claim::~Claim() {
  if (fd_ >= 0) ::close(fd_);
}

void removeStaleStaging(const fs::path& outAbs, const std::vector<Case>& cases) {
  std::error_code ec;
  for (const Case& c : cases) {
    const Claim claim(outAbs / "logs", c.name);
    if (!claim.held()) continue;  // being run now, here or on another machine
    const std::string prefix = "." + c.name + ".partial";
    for (const fs::path& dir : {outAbs, outAbs / ".work"}) {
      if (!fs::is_directory(dir, ec)) continue;
      for (const auto& e : fs::directory_iterator(dir, ec))
        if (e.path().filename().string().rfind(prefix, 0) == 0) fs::remove_all(e.path(), ec);
    }
  }
}

}  // namespace msk::cli
