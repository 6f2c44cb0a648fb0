// One object's result: its output surface (unfolded where it folded), the displacement and residual on it, and its
// volume model's tet mesh settled on it.
#include <cmath>

#include "msk/core/error.h"
#include "msk/core/tet_untangle.h"
#include "msk/segmentation/surface_quality.h"
#include "msk/segmentation/tetrahedralize.h"
#include "segment_stages.h"

namespace msk::detail {

void settleVolumeMesh(ObjectResult& out, const Eigen::VectorXd& restVolumes, const Eigen::VectorXi& surfaceNode) {
  MSK_ASSERT(surfaceNode.size() == out.mesh.vertexCount(), "volume model: tet boundary does not match the surface");
  for (Eigen::Index v = 0; v < surfaceNode.size(); ++v)
    out.volumeMesh.nodes.row(surfaceNode[v]) = out.mesh.vertices.row(v);
  untangleTetMesh(out.volumeMesh, restVolumes.cwiseMax(1e-3 * std::fabs(restVolumes.mean())),
                  0.1 * meanEdgeLength(out.mesh));
  improveWorstTetShapes(out.volumeMesh, 0.3);
  out.volumeModelMm3 = totalVolume(out.volumeMesh);
  out.invertedTets = static_cast<int>((tetVolumes(out.volumeMesh).array() <= 0).count());
  out.volumeModelTemplateMm3 = restVolumes.sum();
}

void finishObject(ObjectState& st, bool unfold) {
  st.current.pointData.clear();
  st.current.pointData["image_residual_mm"] =
      st.residual.size() == st.current.vertexCount() ? st.residual : Eigen::VectorXd::Zero(st.current.vertexCount());
  ObjectResult& out = st.out;
  out.mesh = trianglesFromSimplex(st.current);
  if (unfold) {
    const UnfoldReport u = unfoldSurface(out.mesh);
    out.foldsFound = u.before;
    out.unfoldedVertices = u.verticesMoved;
    out.selfIntersections = u.after;
  }
  out.mesh.pointData["displacement_mm"] = (out.mesh.vertices - st.lv[0].triangles.vertices).rowwise().norm();
  if (st.volume) {
    Points all(st.volume->vertexCount(), 3);
    all.topRows(st.volume->tetCount()) = st.volFinal;
    all.bottomRows(st.volume->ghostCount()) = st.current.positions;
    all = relaxVolumeSimplexTets(*st.volume, all);  // the tets' equilibrium with the final surface (no lag)
    // Boundary nodes on the evolved surface's vertices (the tet boundary is the surface's triangulation,
    // prepareObject), interior nodes by least squares from the simplex vertices.
    const TetMesh rest = tetsFromVolumeSimplex(*st.volume, st.volume->simplex.positions);
    tetBoundary(rest, &st.volSurfaceNode);
    st.volRestVolumes = tetVolumes(rest);
    MSK_ASSERT(st.volSurfaceNode.size() == out.mesh.vertexCount(),
               "volume model: tet boundary does not match the surface");
    out.volumeMesh = tetsFromVolumeSimplex(*st.volume, all, st.volSurfaceNode, out.mesh.vertices);
    settleVolumeMesh(out, st.volRestVolumes, st.volSurfaceNode);
    if (st.volumeHold)
      out.volumeDecision = st.volumeHold->decision() == VolumeDecision::Holding     ? "holding"
                           : st.volumeHold->decision() == VolumeDecision::Following ? "following"
                                                                                    : "observing";
  }
  out.meanImageResidualMm = out.mesh.pointData["image_residual_mm"].mean();
  out.volumeMm3 = enclosedVolume(out.mesh);
  out.imageSearchSeconds = st.searchSeconds;
  const long searches = st.reuse.searched + st.reuse.reused;
  out.imageSearchReusedShare =
      searches > 0 ? static_cast<double>(st.reuse.reused) / static_cast<double>(searches) : 0.0;
  const std::string problem = closedMeshProblem(out.mesh);
  if (!problem.empty()) throw Error(st.obj->name + ": the evolved surface is invalid: " + problem);
}

}  // namespace msk::detail
