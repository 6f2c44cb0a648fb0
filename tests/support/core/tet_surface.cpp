#include "msk/test/tet_surface.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace msk::test {

TetSurfaceOffsets tetSurfaceOffsets(const TetMesh& tets, const TriangleMesh& surface) {
  const TriangleMesh boundary = tetBoundary(tets);
  TetSurfaceOffsets o;
  o.boundaryNodes = boundary.vertexCount();
  o.surfaceVertices = surface.vertexCount();
  o.meanEdgeMm = meanEdgeLength(surface);
  for (int v = 0; v < surface.vertexCount(); ++v) {
    double best = std::numeric_limits<double>::infinity();
    for (int b = 0; b < boundary.vertexCount(); ++b)
      best = std::min(best, (boundary.vertices.row(b) - surface.vertices.row(v)).squaredNorm());
    o.largestMm = std::max(o.largestMm, std::sqrt(best));
    o.offSurface += std::sqrt(best) > 1e-3;
  }
  return o;
}

Points volumeResiduals(const VolumeSimplexMesh& model, const Points& positions) {
  VolumeSimplexConstraints rows(model, 1.0, VolumeBoundary::Constrained);
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(positions.rows());
  Points r = Points::Zero(positions.rows(), 3);
  ConstraintRow row;
  for (int k = 0; k < rows.rowCount(); ++k)
    if (rows.row(k, positions, w, row)) r.row(row.index[0]) = row.c.transpose();
  return r;
}

}  // namespace msk::test
