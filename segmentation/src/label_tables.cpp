#include "msk/segmentation/label_tables.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/segmentation/qc_pictures.h"

namespace msk {

namespace {

void writeText(const std::string& path, const std::string& text) {
  writeAtomically(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    if (!f.flush()) throw IoError(path, "cannot write");
  });
}

std::string hexColour(const std::array<uint8_t, 3>& rgb) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", rgb[0], rgb[1], rgb[2]);
  return buf;
}

Json vec(const Eigen::Vector3d& v) { return Json::array({v[0], v[1], v[2]}); }

}  // namespace

std::vector<LabelEntry> labelEntries(const Scene& scene) {
  std::vector<LabelEntry> out;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    LabelEntry e;
    e.label = o.label;
    e.name = o.name;
    e.rgb = qcObjectColour(i);
    if (o.colour)
      for (int c = 0; c < 3; ++c)
        e.rgb[static_cast<size_t>(c)] = static_cast<uint8_t>((*o.colour)[static_cast<size_t>(c)]);
    out.push_back(e);
  }
  return out;
}

std::vector<std::string> writeLabelTables(const std::string& dir, const std::vector<LabelEntry>& labels) {
  std::vector<LabelEntry> sorted = labels;
  std::sort(sorted.begin(), sorted.end(), [](const LabelEntry& a, const LabelEntry& b) { return a.label < b.label; });
  // 3D Slicer colour table: "# comment" lines, then "value name r g b a" (names without spaces).
  std::ostringstream slicer;
  slicer
      << "# 3D Slicer colour table of mskseg's label map (labels.nii.gz)\n# value name R G B A\n0 background 0 0 0 0\n";
  for (const LabelEntry& e : sorted)
    slicer << e.label << ' ' << e.name << ' ' << int(e.rgb[0]) << ' ' << int(e.rgb[1]) << ' ' << int(e.rgb[2])
           << " 255\n";
  // ITK-SNAP label description: IDX R G B A VIS MSH "LABEL".
  std::ostringstream snap;
  snap << "################################################\n# ITK-SnAP Label Description File\n"
       << "# mskseg's label map (labels.nii.gz)\n# Columns: IDX -R- -G- -B- -A-- VIS MSH LABEL\n"
       << "################################################\n    0     0    0    0        0  0  0    \"Clear Label\"\n";
  for (const LabelEntry& e : sorted) {
    char line[256];
    std::snprintf(line, sizeof line, "%5d %5d %4d %4d        1  1  1    \"%s\"\n", e.label, e.rgb[0], e.rgb[1],
                  e.rgb[2], e.name.c_str());
    snap << line;
  }
  // BIDS dseg.tsv.
  std::ostringstream tsv;
  tsv << "index\tname\tcolor\n";
  for (const LabelEntry& e : sorted) tsv << e.label << '\t' << e.name << '\t' << hexColour(e.rgb) << '\n';

  const std::vector<std::string> paths = {fileInFolder(dir, "labels.ctbl"), fileInFolder(dir, "labels.itksnap.txt"),
                                          fileInFolder(dir, "labels.tsv")};
  writeText(paths[0], slicer.str());
  writeText(paths[1], snap.str());
  writeText(paths[2], tsv.str());
  return paths;
}

Json structureStatistics(const ImageF& image, const SegmentationResult& result) {
  const Grid& g = result.labels.grid;
  const double voxelMl = g.spacing.prod() / 1000.0;  // the direction matrix is orthonormal
  Json out = Json::array();
  for (const ObjectResult& o : result.objects) {
    std::vector<double> values;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    size_t count = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i) {
          if (result.labels.at(i, j, k) != o.label) continue;
          ++count;
          const Eigen::Vector3d w = g.toWorld(Eigen::Vector3d(i, j, k));
          sum += w;
          lo = lo.cwiseMin(w);
          hi = hi.cwiseMax(w);
          const float v = image.at(i, j, k);
          if (std::isfinite(v)) values.push_back(v);
        }
    Json s;
    s["name"] = o.name;
    s["label"] = o.label;
    s["voxels"] = count;
    s["volume_labels_ml"] = static_cast<double>(count) * voxelMl;
    s["volume_mesh_ml"] = enclosedVolume(o.mesh) / 1000.0;
    s["surface_area_mm2"] = surfaceArea(o.mesh);
    if (!values.empty()) {
      double mean = 0;
      for (double v : values) mean += v;
      mean /= static_cast<double>(values.size());
      double var = 0;
      for (double v : values) var += (v - mean) * (v - mean);
      std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
      s["intensity_mean"] = mean;
      s["intensity_median"] = values[values.size() / 2];
      s["intensity_sd"] = std::sqrt(var / static_cast<double>(values.size()));
    }
    if (count > 0) {
      s["centroid_ras_mm"] = vec(sum / static_cast<double>(count));
      s["bbox_min_ras_mm"] = vec(lo);
      s["bbox_max_ras_mm"] = vec(hi);
    }
    out.push_back(s);
  }
  return out;
}

std::string statisticsCsv(const Json& statistics) {
  std::ostringstream f;
  f << "name,label,voxels,volume_labels_ml,volume_mesh_ml,surface_area_mm2,intensity_mean,intensity_median,"
       "intensity_sd,centroid_x,centroid_y,centroid_z,bbox_min_x,bbox_min_y,bbox_min_z,bbox_max_x,bbox_max_y,"
       "bbox_max_z\n";
  auto num = [](const Json& s, const char* key) -> std::string {
    const Json* v = jsonMember(s, key);
    if (!v || !v->is_number()) return "";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", v->get<double>());
    return buf;
  };
  auto triple = [](const Json& s, const char* key) -> std::string {
    const Json* v = jsonMember(s, key);
    if (!v) return ",,";
    char buf[128];
    std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f", (*v)[0].get<double>(), (*v)[1].get<double>(),
                  (*v)[2].get<double>());
    return buf;
  };
  for (const Json& s : statistics)
    f << s.at("name").get<std::string>() << ',' << s.at("label").get<int>() << ',' << num(s, "voxels") << ','
      << num(s, "volume_labels_ml") << ',' << num(s, "volume_mesh_ml") << ',' << num(s, "surface_area_mm2") << ','
      << num(s, "intensity_mean") << ',' << num(s, "intensity_median") << ',' << num(s, "intensity_sd") << ','
      << triple(s, "centroid_ras_mm") << ',' << triple(s, "bbox_min_ras_mm") << ',' << triple(s, "bbox_max_ras_mm")
      << '\n';
  return f.str();
}

}  // namespace msk
