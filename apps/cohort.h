#pragma once
// A cohort's cases, as `mskseg batch` runs them and `mskseg collect` gathers what separate `mskseg segment` runs of
// them (a Snakemake workflow's jobs) wrote: finding the cases, reading a finished case's results, the summary tables.
#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "batch_bids.h"
#include "cli.h"

namespace msk::cli {

/// One object's scores against the case's reference labels.
struct ObjectScore {
  std::string name;
  int label = 0;
  double dice = 0, assdMm = 0, hd95Mm = 0;
};

/// One case: where it reads and writes, and how it ended.
struct Case {
  std::string name, image, scene, out, log;
  std::string atlas;                        // with --atlas: the atlas folder (then `scene` is empty)
  std::string reference, referenceProblem;  // with --reference: the case's reference labels, or why there are none
  std::string reportPath, labelsPath;       // where the finished case's report and label map are
  bool bids = false;                        // with --bids: `out` is a work folder published into the BIDS layout
  BidsCase bidsCase;
  std::string fingerprint;  // of what produces the case: version, scene or atlas, options, image
  // ok | failed | done (by an earlier run) | stale (done by an earlier run with other inputs, kept by --keep-stale) |
  // skipped (no image) | elsewhere (another batch runs it) | interrupted (the batch was stopped while it ran) |
  // not-started (the batch was stopped first) | pending
  std::string status = "pending";
  std::string message;
  int exitCode = -1;
  double seconds = 0, peakRssMiB = 0;
  std::vector<ObjectScore> scores;
  double meanDice = std::nan(""), minDice = std::nan("");  ///< over `scores` (NaN: none)
  // Signs of trouble that need no reference, from the case's report.json (NaN: not read).
  double worstResidualMm = std::nan("");       ///< largest mean image residual of an object
  double worstVolumeChangePct = std::nan("");  ///< largest |volume / template volume − 1| of an object, %
  double overlapVoxels = std::nan("");         ///< voxels inside two objects
  std::string quality;  ///< the report's status from the image alone: ok | doubtful | failed (empty: not read)
  std::vector<std::pair<std::string, double>> volumesMl;  ///< each object's volume (mL), from the report
  std::string mosaicPath;  ///< where the finished case's QC mosaic is (it may not exist: --no-qc)
};

/// What a batch (or collect) was asked to do.
struct CohortSettings {
  std::string casesDir, scene, atlas, out, imageName = "image.nii.gz", referenceName;
  int jobs = 1;
  bool redo = false, keepStale = false;
  bool useBids = false;  ///< --bids: the cases are the images of a BIDS dataset, the results a BIDS derivative
  BidsSelection bids;
  std::vector<std::string> forwarded;  ///< options after "--", for every case's `mskseg segment`
  std::filesystem::path outAbs;        ///< `out`, absolute
};

/// Adds --image and --reference (the case files, by name or pattern) to a command that reads a cohort folder.
void addCaseFileOptions(CLI::App& app, CohortSettings& s);

/// `s` as one CSV field (quoted if it holds a comma, a quote or a line break).
std::string csvField(const std::string& s);

/// `v` with `digits` decimals.
std::string fixed(double v, int digits);

/// The last line of the case's log that reports an error (what `mskseg segment` printed before failing), else its
/// last non-empty line.
std::string errorLine(const std::string& logPath);

/// The file of case folder `dir` named `pattern`: a path inside the folder whose parts may be shell patterns, such as
/// "*_T1w.nii.gz" or "anat/*_T1w.nii.gz", matching exactly one file. Empty with `problem` set if there is none or more
/// than one.
std::string caseFile(const std::filesystem::path& dir, const std::string& pattern, std::string& problem);

/// Refuses (ParameterError) a --image or --reference pattern that could name a file outside the case folder.
void checkCasePattern(const std::string& option, const std::string& pattern);

/// Reads a finished case's results once: the reference-free checks from its report (left NaN if it cannot be read)
/// and, with `scored`, each object's scores (the names and labels the report lists) against the reference.
void readResults(Case& c, bool scored);

/// OUT/summary.csv and, with `scored`, OUT/metrics.csv (each written atomically).
void writeSummary(const std::string& out, const std::vector<Case>& cases, bool scored);

/// OUT/logs/<case>.exit: the exit code of the case's `mskseg segment` once it has ended (written by batch and by
/// the workflow's jobs; read by collect).
std::string exitCodePath(const CohortSettings& s, const Case& c);

/// Writes c.exitCode to exitCodePath() (atomically).
void writeExitCode(const CohortSettings& s, const Case& c);

/// The cases: subfolders of s.casesDir holding the image, in name order (hidden folders and the output folder are not
/// cases), or the images of the BIDS dataset. Returns how many can run.
int findCases(const CohortSettings& s, std::vector<Case>& cases);

/// OUT/report.html: one self-contained page (no network, thumbnails embedded) with a row per case (status, quality,
/// seconds, each object's volume with outliers against the cohort marked, Dice and ASSD where scored, message) and a
/// thumbnail opening the case's QC mosaic; sortable by any column and filterable by status (also from the address:
/// report.html#sort=<column>&dir=asc|desc&status=<status>). Written atomically.
void writeCohortPage(const std::string& out, const std::vector<Case>& cases, const std::string& title);

/// A case claimed by one process: an exclusive lock (flock) on OUT/logs/.<case>.claim, held while the case runs, the
/// file naming the host and process that hold it. Another batch on the same output folder (a rerun started meanwhile,
/// one on another machine sharing the file system) leaves the case alone; the kernel releases the lock however the
/// holder ends, so no claim outlives its process.
class Claim {
 public:
  /// Tries to claim the case; held() says whether it did. Throws IoError if the claim file cannot be opened.
  Claim(const std::filesystem::path& logs, const std::string& caseName);
  ~Claim();
  Claim(const Claim&) = delete;
  Claim& operator=(const Claim&) = delete;
  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

/// Removes the staging folders that runs killed while writing a case left (OUT/.<case>.partial<pid>, with --bids
/// OUT/.work/.<case>.partial<pid>), of each case that no process holds (see Claim): none of them is being written.
void removeStaleStaging(const std::filesystem::path& outAbs, const std::vector<Case>& cases);

}  // namespace msk::cli
