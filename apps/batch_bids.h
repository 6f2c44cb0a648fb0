#pragma once
// BIDS for `mskseg batch --bids`: the cases of a raw BIDS dataset (sub-<label>/[ses-<label>/]anat/*_<suffix>.nii[.gz])
// and their results in the BIDS derivatives layout (OUT/sub-<label>/[ses-<label>/]anat/, entity-named files).
#include <string>
#include <vector>

namespace msk::cli {

/// What --bids selects.
struct BidsSelection {
  std::string dataset;                    ///< the raw dataset's folder
  std::vector<std::string> participants;  ///< labels without "sub-" (empty: every subject)
  std::vector<std::string> sessions;      ///< labels without "ses-" (empty: every session)
  std::string suffix = "T1w";             ///< the images' suffix
};

/// One image of the dataset, a case.
struct BidsCase {
  std::string subject, session;  ///< entity labels (session empty if the dataset has none for the subject)
  std::string prefix;            ///< the image's name without "_<suffix>.nii[.gz]": sub-01[_ses-1][_acq-x][_run-1]
  std::string image;             ///< absolute path of the image
  std::string rawPath;           ///< the image's path inside the dataset (sub-01/ses-1/anat/...)
  std::string folder;            ///< its derivatives folder inside OUT: sub-01[/ses-1]/anat
};

/// The dataset's images of the selection, in path order. Throws IoError naming the dataset folder if it is not a BIDS
/// dataset (no sub-* folder), UsageError if a requested participant or session does not exist.
std::vector<BidsCase> findBidsCases(const BidsSelection& selection);

/// The derivative's file that holds the case's report (its presence marks the case done): the segmentation's JSON
/// sidecar, OUT/<folder>/<prefix>_desc-mskseg_dseg.json.
std::string bidsReportPath(const std::string& outRoot, const BidsCase& c);

/// The derivative's label map, OUT/<folder>/<prefix>_desc-mskseg_dseg.nii.gz.
std::string bidsLabelsPath(const std::string& outRoot, const BidsCase& c);

/// Moves what `mskseg segment` wrote into `work` to the case's derivatives folder under BIDS names, each file by an
/// atomic rename, the JSON sidecar (report and Sources) last; then removes `work`. Throws Error naming the file or
/// object that cannot be published (two object names that give the same BIDS label, say).
void publishBidsCase(const std::string& work, const std::string& outRoot, const BidsCase& c, const std::string& suffix);

/// OUT/dataset_description.json of the derivative dataset (written atomically).
void writeBidsDescription(const std::string& outRoot, const std::string& dataset, const std::string& commandLine);

/// `name` as a BIDS label value (its letters and digits).
std::string bidsLabel(const std::string& name);

}  // namespace msk::cli
