// One pass's particle system: every object's particles stacked (tets, surface; then the medial axes), masses, sets and
// the collision sets of the scene's pairs.
#include <algorithm>

#include "parallel_each.h"
#include "segment_stages.h"

namespace msk::detail {

namespace {

/// Width of the partners' grid cells in mean triangle edges (at least the contacts' reach): wider cells mean fewer
/// cells per query and per build and more triangles per cell; 2.5 was the fastest of 0.25 to 10 on the bundled thigh
/// (docs/measurements.md, "Wider grid cells").
constexpr double kPartnerCellEdges = 2.5;

/// A clean-up sweep whose corrections move no coordinate by more than this (mm) ends the sweeps.
constexpr double kNegligibleMoveMm = 1e-9;

/// Detects the contacts of every collision set at positions `p` (between side tests the vertices in contact may follow
/// their partner triangles: CollisionConstraints::detect()). The sets only read the positions and their shared partner
/// surfaces (updated before), and each writes its own contacts, so they run on `threads` threads (0 = all cores) with
/// the same result as one.
void detectAll(std::vector<std::unique_ptr<CollisionConstraints>>& sets, const Points& p, bool sideTest, int threads) {
  parallelEach(sets.size(), threads, [&](size_t k) { sets[k]->detect(p, sideTest, 1, true); });
}

}  // namespace

LevelSystem::LevelSystem(std::vector<ObjectState>& objs, int l, int coarsest, bool refine,
                         const std::vector<char>& fixed, const SegmentOptions& opts, const ResolvedSettings& rs,
                         const ImageFeatures& feat, const Grid& grid)
    : objs_(objs), fixed_(fixed), l_(l) {
  const int order = coarsest - l;
  for (size_t i = 0; i < objs.size(); ++i) {
    ObjectState& st = objs[i];
    st.volFirst = n_;  // a volume model's tet particles come right before its surface's
    n_ += st.tetCount(l);
    st.first = n_;
    st.search.rangeMm = rs.rangeMm[static_cast<size_t>(order)];
    if (!fixed[i]) enterLevel(st, l, coarsest, opts, feat, grid, refine);
    n_ += st.current.vertexCount();
  }
  // Medial-axis particles follow all the surfaces.
  for (size_t i = 0; i < objs.size(); ++i)
    if (objs[i].hasAxis()) {
      objs[i].axisFirst = n_;
      n_ += objs[i].axisCount();
      if (!fixed[i]) buildAxisSets(objs[i], opts);
    }
}

int LevelSystem::assemble(const Scene& scene, const std::vector<PairContact>& contacts, const SegmentOptions& opts) {
  x_.resize(n_, 3);
  for (size_t i = 0; i < objs_.size(); ++i) {
    const ObjectState& st = objs_[i];
    x_.middleRows(st.first, st.current.vertexCount()) = st.current.positions;
    if (st.hasAxis()) x_.middleRows(st.axisFirst, st.axisCount()) = fixed_[i] ? st.axisEnd : st.axisStart;
    if (st.volumeSet) x_.middleRows(st.volFirst, st.tetCount(l_)) = fixed_[i] ? st.volFinal : st.volStart;
  }
  for (size_t i = 0; i < objs_.size(); ++i)
    if (!fixed_[i])
      for (ConstraintSet* c : objs_[i].sets()) sets_.push_back(c);
  // Bones are heavier, so a contact moves the muscle more than the bone (masses only matter for shared corrections:
  // image targets and shape memory do not depend on a uniform mass scale). An axis carries the mass of its surface.
  invMass_ = Eigen::VectorXd::Ones(n_);
  for (size_t i = 0; i < objs_.size(); ++i) {
    const ObjectState& st = objs_[i];
    const int nv = st.current.vertexCount(), nt = st.tetCount(l_);
    if (st.obj->kind == ObjectKind::Bone) {
      invMass_.segment(st.first, nv).setConstant(1.0 / opts.collision.boneMassRatio);
      invMass_.segment(st.volFirst, nt).setConstant(1.0 / opts.collision.boneMassRatio);
    }
    if (st.hasAxis())
      invMass_.segment(st.axisFirst, st.axisCount()) =
          axisInverseMass(st.attachment, st.axisCount(), invMass_.segment(st.first, nv));
    if (fixed_[i]) {
      invMass_.segment(st.volFirst, nt).setZero();
      invMass_.segment(st.first, nv).setZero();
      if (st.hasAxis()) invMass_.segment(st.axisFirst, st.axisCount()).setZero();
    }
  }
  if (opts.collision.enabled && !scene.collisions.empty()) {
    // Each direction of a pair is A's vertices against B's surface (fan triangles of B's simplex faces, whose corners
    // are B's particles). Each partner surface is set up once per level and its grid rebuilt once per step, shared by
    // the sets against it; it must reach the largest gap + proximity of the pairs it is a partner in.
    std::map<size_t, double> reach;
    for (size_t k = 0; k < scene.collisions.size(); ++k)
      for (int o : {scene.collisions[k].a, scene.collisions[k].b})
        reach[static_cast<size_t>(o)] =
            std::max(reach[static_cast<size_t>(o)], contacts[k].gapMm + contacts[k].proximityMm);
    auto surfaceOf = [&](size_t i) {
      auto it = surfaces_.find(i);
      if (it == surfaces_.end()) {
        Triangles t = simplexFanTriangles(objs_[i].current);
        t.array() += objs_[i].first;
        it = surfaces_.emplace(i, std::make_shared<CollisionSurface>(t, reach.at(i), kPartnerCellEdges)).first;
      }
      return it->second;
    };
    for (size_t k = 0; k < scene.collisions.size(); ++k) {
      const CollisionPair& pair = scene.collisions[k];
      const PairContact& pc = contacts[k];
      for (auto [u, v] : {std::pair<size_t, size_t>(pair.a, pair.b), std::pair<size_t, size_t>(pair.b, pair.a)}) {
        collide_.push_back(std::make_unique<CollisionConstraints>(objs_[u].first, objs_[u].current.vertexCount(),
                                                                  surfaceOf(v), pc.gapMm, pc.proximityMm, pc.friction,
                                                                  pc.response));
        if (pc.response.resolution == CollisionResolution::Global) {
          // Pairs resolved globally: their sets are solved together, one system per mode (the sets alone do nothing).
          auto& g = global_[pc.response.mode];
          if (!g) g = std::make_unique<GlobalCollisionResolution>(pc.response.mode);
          g->add(collide_.back().get());
        }
      }
    }
  }
  // Contacts are projected last in a step, so they have the last word.
  for (auto& c : collide_)
    if (c->response().resolution == CollisionResolution::Sequential) sets_.push_back(c.get());
  for (auto& kv : global_) sets_.push_back(kv.second.get());
  return static_cast<int>(collide_.size());
}

void LevelSystem::detectContacts(const Points& p, bool sideTest, int threads) {
  std::vector<CollisionSurface*> surfaces;
  for (auto& kv : surfaces_) surfaces.push_back(kv.second.get());
  parallelEach(surfaces.size(), threads, [&](size_t k) { surfaces[k]->update(p); });
  detectAll(collide_, p, sideTest, threads);
}

int LevelSystem::cleanUpContacts(Points& p, const Eigen::VectorXd& w, int sweeps, const Scene& scene, int threads) {
  threads = threadCount(threads);
  Points before;
  int sweep = 0;
  for (; sweep < sweeps; ++sweep) {
    int corrected = 0;
    if (global_.empty()) before = p;
    for (size_t k = 0; k < collide_.size(); ++k) {
      if (collide_[k]->response().resolution != CollisionResolution::Sequential) continue;
      // Positions change with every projection here: the partner's grid is rebuilt before each detection (update()
      // keeps it if the partner has not moved).
      const CollisionPair& pair = scene.collisions[k / 2];
      surfaces_.at(static_cast<size_t>(k % 2 == 0 ? pair.b : pair.a))->update(p);
      collide_[k]->detect(p, sweep == 0, threads, true);
      corrected += collide_[k]->projectPositions(p, w);
    }
    if (global_.empty()) {
      // A sweep that corrected nothing left the positions as they were: every further sweep would repeat it. Nor do
      // the sweeps after one whose corrections moved no coordinate by more than kNegligibleMoveMm: what they correct is
      // the rounding of the last (contacts set exactly at the gap, moved back and forth by 1e-13 mm and less).
      if (corrected == 0 || !((p - before).cwiseAbs().maxCoeff() > kNegligibleMoveMm)) return sweep + 1;
      continue;
    }
    for (auto& kv : surfaces_) kv.second->update(p);
    for (auto& c : collide_)
      if (c->response().resolution == CollisionResolution::Global) c->detect(p, sweep == 0, threads, true);
    for (auto& kv : global_) kv.second->projectPositions(p, w);
  }
  return sweep;
}

}  // namespace msk::detail
