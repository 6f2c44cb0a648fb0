// mskseg eval: overlap and surface-distance metrics between label maps or between meshes.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/metrics.h"

namespace fs = std::filesystem;

namespace msk::cli {
namespace {

struct Row {
  std::string name;
  SegmentationMetrics m;
  int label = 0;  ///< the label scored (0: meshes)
};

std::vector<int32_t> parseLabels(const std::string& text) {
  std::vector<int32_t> out;
  std::stringstream ss(text);
  std::string p;
  while (std::getline(ss, p, ',')) {
    char* end = nullptr;
    const double v = std::strtod(p.c_str(), &end);
    if (p.empty() || end != p.c_str() + p.size() || v != std::floor(v) || v < 1 || v > 2147483647.0)
      throw UsageError("option --labels expects positive integers, got '" + p + "'");
    out.push_back(static_cast<int32_t>(v));
  }
  if (out.empty()) throw UsageError("option --labels is empty");
  return out;
}

Json metricsJson(const Row& r) {
  Json j;
  j["object"] = r.name;
  if (r.label != 0) j["label"] = r.label;
  auto num = [](double v) { return std::isfinite(v) ? Json(v) : Json(); };
  j["dice"] = num(r.m.dice);
  j["jaccard"] = num(r.m.jaccard);
  j["assd_mm"] = num(r.m.assd);
  j["mean_result_to_reference_mm"] = num(r.m.meanAtoB);
  j["mean_reference_to_result_mm"] = num(r.m.meanBtoA);
  j["hd95_mm"] = num(r.m.hd95);
  j["hausdorff_mm"] = num(r.m.hausdorff);
  j["volume_result_mm3"] = num(r.m.volumeA);
  j["volume_reference_mm3"] = num(r.m.volumeB);
  return j;
}

/// The label table mskseg writes beside its label map (labels.tsv: index, name, colour), label -> name; empty if the
/// result has none.
std::map<int32_t, std::string> labelNamesBeside(const std::string& labelMapPath) {
  std::map<int32_t, std::string> names;
  std::ifstream in((fs::path(labelMapPath).parent_path() / "labels.tsv").string());
  std::string line;
  if (!std::getline(in, line) || line.rfind("index\tname", 0) != 0) return names;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string index, name;
    if (std::getline(fields, index, '\t') && std::getline(fields, name, '\t') && !name.empty()) {
      try {
        names[std::stoi(index)] = name;
      } catch (const std::exception&) {
        return {};
      }
    }
  }
  return names;
}

/// The row of a mesh scored against one label of a label map: the mesh rasterised on the map's grid (a voxel counts
/// inside when its centre is), then compared voxel by voxel. `label` is --labels' one label, else the map's only one.
Row meshAgainstLabelMap(const std::string& a, const std::string& b, const std::string& labelsText) {
  const bool resultIsMesh = isMeshFile(a);
  const std::string meshPath = resultIsMesh ? a : b, mapPath = resultIsMesh ? b : a;
  const LabelMap map = readNifti<int32_t>(mapPath);
  std::set<int32_t> present;
  for (int32_t v : map.data)
    if (v != 0) present.insert(v);
  int32_t label = 0;
  if (!labelsText.empty()) {
    const std::vector<int32_t> given = parseLabels(labelsText);
    if (given.size() != 1)
      throw UsageError("a mesh against a label map: --labels takes one label, the mesh's structure in the map");
    label = given[0];
  } else if (present.size() == 1) {
    label = *present.begin();
  } else {
    throw UsageError("a mesh against a label map of " + std::to_string(present.size()) +
                     " labels: give --labels with the label of the mesh's structure");
  }
  if (!present.count(label)) throw IoError(mapPath, "has no voxel of label " + std::to_string(label));
  const LabelMap meshMap = rasterize(readMesh(meshPath), map.grid);
  const SegmentationMetrics m =
      resultIsMesh ? labelMetrics(meshMap, 1, map, label) : labelMetrics(map, label, meshMap, 1);
  const std::map<int32_t, std::string> names = labelNamesBeside(mapPath);
  const auto named = names.find(label);
  return {named != names.end() ? named->second : fs::path(meshPath).stem().string(), m, label};
}

}  // namespace

int cmdEval(const std::vector<std::string>& argv) {
  CommandLine app(
      "eval",
      "A and B are label maps on the same grid (.nii/.nii.gz), two closed meshes (.vtk .vtp .stl .obj .ply), or a "
      "mesh and a label map (the mesh rasterised on the map's grid, against one label: --labels L, or the map's only "
      "label). Prints Dice, Jaccard, average symmetric surface distance (ASSD), HD95 and "
      "Hausdorff distance in mm (definitions in docs/measurements.md). Label maps: the labels named in the result's "
      "label table (labels.tsv beside it, as mskseg writes it; rows named after its objects), else every label of the "
      "reference, unless --labels.");
  std::string a, b, labelsText, jsonPath, csvPath;
  double voxel = 0.5;
  app.add_option("--result", a, "the segmentation (label map or mesh)")->required();
  app.add_option("--reference", b, "the reference (label map or mesh)")->required();
  app.add_option("--labels", labelsText,
                 "labels to score, e.g. 1,2,3 (default: those of the result's labels.tsv, else every label of the "
                 "reference)");
  app.add_option("--json", jsonPath, "write the figures as JSON ('-': stdout, instead of the table)");
  app.add_option("--csv", csvPath, "write the figures as CSV ('-': stdout, instead of the table)");
  addNumber(app, "--voxel", voxel, "grid spacing of the mesh overlap, mm, (0.05, 10] (default 0.5)");
  if (!parseArgs(app, argv)) return 0;
  if (!(voxel > 0.05 && voxel <= 10))
    throw ParameterError("--voxel", std::to_string(voxel), "must be in (0.05, 10] mm");
  std::vector<Row> rows;
  if (isMeshFile(a) != isMeshFile(b)) {
    rows.push_back(meshAgainstLabelMap(a, b, labelsText));
  } else if (isMeshFile(a)) {
    rows.push_back({"mesh", meshMetrics(readMesh(a), readMesh(b), voxel)});
  } else {
    LabelMap la = readNifti<int32_t>(a), lb = readNifti<int32_t>(b);
    if (!la.grid.sameGeometry(lb.grid))
      throw IoError(a, "label map is not on the reference's grid (" + b + "): resample it first");
    std::vector<int32_t> labels;
    const std::map<int32_t, std::string> names = labelNamesBeside(a);
    if (!labelsText.empty()) {
      labels = parseLabels(labelsText);
    } else if (!names.empty()) {
      for (const auto& [label, name] : names) labels.push_back(label);
    } else {
      std::set<int32_t> s;
      for (int32_t v : lb.data)
        if (v != 0) s.insert(v);
      labels.assign(s.begin(), s.end());
      if (labels.empty()) throw IoError(b, "reference has no labelled voxels");
    }
    for (int32_t l : labels) {
      const auto named = names.find(l);
      rows.push_back({named != names.end() ? named->second : std::to_string(l), labelMetrics(la, l, lb, l), l});
    }
  }
  if (jsonPath != "-" && csvPath != "-") {  // stdout carries the table unless it carries JSON or CSV
    size_t width = 8;
    for (const auto& r : rows) width = std::max(width, r.name.size());
    std::printf("%-*s %8s %8s %9s %9s %10s %12s %12s\n", static_cast<int>(width), "object", "dice", "jaccard",
                "assd_mm", "hd95_mm", "hausd_mm", "vol_res_mL", "vol_ref_mL");
    for (const auto& r : rows)
      std::printf("%-*s %8.4f %8.4f %9.3f %9.3f %10.3f %12.3f %12.3f\n", static_cast<int>(width), r.name.c_str(),
                  r.m.dice, r.m.jaccard, r.m.assd, r.m.hd95, r.m.hausdorff, r.m.volumeA / 1000.0, r.m.volumeB / 1000.0);
  }
  if (!jsonPath.empty()) {
    Json j;
    j["result"] = a;
    j["reference"] = b;
    j["mskseg_version"] = MSK_VERSION;
    Json list = Json::array();
    for (const auto& r : rows) list.push_back(metricsJson(r));
    j["metrics"] = list;
    if (jsonPath == "-")
      std::cout << dumpJson(j, 2) << "\n";
    else
      writeJsonFile(jsonPath, j);
  }
  if (!csvPath.empty()) {
    std::ostringstream c;
    c << "object,dice,jaccard,assd_mm,hd95_mm,hausdorff_mm,volume_result_mm3,volume_reference_mm3\n";
    c.precision(8);
    for (const auto& r : rows)
      c << r.name << "," << r.m.dice << "," << r.m.jaccard << "," << r.m.assd << "," << r.m.hd95 << "," << r.m.hausdorff
        << "," << r.m.volumeA << "," << r.m.volumeB << "\n";
    if (csvPath == "-") {
      std::cout << c.str();
    } else {
      writeAtomically(csvPath, [&](const std::string& tmp) {
        std::ofstream f(tmp);
        f << c.str();
        if (!f) throw IoError(csvPath, "write failed");
      });
    }
  }
  return 0;
}

}  // namespace msk::cli
