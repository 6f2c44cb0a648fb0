#pragma once
/// Tetrahedral mesh files: VTK XML unstructured grids (.vtu) tagged with their coordinate space.
#include <string>

#include "msk/core/volume_simplex.h"
#include "msk/imaging/mesh_io.h"

namespace msk {

/// Writes a RAS tet mesh (world mm) converted to `space` as a VTK XML unstructured grid (.vtu; nodes as doubles,
/// every cell a VTK_TETRA with the mesh's node order), tagged with the field data string array "SPACE" = "LPS" or
/// "RAS", atomically (on failure nothing is left at `path`). RAS↔LPS has determinant +1, so orientation is kept.
/// Throws IoError naming the file: wrong extension, invalid mesh (tetMeshProblem), or the write fails.
void writeTetMesh(const std::string& path, const TetMesh& rasMesh, MeshSpace space = MeshSpace::LPS);

/// Reads a .vtu tet mesh into RAS mm. The field data "SPACE" is honoured (untagged files are LPS); `fileSpace`
/// receives the space found. Throws IoError naming the file if it is missing, unreadable or corrupt, has a cell that
/// is not a tetrahedron, non-finite nodes, or is not a valid tet mesh (tetMeshProblem).
TetMesh readTetMesh(const std::string& path, MeshSpace* fileSpace = nullptr);

}  // namespace msk
