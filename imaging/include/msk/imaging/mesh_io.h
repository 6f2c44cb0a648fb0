#pragma once
/// Mesh files: VTK legacy (.vtk, written as version 4.2), VTK XML (.vtp), STL, OBJ, PLY.
#include <string>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Coordinate convention of a mesh file.
enum class MeshSpace { LPS, RAS };

/// "LPS" or "RAS".
const char* meshSpaceName(MeshSpace s);
/// Parses "lps"/"ras" (any case); throws ParameterError otherwise.
MeshSpace parseMeshSpace(const std::string& text);

/// Reads a closed triangle mesh and returns it in RAS mm (internal convention).
/// The file's SPACE tag is honoured (legacy header line, VTP field data "SPACE", comment in STL/OBJ/PLY);
/// untagged files are LPS. Polygons are triangulated; per-vertex scalar arrays are kept (VTK/VTP/PLY).
/// Throws IoError (missing, unreadable, empty, not closed) naming the file. `fileSpace` receives the space found.
TriangleMesh readMesh(const std::string& path, MeshSpace* fileSpace = nullptr);

/// Writes a RAS mesh converted to `space`, tagged, format by extension, atomically. Faces are reordered
/// where the conversion has negative determinant (it has not for RAS↔LPS). Throws IoError.
/// Point arrays are stored as doubles in .vtk (legacy 4.2, binary), .vtp and .ply (binary, whitespace in names
/// becomes '_'); STL and OBJ carry geometry only. STL stores float32 coordinates, the others full doubles.
void writeMesh(const std::string& path, const TriangleMesh& rasMesh, MeshSpace space = MeshSpace::LPS);

/// True if the extension is one writeMesh/readMesh handle.
bool isMeshFile(const std::string& path);

}  // namespace msk
