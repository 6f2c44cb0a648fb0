#pragma once
/// VTK adapter (private to msk_imaging): our triangle meshes as vtkPolyData and back, VTK's error printing
/// switched off around a read or write, and the SPACE tag kept as field data.
#include <vtkAlgorithm.h>
#include <vtkFieldData.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <string>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/mesh_io.h"

namespace msk::detail {

/// Switches VTK's global error/warning printing off for one read or write (libraries never print);
/// failures are detected from the output instead. Not safe against concurrent VTK use on other threads.
class VtkQuiet {
 public:
  /// Saves the global display flag and switches printing off.
  VtkQuiet() : was_(vtkObject::GetGlobalWarningDisplay()) { vtkObject::GlobalWarningDisplayOff(); }
  /// Restores the saved flag.
  ~VtkQuiet() { vtkObject::SetGlobalWarningDisplay(was_); }
  VtkQuiet(const VtkQuiet&) = delete;
  VtkQuiet& operator=(const VtkQuiet&) = delete;

 private:
  int was_;
};

/// Runs a reader and returns (a shallow copy of) its polydata output; IoError naming `path` and the format `what`
/// if it failed or is empty.
vtkSmartPointer<vtkPolyData> runReader(vtkAlgorithm* reader, const std::string& path, const std::string& what);

/// Triangle filter (polygons and strips → triangles; vertices and lines dropped), optionally merging
/// coincident points first (tolerance 0: exact duplicates only).
vtkSmartPointer<vtkPolyData> triangulate(vtkPolyData* in, bool mergePoints);

/// Copies triangles, points and named 1-component numeric point arrays; IoError naming `path` if there are no
/// triangles, a cell is not a triangle, an index is out of range or an array has the wrong length.
TriangleMesh toMesh(vtkPolyData* pd, const std::string& path);

/// A vtkPolyData with the mesh's points (double) and triangles, in the mesh's order; no point arrays.
vtkSmartPointer<vtkPolyData> toPolyData(const TriangleMesh& m);

/// Adds every point array of `m` to `pd` as a named 1-component double array; IoError naming `path` for an
/// array with an empty name.
void addPointArrays(vtkPolyData* pd, const TriangleMesh& m, const std::string& path);

/// Adds the string array "SPACE" = "LPS" or "RAS" to `fd`.
void addSpaceField(vtkFieldData* fd, MeshSpace space);

/// Reads the string array "SPACE" of `fd` (may be null): true and `out` set if present; IoError naming `path` if
/// its value is neither LPS nor RAS.
bool fieldDataSpace(vtkFieldData* fd, const std::string& path, MeshSpace& out);

}  // namespace msk::detail
