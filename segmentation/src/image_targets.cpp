// An object's image targets at its current surface: the search along the normals, score weights, and a muscle's
// per-step limit.
#include <algorithm>
#include <cmath>
#include <vector>

#include "segment_stages.h"

namespace msk::detail {

namespace {

/// Weights in [0, 1] from search scores: strong edges (≥ half the median positive score) get full weight.
Eigen::VectorXd scoreWeights(const Eigen::VectorXd& scores) {
  std::vector<double> pos;
  for (int i = 0; i < scores.size(); ++i)
    if (scores[i] > 0) pos.push_back(scores[i]);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(scores.size());
  if (pos.empty()) return w;
  std::nth_element(pos.begin(), pos.begin() + pos.size() / 2, pos.end());
  const double ref = 0.5 * pos[pos.size() / 2];
  for (int i = 0; i < scores.size(); ++i) w[i] = ref > 0 ? std::min(1.0, scores[i] / ref) : 0.0;
  return w;
}

/// Moves each target toward its vertex until it is at most `edges` local edge lengths (the vertex's mean distance to
/// its three neighbours) away: a limit on the image step, so that no vertex moves more than about γ × `edges` mesh
/// spacings per step. Targets a muscle cannot reach (at a partner, or where a septum is missing) otherwise pull at
/// full length step after step, and the surface buckles between them (docs/method.md, Surface quality). What matters
/// is the absolute step: a limit relative to the neighbours' mean step does not keep the surface from folding.
void limitTargetStep(const SimplexMesh& mesh, double edges, Points& targets) {
  const Points& p = mesh.positions;
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    double edge = 0;
    for (int c = 0; c < 3; ++c) edge += (p.row(mesh.neighbors(v, c)) - p.row(v)).norm();
    const double cap = edges * edge / 3.0;
    const Eigen::RowVector3d d = targets.row(v) - p.row(v);
    const double len = d.norm();
    if (len > cap) targets.row(v) = p.row(v) + (cap / len) * d;
  }
}

}  // namespace

ImageTargets imageTargets(ObjectState& st, const SimplexMesh& mesh, const SegmentOptions& opts,
                          const ImageFeatures& feat, const Grid& grid, const ImageFeatures* focus, double reuseMoveMm) {
  const auto ts = Clock::now();
  st.reuse.moveMm = reuseMoveMm;
  st.reuse.turnDegrees = kReuseTurnDegrees;
  const TargetSearchResult found =
      searchTargets(feat, mesh.positions, validSimplexVertexNormals(mesh), mesh.neighbors, st.search, st.polarity, grid,
                    st.search.mode == TargetMode::Profile ? &st.profiles : nullptr, focus, &st.reuse);
  st.searchSeconds += since(ts);
  ImageTargets out{found.targets, scoreWeights(found.scores), found.residual};
  if (opts.image.farTargetScaleMm > 0)  // robust (Cauchy) down-weighting of far targets: outliers pull less
    for (int i = 0; i < out.weights.size(); ++i)
      out.weights[i] /= 1.0 + std::pow(found.offsets[i] / opts.image.farTargetScaleMm, 2);
  if (opts.image.muscleTargetStepEdges > 0 && st.obj->kind == ObjectKind::Muscle)
    limitTargetStep(mesh, opts.image.muscleTargetStepEdges, out.targets);
  return out;
}

}  // namespace msk::detail
