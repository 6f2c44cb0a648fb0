// The step loop of one pass, and what a pass hands back to each object.
#include <algorithm>
#include <string>

#include "msk/core/error.h"
#include "parallel_each.h"
#include "segment_stages.h"

namespace msk::detail {

namespace {
/// Steps over which an object's drift at the end of a pass is measured.
constexpr int kSettleWindow = 10;
}  // namespace

LevelReport runSteps(std::vector<ObjectState>& objs, const std::vector<char>& fixed, LevelSystem& system,
                     Solver& solver, const SegmentOptions& opts, const ResolvedSettings& rs, const ImageFeatures& feat,
                     const ImageFeatures* focus, const Grid& grid, int& stepsDone, int rampSteps, int totalSteps,
                     const std::string& stage, const ProgressFn& progress, double& detectSeconds) {
  LevelReport rep;
  rep.settleToleranceMm = rs.toleranceMm;
  const ShapeOptions& shape = opts.shape;
  const int sideTestEvery = opts.collision.sideTestEvery;
  // Positions at the start of the last two windows of kSettleWindow steps, for each object's drift at the end.
  Points windowStart, lastWindowStart;
  int windowStep = -1, lastWindowStep = -1;
  const int threads = threadCount(opts.evolution.threads);
  const int moving = static_cast<int>(std::count(fixed.begin(), fixed.end(), 0));
  const int threadsPerObject = std::max(1, threads / std::max(1, moving));
  const double reuseMoveMm = rs.reuseTargetVoxels * grid.spacing.minCoeff();
  for (int s = 0; s < rs.maxStepsPerLevel; ++s) {
    if (s % kSettleWindow == 0) {
      lastWindowStart.swap(windowStart);
      lastWindowStep = windowStep;
      windowStart = solver.positions();
      windowStep = s;
    }
    const double runFraction = std::min(1.0, static_cast<double>(stepsDone) / std::max(1, rampSteps - 1));
    // Each object's image search reads the shared image features and writes only its own targets: on the run's
    // threads, the same for any number of them; threads that objects leave free search the vertices of an object.
    parallelEach(objs.size(), threads, [&](size_t i) {
      if (fixed[i]) return;
      ObjectState& st = objs[i];
      st.search.threads = threadsPerObject;
      if (st.prior) st.prior->setLambda(shape.priorStart + (shape.priorEnd - shape.priorStart) * runFraction);
      st.current.positions = solver.positions().middleRows(st.first, st.current.vertexCount());
      const ImageTargets found = imageTargets(st, st.current, opts, feat, grid, focus, reuseMoveMm);
      st.targets->setTargets(found.targets, found.weights);
      st.residual = found.residual;
    });
    // The side test (winding number) on the first step of a level and every few steps after it, so that a vertex
    // that got through a partner is found and pushed back out the right way.
    const auto tc = Clock::now();
    const bool sideTest = s == 0 || (sideTestEvery > 0 && s % sideTestEvery == 0);
    system.detectContacts(solver.positions(), sideTest, opts.evolution.threads);
    detectSeconds += since(tc);
    rep.lastMaxMoveMm = solver.step(system.sets());
    ++rep.steps;
    ++stepsDone;
    if (progress) progress(std::min(1.0, static_cast<double>(stepsDone) / totalSteps), stage);
    if (rep.lastMaxMoveMm < rs.toleranceMm) {
      rep.stoppedOnTolerance = true;
      break;
    }
  }
  // Each object's drift: the mean net displacement of its surface vertices per step over the last window (at least
  // half a window long), in which the steps' back-and-forth between neighbouring image targets cancels.
  const bool shortWindow = rep.steps - windowStep < kSettleWindow / 2 && lastWindowStep >= 0;
  const Points& from = shortWindow ? lastWindowStart : windowStart;
  const int span = rep.steps - (shortWindow ? lastWindowStep : windowStep);
  for (size_t i = 0; i < objs.size(); ++i) {
    if (fixed[i]) continue;
    ObjectState& st = objs[i];
    const int n = st.current.vertexCount();
    const Points moved = solver.positions().middleRows(st.first, n) - from.middleRows(st.first, n);
    st.driftMmPerStep = span > 0 && n > 0 ? moved.rowwise().norm().mean() / span : 0.0;
  }
  return rep;
}

void collectPass(std::vector<ObjectState>& objs, const std::vector<char>& fixed, const Solver& solver, int l, int order,
                 const LevelReport& report) {
  for (size_t i = 0; i < objs.size(); ++i) {
    if (fixed[i]) continue;
    ObjectState& st = objs[i];
    const Points& x = solver.positions();
    st.current.positions = x.middleRows(st.first, st.current.vertexCount());
    if (st.hasAxis()) st.axisEnd = x.middleRows(st.axisFirst, st.axisCount());
    if (st.volumeSet) st.volFinal = x.middleRows(st.volFirst, st.tetCount(l));
    // A run that has blown up (size changed by more than ×5) stops with a clear message instead of writing it out.
    const Points& refP = st.lv[static_cast<size_t>(l)].simplex.positions;
    const double refDiag = (refP.colwise().maxCoeff() - refP.colwise().minCoeff()).norm();
    const Points& cur = st.current.positions;
    const double curDiag = (cur.colwise().maxCoeff() - cur.colwise().minCoeff()).norm();
    if (!(curDiag < 5.0 * refDiag && curDiag > 0.2 * refDiag))
      throw Error(st.obj->name + ": evolution diverged at level " + std::to_string(order + 1) + " (size ×" +
                  std::to_string(curDiag / refDiag) + " of the template); lower the stiffness or check the image");
    LevelReport r = report;
    r.vertices = st.current.vertexCount();
    r.driftMmPerStep = st.driftMmPerStep;
    r.converged = report.stoppedOnTolerance || st.driftMmPerStep < report.settleToleranceMm;
    st.out.levels.push_back(r);
  }
}

}  // namespace msk::detail
