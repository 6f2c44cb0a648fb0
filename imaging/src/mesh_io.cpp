// Mesh files: the public entry points. Dispatch by extension to one adapter per format (mesh_io_<format>.cpp),
// the SPACE tag and the LPS/RAS conversion, and the checks every mesh read or written passes.
#include "msk/imaging/mesh_io.h"

#include <exception>
#include <vector>

#include "mesh_io_detail.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/mesh_repair.h"

namespace msk {

namespace {

/// One mesh file format: its extension (lower case, with the dot) and its adapter.
struct Format {
  const char* extension;
  TriangleMesh (*read)(const std::string& path, MeshSpace& space);
  void (*write)(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space);
};

constexpr Format kFormats[] = {{".vtk", detail::readVtkLegacy, detail::writeVtkLegacy},
                               {".vtp", detail::readVtp, detail::writeVtp},
                               {".stl", detail::readStl, detail::writeStl},
                               {".obj", detail::readObj, detail::writeObj},
                               {".ply", detail::readPly, detail::writePly}};

/// The format of `path` by its extension; null if none.
const Format* formatOf(const std::string& path) {
  const std::string ext = fileExtension(path);
  for (const Format& f : kFormats)
    if (ext == f.extension) return &f;
  return nullptr;
}

/// IoError for a path whose extension is not a mesh format.
IoError unsupported(const std::string& path) {
  const std::string ext = fileExtension(path);
  return IoError(path, "unsupported mesh format '" + (ext.empty() ? std::string("(no extension)") : ext) +
                           "' (use .vtk, .vtp, .stl, .obj or .ply)");
}

/// Removes vertices no face uses (free-standing points, line ends), keeping the order of the rest.
/// Leaves the mesh alone if a face index is out of range (closedMeshProblem reports that).
void dropUnusedVertices(TriangleMesh& m) {
  const int nv = m.vertexCount();
  std::vector<int> map(static_cast<size_t>(nv), -1);
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = m.faces(f, k);
      if (v < 0 || v >= nv) return;
      map[static_cast<size_t>(v)] = 1;
    }
  int next = 0;
  for (int& u : map) u = u > 0 ? next++ : -1;
  if (next == nv) return;
  Points kept(next, 3);
  for (int i = 0; i < nv; ++i)
    if (map[static_cast<size_t>(i)] >= 0) kept.row(map[static_cast<size_t>(i)]) = m.vertices.row(i);
  for (auto& [name, values] : m.pointData) {
    if (values.size() != nv) continue;
    Eigen::VectorXd k(next);
    for (int i = 0; i < nv; ++i)
      if (map[static_cast<size_t>(i)] >= 0) k[map[static_cast<size_t>(i)]] = values[i];
    values = k;
  }
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) m.faces(f, k) = map[static_cast<size_t>(m.faces(f, k))];
  m.vertices = kept;
}

}  // namespace

const char* meshSpaceName(MeshSpace s) { return s == MeshSpace::LPS ? "LPS" : "RAS"; }

MeshSpace parseMeshSpace(const std::string& text) {
  const std::string t = detail::lowercase(text);
  if (t == "lps") return MeshSpace::LPS;
  if (t == "ras") return MeshSpace::RAS;
  throw ParameterError("mesh space", text, "expected LPS or RAS");
}

bool isMeshFile(const std::string& path) { return formatOf(path) != nullptr; }

TriangleMesh readMesh(const std::string& path, MeshSpace* fileSpace) {
  const Format* format = formatOf(path);
  if (!format) throw unsupported(path);
  detail::requireRegularFile(path);

  MeshSpace space = MeshSpace::LPS;  // untagged files are LPS
  TriangleMesh mesh;
  try {
    mesh = format->read(path, space);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {  // e.g. std::bad_alloc from a garbage count inside VTK
    throw IoError(path, std::string("cannot read the file: ") + e.what());
  }

  dropUnusedVertices(mesh);
  if (mesh.vertexCount() > 0 && !mesh.vertices.allFinite())
    throw IoError(path, "vertex coordinates are not finite (NaN or infinity)");
  std::string problem = closedMeshProblem(mesh);
  if (!problem.empty()) {
    // Exporters often write a vertex once per face or texture seam, or leave a small hole: mended where sound.
    TriangleMesh mended = mesh;
    const MeshMending done = mendSurface(mended);
    if (!done.summary().empty() && closedMeshProblem(mended).empty()) {
      log::warn(path + ": not a closed surface as written (" + problem + "); " + done.summary() + ", which closes it");
      mesh = std::move(mended);
      problem.clear();
    }
  }
  if (!problem.empty()) throw IoError(path, "not a closed triangle surface: " + problem);
  if (space == MeshSpace::LPS) transformMesh(mesh, rasLpsFlip());
  if (fileSpace) *fileSpace = space;
  return mesh;
}

void writeMesh(const std::string& path, const TriangleMesh& rasMesh, MeshSpace space) {
  const Format* format = formatOf(path);
  if (!format) throw unsupported(path);
  const std::string problem = closedMeshProblem(rasMesh);
  if (!problem.empty()) throw IoError(path, "refusing to write an invalid mesh: " + problem);
  TriangleMesh m = rasMesh;
  if (space == MeshSpace::LPS) transformMesh(m, rasLpsFlip());
  writeAtomically(path, [&](const std::string& tmp) { format->write(tmp, path, m, space); });
}

}  // namespace msk
