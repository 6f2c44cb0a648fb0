// The axis-first coarse stage: an object with a medial axis moves as a generalised cylinder of its axis, driven by the
// attachment-weighted mean of its surface vertices' image-target displacements (searched, score-weighted and
// step-limited as in the full evolution), before its full-surface evolution.
#include "segment_stages.h"

namespace msk::detail {

AxisFirstReport runAxisFirst(ObjectState& st, int l, const SegmentOptions& opts, const ResolvedSettings& rs,
                             const ImageFeatures& feat, const Grid& grid) {
  AxisFirstReport rep;
  rep.object = st.obj->name;
  const GeneralisedCylinder cylinder(st.lv[static_cast<size_t>(l)].simplex.positions, st.axis.curve.positions,
                                     st.attachment);
  Points axis = st.axisStart;
  SimplexMesh mesh = st.current;
  for (int s = 0; s < opts.axis.firstSteps; ++s) {
    mesh.positions = cylinder.surface(axis);
    const ImageTargets found = imageTargets(st, mesh, opts, feat, grid, nullptr);
    const Points displacement =
        found.weights.cwiseMin(1.0).cwiseMax(0.0).asDiagonal() * (found.targets - mesh.positions);
    rep.lastMaxMoveMm = cylinder.step(axis, displacement, opts.axis.firstStage);
    ++rep.steps;
    if (rep.lastMaxMoveMm < rs.toleranceMm) {
      rep.converged = true;
      break;
    }
  }
  st.current.positions = cylinder.surface(axis);
  rep.meanAxisMoveMm = (axis - st.axisStart).rowwise().norm().mean();
  st.axisStart = axis;
  st.stageAxisRef = st.axis.curve.positions;
  st.stageAxis = axis;
  return rep;
}

}  // namespace msk::detail
