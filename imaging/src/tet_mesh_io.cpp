// Tet mesh files through VTK's XML unstructured-grid reader and writer (VTK confined to this file and vtk_mesh.h).
#include "msk/imaging/tet_mesh_io.h"

#include <vtkCallbackCommand.h>
#include <vtkCellArray.h>
#include <vtkCellType.h>
#include <vtkCommand.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <cstdint>
#include <string>

#include "isolated_reader.h"
#include "mesh_io_detail.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "vtk_mesh.h"

namespace msk {

namespace {

/// For one VTK read or write: global error printing off (libraries never print) and the first error or warning
/// that `algorithm` reports kept, so a failure is detected even when VTK returns an empty output.
class VtkErrorTrap {
 public:
  explicit VtkErrorTrap(vtkAlgorithm* algorithm) : algorithm_(algorithm) {
    callback_->SetClientData(this);
    callback_->SetCallback(&VtkErrorTrap::record);
    errorTag_ = algorithm_->AddObserver(vtkCommand::ErrorEvent, callback_);
  }
  ~VtkErrorTrap() { algorithm_->RemoveObserver(errorTag_); }
  VtkErrorTrap(const VtkErrorTrap&) = delete;
  VtkErrorTrap& operator=(const VtkErrorTrap&) = delete;
  /// True if an error was reported.
  bool failed() const { return failed_; }
  /// The first error message (first line only), possibly empty.
  const std::string& message() const { return message_; }

 private:
  static void record(vtkObject*, unsigned long, void* self, void* text) {
    auto* trap = static_cast<VtkErrorTrap*>(self);
    if (trap->failed_) return;
    trap->failed_ = true;
    if (text) {
      trap->message_ = static_cast<const char*>(text);
      trap->message_ = trap->message_.substr(0, trap->message_.find('\n'));
    }
  }
  detail::VtkQuiet quiet_;  // first member: printing is off before the observer is added and on after it is removed
  vtkAlgorithm* algorithm_;
  vtkNew<vtkCallbackCommand> callback_;
  unsigned long errorTag_ = 0;
  bool failed_ = false;
  std::string message_;
};

void checkExtension(const std::string& path) {
  if (fileExtension(path) != ".vtu")
    throw IoError(path, "unsupported tetrahedral mesh format '" + fileExtension(path) + "' (use .vtu)");
}

/// RAS ↔ LPS: x and y change sign (the map is its own inverse).
Points flipped(const Points& p) {
  Points q = p;
  q.col(0) = -q.col(0);
  q.col(1) = -q.col(1);
  return q;
}

}  // namespace

void writeTetMesh(const std::string& path, const TetMesh& rasMesh, MeshSpace space) {
  checkExtension(path);
  const std::string problem = tetMeshProblem(rasMesh);
  if (!problem.empty()) throw IoError(path, "refusing to write an invalid tetrahedral mesh: " + problem);
  const Points nodes = space == MeshSpace::LPS ? flipped(rasMesh.nodes) : rasMesh.nodes;

  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(nodes.rows());
  for (Eigen::Index i = 0; i < nodes.rows(); ++i) points->SetPoint(i, nodes(i, 0), nodes(i, 1), nodes(i, 2));
  vtkNew<vtkCellArray> cells;
  cells->AllocateExact(rasMesh.tetCount(), 4 * static_cast<vtkIdType>(rasMesh.tetCount()));
  for (int t = 0; t < rasMesh.tetCount(); ++t) {
    const vtkIdType ids[4] = {rasMesh.tets(t, 0), rasMesh.tets(t, 1), rasMesh.tets(t, 2), rasMesh.tets(t, 3)};
    cells->InsertNextCell(4, ids);
  }
  vtkNew<vtkUnstructuredGrid> grid;
  grid->SetPoints(points);
  grid->SetCells(VTK_TETRA, cells);
  detail::addSpaceField(grid->GetFieldData(), space);

  writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkXMLUnstructuredGridWriter> w;
    VtkErrorTrap trap(w);
    w->SetInputData(grid);
    w->SetFileName(tmp.c_str());
    w->SetDataModeToAppended();
    w->EncodeAppendedDataOff();  // raw binary
    const int ok = w->Write();
    if (!ok || w->GetErrorCode() != 0 || trap.failed())
      throw IoError(path, "VTK could not write the file" + (trap.message().empty() ? "" : ": " + trap.message()));
  });
}

namespace {

/// VTK's XML unstructured-grid reader in this process: nodes as stored in the file (not yet in RAS) and tets.
TetMesh readVtuHere(const std::string& path, MeshSpace& space) {
  TetMesh mesh;
  vtkNew<vtkXMLUnstructuredGridReader> r;
  VtkErrorTrap trap(r);
  r->SetFileName(path.c_str());
  r->Update();
  vtkUnstructuredGrid* grid = r->GetOutput();
  if (trap.failed() || r->GetErrorCode() != 0 || !grid || grid->GetNumberOfPoints() == 0 ||
      grid->GetNumberOfCells() == 0)
    throw IoError(path, "cannot read the file as a VTK XML unstructured grid (unreadable, corrupt or empty)" +
                            (trap.message().empty() ? "" : std::string(": ") + trap.message()));

  detail::fieldDataSpace(grid->GetFieldData(), path, space);

  const vtkIdType n = grid->GetNumberOfPoints(), cellCount = grid->GetNumberOfCells();
  if (n > INT32_MAX || cellCount > INT32_MAX) throw IoError(path, "more nodes or cells than this program handles");
  mesh.nodes.resize(n, 3);
  for (vtkIdType i = 0; i < n; ++i) {
    double p[3];
    grid->GetPoint(i, p);
    mesh.nodes.row(i) << p[0], p[1], p[2];
  }
  mesh.tets.resize(cellCount, 4);
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < cellCount; ++c) {
    if (grid->GetCellType(c) != VTK_TETRA)
      throw IoError(path, "cell " + std::to_string(c) + " is not a tetrahedron (VTK cell type " +
                              std::to_string(grid->GetCellType(c)) + ")");
    grid->GetCellPoints(c, ids);
    if (ids->GetNumberOfIds() != 4) throw IoError(path, "cell " + std::to_string(c) + " has no 4 points");
    for (int k = 0; k < 4; ++k) {
      const vtkIdType id = ids->GetId(k);
      if (id < 0 || id >= n) throw IoError(path, "cell " + std::to_string(c) + " names a point that does not exist");
      mesh.tets(c, k) = static_cast<int>(id);
    }
  }
  return mesh;
}

std::string encode(const TetMesh& m, MeshSpace space) {
  detail::ByteWriter out;
  out.value<int32_t>(space == MeshSpace::LPS ? 0 : 1);
  out.value<int64_t>(m.nodeCount());
  out.value<int64_t>(m.tetCount());
  for (int i = 0; i < m.nodeCount(); ++i)
    for (int c = 0; c < 3; ++c) out.value<double>(m.nodes(i, c));
  for (int t = 0; t < m.tetCount(); ++t)
    for (int k = 0; k < 4; ++k) out.value<int32_t>(m.tets(t, k));
  return std::move(out.bytes());
}

TetMesh decode(const std::string& bytes, const std::string& path, MeshSpace& space) {
  detail::ByteReader in(bytes, path);
  space = in.value<int32_t>() == 0 ? MeshSpace::LPS : MeshSpace::RAS;
  const int64_t n = in.value<int64_t>(), t = in.value<int64_t>();
  if (n < 0 || t < 0 || static_cast<uint64_t>(n) > in.left() / 24 || static_cast<uint64_t>(t) > in.left() / 16)
    in.malformed();
  TetMesh m;
  m.nodes.resize(n, 3);
  m.tets.resize(t, 4);
  for (int64_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) m.nodes(i, c) = in.value<double>();
  for (int64_t j = 0; j < t; ++j)
    for (int k = 0; k < 4; ++k) m.tets(j, k) = in.value<int32_t>();
  return m;
}

}  // namespace

// VTK's XML reader crashes and exhausts memory or time on malformed files (see mesh_io_vtp.cpp): it runs in a child
// process, where a crash is one error naming the file.
TetMesh readTetMesh(const std::string& path, MeshSpace* fileSpace) {
  checkExtension(path);
  detail::requireRegularFile(path);

  MeshSpace space = MeshSpace::LPS;  // untagged files are LPS
  const std::string bytes = detail::runInChildProcess(path, "VTK XML", [&] {
    MeshSpace found = MeshSpace::LPS;
    const TetMesh m = readVtuHere(path, found);
    return encode(m, found);
  });
  TetMesh mesh = decode(bytes, path, space);

  if (!mesh.nodes.allFinite()) throw IoError(path, "node coordinates are not finite (NaN or infinity)");
  if (space == MeshSpace::LPS) mesh.nodes = flipped(mesh.nodes);
  const std::string problem = tetMeshProblem(mesh);
  if (!problem.empty()) throw IoError(path, "not a valid tetrahedral mesh: " + problem);
  if (fileSpace) *fileSpace = space;
  return mesh;
}

}  // namespace msk
