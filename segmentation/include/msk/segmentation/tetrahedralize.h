#pragma once
/// Tetrahedralisation of a closed surface (CGAL Mesh_3 adapter): the tet mesh a 3-simplex volume model is built on
/// (msk/core/volume_simplex.h).
#include "msk/core/tet_split.h"
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
  /// Sliver exudation (CGAL's exuder, after the optional optimisers below): far fewer flat tets. It may break ties by
  /// memory address, so the connectivity can differ between runs in one process. Off by default.
  bool exude = false;
  /// Sliver perturbation (CGAL's perturber: moves the nodes of the flattest tets, deterministic generator). Off by
  /// default.
  bool perturb = false;
  /// ODT smoothing of the interior nodes (CGAL's odt_optimize_mesh_3, at most `optimiseIterations` passes).
  bool odt = false;
  /// Lloyd smoothing of the interior nodes (CGAL's lloyd_optimize_mesh_3, at most `optimiseIterations` passes).
  bool lloyd = false;
  int optimiseIterations = 20;  ///< passes of ODT or Lloyd smoothing (no time limit, so runs are repeatable)
  /// Dihedral angle (degrees) the perturber and the exuder aim at; 0 = as high as they can get.
  double sliverBoundDeg = 0;
  unsigned seed = 0;  ///< seed of CGAL's random generator for the domain's initial points
  /// Split what the surface alone would shape (splitBoundaryTets(), msk/core/tet_split.h, by `interiorSplit`), then
  /// place the new Steiner nodes away from small and badly shaped tets (untangleTets(), improveTetShapes(),
  /// msk/core/tet_untangle.h). A tet with all four nodes on the
  /// surface, or an interior edge or face between surface nodes, is carried by the surface and inverts where a deformed
  /// surface flattens a ridge or folds; with interior nodes the tets can be untangled. Off by default.
  bool interiorNodes = false;
  BoundarySplit interiorSplit = BoundarySplit::Bridges;  ///< what interiorNodes splits
};

/// Tetrahedralises the inside of a closed, outward-oriented triangle surface (world mm) with CGAL Mesh_3
/// (polyhedral domain, Exact_predicates_inexact_constructions_kernel, sequential; optimisers as `options` say; no
/// sharp-feature protection, so creases are rounded at the facet distance). Every tet is positively oriented; nodes not
/// used by a tet are dropped. Nodes and tets come in a canonical order (nodes by coordinates), so the result depends
/// only on the input and the options (fixed seed; exudation aside, see TetOptions::exude); Steiner nodes of
/// TetOptions::interiorNodes come after the mesher's nodes. Throws Error if the surface is not closed and
/// consistently oriented (closedMeshProblem), encloses no volume, or the mesher yields no tet, and ParameterError on a
/// negative size or an out-of-range angle or ratio.
TetMesh tetrahedralize(const TriangleMesh& closedSurface, const TetOptions& options = {});

/// The options the segmenter tetrahedralises a volume model's template with: tets about as large as the template's
/// triangles (facet size its mean edge length, cell size 1.5 times that, facet distance a tenth of it), ODT smoothing,
/// sliver perturbation and exudation (fewer badly shaped tets to fold at the surface), and interior nodes (every tet
/// has a node off the surface, so a tet the deformed surface folds can be untangled).
TetOptions volumeModelTetOptions(const TriangleMesh& templ);

}  // namespace msk
