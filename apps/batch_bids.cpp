#include "batch_bids.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <system_error>

#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/imaging/json.h"

namespace fs = std::filesystem;

namespace msk::cli {

namespace {

/// The folders of `dir` named <key>-<label>, by label, in label order.
std::map<std::string, fs::path> entityFolders(const fs::path& dir, const std::string& key) {
  std::map<std::string, fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (!e.is_directory() || n.rfind(key + "-", 0) != 0 || n.size() == key.size() + 1) continue;
    const std::string label = n.substr(key.size() + 1);
    if (bidsLabel(label) == label) out[label] = e.path();
  }
  return out;
}

/// `labels` without the "<key>-" some users write before them.
std::vector<std::string> bareLabels(const std::vector<std::string>& labels, const std::string& key) {
  std::vector<std::string> out;
  for (const std::string& l : labels) out.push_back(l.rfind(key + "-", 0) == 0 ? l.substr(key.size() + 1) : l);
  return out;
}

bool wanted(const std::vector<std::string>& filter, const std::string& label) {
  return filter.empty() || std::find(filter.begin(), filter.end(), label) != filter.end();
}

bool endsWith(const std::string& s, const std::string& end) {
  return s.size() >= end.size() && s.compare(s.size() - end.size(), end.size(), end) == 0;
}

/// The images of one anat folder: files named <start>..._<suffix>.nii[.gz].
void anatImages(const fs::path& datasetRoot, const fs::path& anat, const std::string& start, const std::string& suffix,
                BidsCase base, std::vector<BidsCase>& out) {
  std::error_code ec;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(anat, ec))
    if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    const std::string n = f.filename().string();
    if (n.rfind(start, 0) != 0) continue;
    for (const std::string ext : {".nii.gz", ".nii"}) {
      const std::string end = "_" + suffix + ext;
      if (!endsWith(n, end)) continue;
      BidsCase c = base;
      c.prefix = n.substr(0, n.size() - end.size());
      c.image = fs::absolute(f).lexically_normal().string();
      c.rawPath = fs::absolute(f).lexically_normal().lexically_relative(datasetRoot).generic_string();
      out.push_back(c);
      break;
    }
  }
}

/// The files an earlier run published for the case in `dir`: <prefix>_ followed by one of the entities only outputs
/// carry (so sub-01's outputs are told from sub-01_run-2's).
std::vector<fs::path> publishedFiles(const fs::path& dir, const std::string& prefix) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(prefix + "_", 0) != 0) continue;
    const std::string rest = n.substr(prefix.size() + 1);
    if (rest.rfind("label-", 0) == 0 || rest.rfind("desc-", 0) == 0 || rest.rfind("from-", 0) == 0)
      out.push_back(e.path());
  }
  return out;
}

/// Renames `from` to `to` (replacing it atomically); throws IoError naming `to`.
void moveFile(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  if (ec) throw IoError(to.string(), "cannot move the result there: " + ec.message());
}

}  // namespace

std::string bidsLabel(const std::string& name) {
  std::string out;
  for (char ch : name)
    if (std::isalnum(static_cast<unsigned char>(ch))) out += ch;
  return out;
}

std::vector<BidsCase> findBidsCases(const BidsSelection& s) {
  std::error_code ec;
  if (!fs::is_directory(s.dataset, ec))
    throw IoError(s.dataset, fs::exists(s.dataset, ec) ? "is not a folder" : "no such folder");
  if (bidsLabel(s.suffix) != s.suffix || s.suffix.empty())
    throw ParameterError("--suffix", s.suffix, "must be letters and digits, e.g. T1w");
  const fs::path root = fs::absolute(s.dataset).lexically_normal();
  const auto subjects = entityFolders(root, "sub");
  if (subjects.empty()) throw IoError(s.dataset, "not a BIDS dataset: it has no sub-<label> folder");
  const std::vector<std::string> participants = bareLabels(s.participants, "sub");
  const std::vector<std::string> sessions = bareLabels(s.sessions, "ses");
  for (const std::string& p : participants)
    if (!subjects.count(p)) throw UsageError("--participant-label " + p + ": " + s.dataset + " has no folder sub-" + p);
  std::vector<BidsCase> out;
  bool sessionSeen = sessions.empty();
  for (const auto& [subject, folder] : subjects) {
    if (!wanted(participants, subject)) continue;
    BidsCase base;
    base.subject = subject;
    const auto sessionFolders = entityFolders(folder, "ses");
    if (sessionFolders.empty()) {
      if (!sessions.empty()) continue;
      base.folder = "sub-" + subject + "/anat";
      anatImages(root, folder / "anat", "sub-" + subject + "_", s.suffix, base, out);
      continue;
    }
    for (const auto& [session, sessionFolder] : sessionFolders) {
      if (!wanted(sessions, session)) continue;
      sessionSeen = true;
      base.session = session;
      base.folder = "sub-" + subject + "/ses-" + session + "/anat";
      anatImages(root, sessionFolder / "anat", "sub-" + subject + "_ses-" + session + "_", s.suffix, base, out);
    }
  }
  if (!sessionSeen) throw UsageError("--session: no selected subject of " + s.dataset + " has such a session");
  return out;
}

std::string bidsReportPath(const std::string& outRoot, const BidsCase& c) {
  return (fs::path(outRoot) / c.folder / (c.prefix + "_desc-mskseg_dseg.json")).string();
}

std::string bidsLabelsPath(const std::string& outRoot, const BidsCase& c) {
  return (fs::path(outRoot) / c.folder / (c.prefix + "_desc-mskseg_dseg.nii.gz")).string();
}

void publishBidsCase(const std::string& work, const std::string& outRoot, const BidsCase& c,
                     const std::string& suffix) {
  const fs::path from(work);
  const Json report = readJsonFile((from / "report.json").string());
  // Object name -> BIDS label value; two names with one value would overwrite each other's files.
  std::map<std::string, std::string> labelOf, nameOfLabel;
  for (const Json& o : report.at("objects")) {
    const std::string name = o.at("name").get<std::string>(), label = bidsLabel(name);
    if (label.empty()) throw Error("object \"" + name + "\": its name has no letter or digit for a BIDS label");
    if (nameOfLabel.count(label))
      throw Error("objects \"" + nameOfLabel[label] + "\" and \"" + name + "\" give the same BIDS label \"" + label +
                  "\" (rename one in the scene)");
    labelOf[name] = label;
    nameOfLabel[label] = name;
  }
  const fs::path anat = fs::path(outRoot) / c.folder, figures = anat.parent_path() / "figures";
  std::error_code ec;
  for (const fs::path& dir : {anat, figures}) {
    fs::create_directories(dir, ec);
    if (ec) throw IoError(dir.string(), "cannot create folder: " + ec.message());
  }
  // An earlier run's results go first, the sidecar (which marks the case done) before anything else.
  fs::remove(bidsReportPath(outRoot, c), ec);
  for (const fs::path& dir : {anat, figures})
    for (const fs::path& old : publishedFiles(dir, c.prefix)) fs::remove(old, ec);

  const std::string p = c.prefix + "_";
  for (const auto& e : fs::directory_iterator(from)) {
    const std::string n = e.path().filename().string();
    if (e.is_directory() && n == "labels") {
      // labels/<object>.nii.gz (--split) -> <prefix>_label-<object>_desc-mskseg_mask.nii.gz
      for (const auto& m : fs::directory_iterator(e.path())) {
        const std::string mn = m.path().filename().string();
        const std::string object = mn.size() > 7 ? mn.substr(0, mn.size() - 7) : mn;
        if (!labelOf.count(object) || mn.compare(mn.size() - 7, 7, ".nii.gz") != 0)
          throw Error("unexpected file " + m.path().string() + " in a case's output");
        moveFile(m.path(), anat / (p + "label-" + labelOf[object] + "_desc-mskseg_mask.nii.gz"));
      }
      continue;
    }
    if (e.is_directory()) {
      if (n != "qc") throw Error("unexpected folder " + e.path().string() + " in a case's output");
      for (const auto& q : fs::directory_iterator(e.path())) {
        // qc/<object>_<view>.png -> figures/<prefix>_label-<object>_desc-<view>_qc.png
        const std::string qn = q.path().filename().string();
        std::string target;
        for (const auto& [name, label] : labelOf)
          for (const char* view : {"axial", "coronal", "sagittal"})
            if (qn == name + "_" + view + ".png") target = p + "label-" + label + "_desc-" + view + "_qc.png";
        if (target.empty()) target = p + "desc-" + bidsLabel(q.path().stem().string()) + "_qc.png";
        moveFile(q.path(), figures / target);
      }
      continue;
    }
    if (n == "report.json") continue;
    const std::string stem = e.path().stem().string(), ext = e.path().extension().string();
    std::string target;
    if (n == "labels.nii.gz")
      target = p + "desc-mskseg_dseg.nii.gz";
    else if (n == "labels.tsv")
      target = p + "desc-mskseg_dseg.tsv";
    else if (n == "labels.ctbl")
      target = p + "desc-mskseg_dseg.ctbl";
    else if (n == "labels.itksnap.txt")
      target = p + "desc-mskseg_dseg.itksnap.txt";
    else if (n == "labels.vti")
      target = p + "desc-mskseg_dseg.vti";
    else if (n == "image.vti")
      target = p + "desc-mskseg_" + suffix + ".vti";
    else if (n == "statistics.json" || n == "statistics.csv")
      target = p + "desc-mskseg_statistics" + ext;
    else if (n == "placement.tfm")
      target = p + "from-atlas_to-" + suffix + "_mode-image_xfm.tfm";
    else if (labelOf.count(stem))
      target = p + "label-" + labelOf[stem] + "_desc-mskseg_" + (ext == ".vtu" ? "tetmesh" : "mesh") + ext;
    else
      target = p + "desc-mskseg" + bidsLabel(stem) + "_" + bidsLabel(ext) + ext;
    moveFile(e.path(), anat / target);
  }

  Json sidecar;
  sidecar["Sources"] = Json::array({"bids:raw:" + c.rawPath});
  for (const auto& item : report.items()) sidecar[item.key()] = item.value();
  writeJsonFile(bidsReportPath(outRoot, c), sidecar);
  fs::remove_all(from, ec);
  fs::remove(figures, ec);  // only if it is empty (a run without QC pictures)
}

void writeBidsDescription(const std::string& outRoot, const std::string& dataset, const std::string& commandLine) {
  const std::string raw = "file://" + fs::absolute(dataset).lexically_normal().string();
  std::string name = fs::absolute(dataset).lexically_normal().filename().string();
  try {  // the raw dataset's own name, if it states one
    const Json d = readJsonFile((fs::path(dataset) / "dataset_description.json").string());
    if (const Json* n = jsonMember(d, "Name"); n && n->is_string()) name = n->get<std::string>();
  } catch (const Error&) {
  }
  Json j;
  j["Name"] = "mskseg segmentations of " + name;
  j["BIDSVersion"] = "1.9.0";
  j["DatasetType"] = "derivative";
  Json by;
  by["Name"] = "mskseg";
  by["Version"] = MSK_VERSION;
  by["Description"] = commandLine;
  j["GeneratedBy"] = Json::array({by});
  Json source;
  source["URL"] = raw;
  j["SourceDatasets"] = Json::array({source});
  j["DatasetLinks"]["raw"] = raw;
  writeJsonFile((fs::path(outRoot) / "dataset_description.json").string(), j);
}

}  // namespace msk::cli
