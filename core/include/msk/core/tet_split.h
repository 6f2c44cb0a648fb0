#pragma once
/// Interior nodes for every tetrahedron. A tet whose four nodes all lie on the boundary surface has its shape fixed by
/// the surface alone: where a deformed surface flattens a convex ridge or folds, such a tet goes flat or inverts and no
/// interior node can restore it. splitBoundaryTets() removes these tets by bisecting one of their interior edges (or,
/// if a tet has none, splitting an interior face) at an interior Steiner node, so every tet of the result has at least
/// one node that is free of the surface (tet_untangle.h moves those).
#include <vector>

#include "msk/core/volume_simplex.h"

namespace msk {

/// 1 for every node on a boundary face of `mesh` (tetBoundaryFaces), else 0; #N entries.
std::vector<char> boundaryNodeMask(const TetMesh& mesh);

/// Number of tets whose four nodes all lie on the boundary.
int boundaryOnlyTetCount(const TetMesh& mesh);

/// What splitBoundaryTets() cuts.
enum class BoundarySplit {
  Tets,    ///< only the tets whose four nodes all lie on the boundary (one interior edge or face of each)
  Bridges  ///< every interior edge and interior face whose nodes all lie on the boundary ("bridges" across the volume,
           ///< which a folding surface carries outside it); no tet keeps four boundary nodes either
};

/// `mesh` with every tet whose four nodes lie on the boundary split, as in the file comment: for each such tet, its
/// longest edge that is not a boundary edge is bisected at its midpoint (every tet around that edge is cut in two), or,
/// if all its edges are boundary edges, its largest face that is not a boundary face gets a node at its centroid (both
/// tets on that face are cut in three). The boundary faces and all existing nodes are kept (new nodes are appended,
/// rows [mesh.nodeCount(), result.nodeCount())); every new tet is positively oriented. Deterministic. `added`
/// (optional) receives the number of Steiner nodes. Throws Error if the mesh is invalid (tetMeshProblem) or a tet has
/// four boundary faces (a mesh of one tet). With BoundarySplit::Bridges, every interior edge between two boundary nodes
/// is bisected first (in order of its node indices), then every interior face of three boundary nodes gets a node at
/// its centroid.
TetMesh splitBoundaryTets(const TetMesh& mesh, int* added = nullptr, BoundarySplit rule = BoundarySplit::Tets);

}  // namespace msk
