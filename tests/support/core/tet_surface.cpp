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

}  // namespace msk::test
