// mskseg info: what a NIfTI volume or a mesh file holds, in world terms.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "args.h"
#include "commands.h"
#include "msk/core/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"

namespace msk::cli {
namespace {

Json matrixJson(const Eigen::MatrixXd& m) {
  Json rows = Json::array();
  for (int r = 0; r < m.rows(); ++r) {
    Json row = Json::array();
    for (int c = 0; c < m.cols(); ++c) row.push(m(r, c));
    rows.push(row);
  }
  return rows;
}

Json vecJson(const Eigen::VectorXd& v) {
  Json a = Json::array();
  for (int i = 0; i < v.size(); ++i) a.push(v[i]);
  return a;
}

std::string fmt(double v, int prec = 4) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

/// Three-letter orientation code (e.g. "RAS", "LPS") of the voxel axes: the dominant world axis of each direction column.
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

int infoVolume(const std::string& path, bool json) {
  NiftiInfo info;
  NiftiReadOptions ro;
  ro.allowNonFinite = true;
  Volume<double> vol = readNifti<double>(path, &info, ro);
  const Grid& g = vol.grid;
  if (json) {
    Json j;
    j["file"] = path;
    j["kind"] = "volume";
    j["nifti_version"] = info.version;
    j["dims"] = vecJson(g.dims.cast<double>());
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
    j["nonfinite_count"] = static_cast<double>(info.nonFiniteCount);
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::ostringstream o;
  o << "file          " << path << "\n"
    << "format        NIfTI-" << info.version << "\n"
    << "dims          " << g.dims[0] << " x " << g.dims[1] << " x " << g.dims[2] << "  (" << g.voxelCount()
    << " voxels)\n"
    << "spacing       " << fmt(g.spacing[0]) << " x " << fmt(g.spacing[1]) << " x " << fmt(g.spacing[2]) << " mm\n"
    << "orientation   " << orientationCode(g.direction) << " (voxel axes i, j, k point to)\n"
    << "affine from   " << affineSourceName(info.affineSource) << "  (sform_code " << info.sformCode
    << ", qform_code " << info.qformCode << ")\n"
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
  std::cout << o.str();
  return 0;
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
    for (const auto& kv : m.pointData) arrays.push(kv.first);
    j["point_arrays"] = arrays;
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::cout << "file          " << path << "\n"
            << "space in file " << meshSpaceName(space) << "\n"
            << "vertices      " << m.vertexCount() << "\nfaces         " << m.faceCount() << "\n"
            << "volume        " << fmt(enclosedVolume(m) / 1000.0, 3) << " mL\n"
            << "area          " << fmt(surfaceArea(m), 1) << " mm^2\n"
            << "bounds (RAS)  (" << fmt(lo[0], 2) << ", " << fmt(lo[1], 2) << ", " << fmt(lo[2], 2) << ") .. ("
            << fmt(hi[0], 2) << ", " << fmt(hi[1], 2) << ", " << fmt(hi[2], 2) << ") mm\n";
  if (!m.pointData.empty()) {
    std::cout << "point arrays ";
    for (const auto& kv : m.pointData) std::cout << " " << kv.first;
    std::cout << "\n";
  }
  return 0;
}

}  // namespace

int cmdInfo(const std::vector<std::string>& argv) {
  Args args(argv, {}, {"help", "json"});
  if (args.has("help")) {
    std::cout << "usage: mskseg info FILE [--json]\n\n"
                 "FILE is a NIfTI volume (.nii, .nii.gz): prints dims, spacing, the voxel->RAS affine and which header\n"
                 "form it came from (sform, qform or pixdim), datatype and scaling, value range and NaN/Inf count;\n"
                 "or a mesh (.vtk .vtp .stl .obj .ply): vertices, faces, volume, area, bounds and the file's space.\n";
    return 0;
  }
  if (args.positional().size() != 1) throw UsageError("expected exactly one FILE");
  const std::string& path = args.positional()[0];
  return isMeshFile(path) ? infoMesh(path, args.has("json")) : infoVolume(path, args.has("json"));
}

}  // namespace msk::cli
