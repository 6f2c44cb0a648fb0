// mskseg info: what a NIfTI volume or a mesh file holds, in world terms.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

#include "commands.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/surface_quality.h"

namespace msk::cli {
namespace {

Json matrixJson(const Eigen::MatrixXd& m) {
  Json rows = Json::array();
  for (int r = 0; r < m.rows(); ++r) {
    Json row = Json::array();
    for (int c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(row);
  }
  return rows;
}

Json vecJson(const Eigen::VectorXd& v) {
  Json a = Json::array();
  for (int i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}

std::string fmt(double v, int prec = 4) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

/// Three-letter orientation code (e.g. "RAS", "LPS") of the voxel axes: the dominant world axis of each direction
/// column.
std::string orientationCode(const Eigen::Matrix3d& d) {
  std::string code;
  for (int c = 0; c < 3; ++c) {
    int a = 0;
    d.col(c).cwiseAbs().maxCoeff(&a);
    const char* pos = "RAS";
    const char* neg = "LPI";
    code += d(a, c) >= 0 ? pos[a] : neg[a];
  }
  return code;
}

/// Voxel count, volume, centroid and bounds (voxel centres, RAS mm) of one label of a label map.
struct LabelStats {
  long voxels = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
};

/// Every non-zero label of `vol`; throws Error naming `path` if a value is not a whole number.
std::map<long, LabelStats> labelStats(const Volume<double>& vol, const std::string& path) {
  std::map<long, LabelStats> out;
  const Grid& g = vol.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double v = vol.at(i, j, k);
        if (!(v == std::floor(v)) || std::fabs(v) > 2147483647.0)
          throw Error(path + ": --labels needs whole-number voxel values, voxel (" + std::to_string(i) + ", " +
                      std::to_string(j) + ", " + std::to_string(k) + ") holds " + fmt(v, 4));
        if (v == 0) continue;
        LabelStats& st = out[static_cast<long>(v)];
        const Eigen::Vector3d p = g.toWorld(Eigen::Vector3d(i, j, k));
        ++st.voxels;
        st.sum += p;
        st.lo = st.lo.cwiseMin(p);
        st.hi = st.hi.cwiseMax(p);
      }
  return out;
}

int infoVolume(const std::string& path, bool json, bool labels) {
  NiftiInfo info;
  NiftiReadOptions ro;
  ro.allowNonFinite = true;
  Volume<double> vol = readNifti<double>(path, &info, ro);
  const Grid& g = vol.grid;
  const double voxelMl = g.spacing.prod() / 1000.0;
  if (json) {
    Json j;
    j["file"] = path;
    j["kind"] = "volume";
    j["nifti_version"] = info.version;
    j["dims"] = Json::array({g.dims[0], g.dims[1], g.dims[2]});
    j["spacing_mm"] = vecJson(g.spacing);
    j["origin_ras_mm"] = vecJson(g.origin);
    j["direction"] = matrixJson(g.direction);
    j["orientation"] = orientationCode(g.direction);
    j["affine_ras"] = matrixJson(g.voxelToWorld());
    j["affine_source"] = affineSourceName(info.affineSource);
    j["sform_code"] = info.sformCode;
    j["qform_code"] = info.qformCode;
    j["datatype"] = dataTypeName(info.datatype);
    j["scl_slope"] = info.sclSlope;
    j["scl_inter"] = info.sclInter;
    j["min"] = info.minValue;
    j["max"] = info.maxValue;
    j["nonfinite_count"] = info.nonFiniteCount;
    if (labels) {
      Json list = Json::array();
      for (const auto& [label, st] : labelStats(vol, path)) {
        Json l;
        l["label"] = label;
        l["voxels"] = st.voxels;
        l["volume_ml"] = st.voxels * voxelMl;
        l["centroid_ras_mm"] = vecJson(st.sum / static_cast<double>(st.voxels));
        l["bounds_ras_min"] = vecJson(st.lo);
        l["bounds_ras_max"] = vecJson(st.hi);
        list.push_back(l);
      }
      j["labels"] = list;
    }
    std::cout << dumpJson(j, 2) << "\n";
    return 0;
  }
  std::ostringstream o;
  o << "file          " << path << "\n"
    << "format        NIfTI-" << info.version << "\n"
    << "dims          " << g.dims[0] << " x " << g.dims[1] << " x " << g.dims[2] << "  (" << g.voxelCount()
    << " voxels)\n"
    << "spacing       " << fmt(g.spacing[0]) << " x " << fmt(g.spacing[1]) << " x " << fmt(g.spacing[2]) << " mm\n"
    << "orientation   " << orientationCode(g.direction) << " (voxel axes i, j, k point to)\n"
    << "affine from   " << affineSourceName(info.affineSource) << "  (sform_code " << info.sformCode << ", qform_code "
    << info.qformCode << ")\n"
    << "voxel->RAS mm\n";
  Eigen::Matrix4d a = g.voxelToWorld();
  for (int r = 0; r < 3; ++r)
    o << "  [" << fmt(a(r, 0), 6) << ", " << fmt(a(r, 1), 6) << ", " << fmt(a(r, 2), 6) << ", " << fmt(a(r, 3), 4)
      << "]\n";
  o << "voxel (0,0,0) RAS (" << fmt(g.origin[0], 2) << ", " << fmt(g.origin[1], 2) << ", " << fmt(g.origin[2], 2)
    << ") mm\n"
    << "datatype      " << dataTypeName(info.datatype);
  if (info.scaled) o << "  (scaled: slope " << info.sclSlope << ", intercept " << info.sclInter << ")";
  o << "\nrange         " << info.minValue << " .. " << info.maxValue << "\n"
    << "NaN/Inf       " << info.nonFiniteCount << "\n";
  if (labels) {
    const std::map<long, LabelStats> stats = labelStats(vol, path);
    o << "labels        " << stats.size() << " besides 0 (centroid x, y, z and bounds of the voxel centres, RAS mm)\n";
    char line[256];
    std::snprintf(line, sizeof line, "  %8s %10s %11s %9s %9s %9s   %s\n", "label", "voxels", "volume_mL", "x", "y",
                  "z", "bounds x, y, z");
    o << line;
    for (const auto& [label, st] : stats) {
      const Eigen::Vector3d c = st.sum / static_cast<double>(st.voxels);
      std::snprintf(line, sizeof line, "  %8ld %10ld %11.3f %9.2f %9.2f %9.2f   %.1f..%.1f, %.1f..%.1f, %.1f..%.1f\n",
                    label, st.voxels, st.voxels * voxelMl, c[0], c[1], c[2], st.lo[0], st.hi[0], st.lo[1], st.hi[1],
                    st.lo[2], st.hi[2]);
      o << line;
    }
  }
  std::cout << o.str();
  return 0;
}

/// Whether a closed mesh can be a template: "ok", "wound inward (...)" or "unusable: <problem>".
std::string templateStatus(const TriangleMesh& m) {
  const std::string problem = templateProblem(m);
  if (!problem.empty()) return "unusable: " + problem;
  if (enclosedVolume(m) < 0) return "wound inward (negative volume; a scene turns it outward)";
  return "ok";
}

int infoMesh(const std::string& path, bool json) {
  MeshSpace space = MeshSpace::LPS;
  TriangleMesh m = readMesh(path, &space);
  Eigen::Vector3d lo = m.vertices.colwise().minCoeff(), hi = m.vertices.colwise().maxCoeff();
  if (json) {
    Json j;
    j["file"] = path;
    j["kind"] = "mesh";
    j["file_space"] = meshSpaceName(space);
    j["vertices"] = m.vertexCount();
    j["faces"] = m.faceCount();
    j["volume_mm3"] = enclosedVolume(m);
    j["area_mm2"] = surfaceArea(m);
    j["bounds_ras_min"] = vecJson(lo);
    j["bounds_ras_max"] = vecJson(hi);
    Json arrays = Json::array();
    for (const auto& kv : m.pointData) arrays.push_back(kv.first);
    j["point_arrays"] = arrays;
    j["as_template"] = templateStatus(m);
    std::cout << dumpJson(j, 2) << "\n";
    return 0;
  }
  std::cout << "file          " << path << "\n"
            << "space in file " << meshSpaceName(space) << "\n"
            << "vertices      " << m.vertexCount() << "\nfaces         " << m.faceCount() << "\n"
            << "volume        " << fmt(enclosedVolume(m) / 1000.0, 3) << " mL\n"
            << "area          " << fmt(surfaceArea(m), 1) << " mm^2\n"
            << "bounds (RAS)  (" << fmt(lo[0], 2) << ", " << fmt(lo[1], 2) << ", " << fmt(lo[2], 2) << ") .. ("
            << fmt(hi[0], 2) << ", " << fmt(hi[1], 2) << ", " << fmt(hi[2], 2) << ") mm\n"
            << "as a template " << templateStatus(m) << "\n";
  if (!m.pointData.empty()) {
    std::cout << "point arrays ";
    for (const auto& kv : m.pointData) std::cout << " " << kv.first;
    std::cout << "\n";
  }
  return 0;
}

}  // namespace

int cmdInfo(const std::vector<std::string>& argv) {
  CommandLine app(
      "info",
      "FILE is a NIfTI volume (.nii, .nii.gz): prints dims, spacing, the voxel->RAS affine and which header form it "
      "came from (sform, qform or pixdim), datatype and scaling, value range and NaN/Inf count; or a mesh (.vtk .vtp "
      ".stl .obj .ply): vertices, faces, volume, area, bounds and the file's space.");
  std::string path;
  bool json = false, labels = false;
  app.add_option("file", path, "the volume or mesh")->required();
  app.add_flag("--json", json, "print JSON");
  app.add_flag("--labels", labels,
               "a label map: each non-zero label's voxel count, volume, centroid and bounds (RAS mm), e.g. to find "
               "the labels to put in a scene, or a midline landmark for --mirror-x");
  if (!parseArgs(app, argv)) return 0;
  if (isMeshFile(path)) {
    if (labels) throw UsageError("--labels is for a label map, not a mesh");
    return infoMesh(path, json);
  }
  return infoVolume(path, json, labels);
}

}  // namespace msk::cli
