#pragma once
/// Tetrahedralisation of a closed surface (CGAL Mesh_3 adapter): the tet mesh a 3-simplex volume model is built on
/// (msk/core/volume_simplex.h).
#include "msk/core/triangle_mesh.h"
#include "msk/core/volume_simplex.h"

namespace msk {

/// Mesh_3 criteria. Sizes of 0 are derived from the surface's bounding-box diagonal, so defaults hold at any scale.
struct TetOptions {
  double cellSizeMm = 0;           ///< largest tet circumradius (mm); 0 = bounding-box diagonal / 15
  double facetSizeMm = 0;          ///< largest boundary-facet surface-ball radius (mm); 0 = the cell size
  double facetDistanceMm = 0;      ///< largest facet-to-surface distance (mm); 0 = the cell size / 20
  double facetAngleDeg = 25;       ///< smallest boundary-facet angle (degrees, ≤ 30 guarantees termination)
  double cellRadiusEdgeRatio = 3;  ///< largest circumradius / shortest edge of a tet (≥ 2)
  /// Sliver exudation (CGAL's exuder): far fewer flat tets, but it breaks ties by memory address, so the
  /// connectivity can differ between runs in one process. Off by default, which keeps results repeatable.
  bool exude = false;
  unsigned seed = 0;  ///< seed of CGAL's random generator for the domain's initial points
};

/// Tetrahedralises the inside of a closed, outward-oriented triangle surface (world mm) with CGAL Mesh_3
/// (polyhedral domain, Exact_predicates_inexact_constructions_kernel, sequential; no perturbation, Lloyd or ODT; no
/// sharp-feature protection, so creases are rounded at the facet distance). Every tet is positively oriented; nodes not
/// used by a tet are dropped. Nodes and tets come in a canonical order (nodes by coordinates), so without exudation the
/// result depends only on the input and the options (fixed seed). Throws Error if the surface is not closed and
/// consistently oriented (closedMeshProblem), encloses no volume, or the mesher yields no tet, and ParameterError on a
/// negative size or an out-of-range angle or ratio.
TetMesh tetrahedralize(const TriangleMesh& closedSurface, const TetOptions& options = {});

}  // namespace msk
