#include "msk/core/surface_separation.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "msk/core/collision_surface.h"
#include "msk/core/error.h"
#include "msk/core/graph_colouring.h"
#include "msk/core/winding_number.h"
#include "worker_pool.h"

namespace msk {

namespace {

/// Whether q lies in the box of `s` grown by `margin`.
bool nearBox(const Eigen::Vector3d& q, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double margin) {
  return (q.array() >= lo.array() - margin).all() && (q.array() <= hi.array() + margin).all();
}

/// Sample points of a surface where contacts are tested: its vertices, then its face centroids (so that a face of A
/// cutting through B between A's vertices is caught too).
int sampleCount(const TriangleMesh& m) { return m.vertexCount() + m.faceCount(); }

/// Corners and weights of sample k of `m` (1 or 3 corners; returns their number).
int sampleCorners(const TriangleMesh& m, int k, int idx[3], double wts[3]) {
  if (k < m.vertexCount()) {
    idx[0] = k;
    wts[0] = 1.0;
    return 1;
  }
  for (int c = 0; c < 3; ++c) {
    idx[c] = m.faces(k - m.vertexCount(), c);
    wts[c] = 1.0 / 3.0;
  }
  return 3;
}

/// A sample of A near B and the side of B it was last found on.
struct ActiveSample {
  int sample = 0;
  Eigen::Vector3d outward = Eigen::Vector3d::Zero();  ///< B's outward direction at the sample's last contact
  Eigen::Vector3d contact = Eigen::Vector3d::Zero();  ///< where that contact was, mm
  double distance = 0;  ///< its distance to B then (outside), mm; far samples wait for the next refresh
};

/// What the queries of one direction of one pair learnt of each of A's samples, for the next ones: the triangle of B
/// its last query found (−1: none), where its next query starts; and, from a refresh, a distance no triangle of B was
/// nearer than (0: none known; in floats rounded down) as of `stamp`, the two surfaces' summed travel
/// (SeparationState::travelled) then, with whether the sample was outside B. A sample whose distance, less the travel
/// since, is still beyond the reach cannot find B; one that was outside and whose distance less the travel since is
/// still beyond the gap + 1 mm is outside B, too far to be corrected (passes between refreshes leave it alone): the
/// next refresh skips both. One still beyond half the gap is still outside: its side needs no winding number.
struct SampleMemory {
  std::vector<int> triangle;
  std::vector<float> clearance;
  std::vector<char> outside;
  double stamp = 0;
};

/// Whether a distance bound `left` (mm) is beyond `limit` with a margin far above rounding.
bool beyond(double left, double limit) { return left > limit * (1 + 1e-9) + 1e-9; }

/// `x` in a float no larger than it (x ≥ 0).
float floatBelow(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, 0.0f);
  return f;
}

/// One direction of one pair, A's samples against B's surface: each sample inside B or closer than the gap is moved
/// to the gap outside (Table 4.23 position correction, spring target, no friction) with the correction of Pc = P̄B − P̄A
/// shared by the corners of both sides through the reduced mass m̄ = (Σ ak² wA + Σ bj² wB)⁻¹, so linear momentum is
/// conserved. With `refresh`, every sample is examined and its side taken from B's winding number; `active` is then
/// refilled with the samples found within reach. Otherwise only `active` is examined, and a sample's side follows from
/// the side it was on before (it has crossed B if it is now behind B's surface as seen along its last outward
/// direction): the corrections between refreshes are far smaller than the reach.
struct PassResult {
  long applied = 0;
  long skipped = 0;      ///< samples a refresh passed over on their distance bound
  double largestMm = 0;  ///< largest correction |ΔPc|
  bool anyInside = false;
};
/// `travel`: the two surfaces' summed travel at the start of the pass (what `memory` is stamped with).
PassResult separateOnce(TriangleMesh& A, TriangleMesh& B, double wA, double wB, double gap, double reach, bool refresh,
                        std::vector<ActiveSample>& active, SampleMemory& memory, double travel) {
  PassResult out;
  CollisionSurface surface(B.faces, reach);
  surface.update(B.vertices);
  std::optional<WindingNumber> winding;
  const int n = refresh ? sampleCount(A) : static_cast<int>(active.size());
  if (refresh) {
    winding.emplace(B.vertices, B.faces);
    active.clear();
    if (memory.clearance.size() != static_cast<size_t>(n)) {
      memory.clearance.assign(static_cast<size_t>(n), 0.0f);
      memory.outside.assign(static_cast<size_t>(n), 0);
      memory.triangle.assign(static_cast<size_t>(n), -1);
    }
  }
  const double since = travel - memory.stamp;
  // The largest sum of this pass's corrections at any vertex of A and of B so far: with `since`, a bound on how far any
  // point of either surface has moved since the samples' distances were stamped.
  std::vector<double> movedA, movedB;
  double mostA = 0, mostB = 0;
  for (int i = 0; i < n; ++i) {
    // Between refreshes a sample last seen outside and more than 1 mm beyond the gap is left alone: corrections
    // move surfaces by far less per sweep.
    if (!refresh && active[static_cast<size_t>(i)].distance > gap + 1.0) continue;
    const int k = refresh ? i : active[static_cast<size_t>(i)].sample;
    bool knownOutside = false;
    if (refresh) {
      // Still out of reach since the last refresh, or still outside beyond the gap + 1 mm: nothing to find or correct
      // (its bound carried to this pass's stamp).
      float& clear = memory.clearance[static_cast<size_t>(k)];
      char& wasOutside = memory.outside[static_cast<size_t>(k)];
      const double left = static_cast<double>(clear) - since - mostA - mostB;
      if (clear > 0 && (beyond(left, reach) || (wasOutside && beyond(left, gap + 1.0)))) {
        clear = floatBelow(left);
        ++out.skipped;
        continue;
      }
      knownOutside = clear > 0 && wasOutside && beyond(left, 0.5 * gap);
      clear = 0;
      wasOutside = 0;
    }
    int ia[3];
    double wa[3];
    const int na = sampleCorners(A, k, ia, wa);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int c = 0; c < na; ++c) q += wa[c] * A.vertices.row(ia[c]).transpose();
    // The grid is from the start of this pass (B moves a little with each correction): it only guides the search,
    // the closest point is computed at B's current positions. The search starts from the sample's last triangle. A
    // bound it gives when it finds nothing holds for B as it was at the pass's start or is now, whichever is nearer: it
    // is stamped with the travel at the pass's start.
    double clearance = 0;
    int& hint = memory.triangle[static_cast<size_t>(k)];
    const SurfacePoint s = surface.closest(B.vertices, q, reach, hint, refresh ? &clearance : nullptr);
    hint = s.triangle;
    if (s.triangle < 0) {
      if (refresh) memory.clearance[static_cast<size_t>(k)] = floatBelow(clearance);
      continue;
    }
    Eigen::Vector3d normal;  // B's outward side at the contact
    bool inside = false;
    if (s.distance > 1e-12) {
      // Between refreshes the side carries over from the last contact, unless the closest point has jumped (to the
      // other side of a thin partner, say): then the winding number decides. A carried side only rules out work: a
      // sample it places outside beyond half the gap is left alone. Every sample that would be corrected has its side
      // confirmed by the winding number at B's current positions (B moves during the pass), since a wrong side there
      // would move the sample the gap's depth into B.
      const bool carry = !refresh && (s.point - active[static_cast<size_t>(i)].contact).norm() < 0.5;
      inside = carry && (q - s.point).dot(active[static_cast<size_t>(i)].outward) < 0;
      if (!knownOutside && (!carry || inside || s.distance < 0.5 * gap)) {
        if (!winding) winding.emplace(B.vertices, B.faces);
        inside = winding->inside(q, B.vertices);
      }
      normal = (inside ? -1.0 : 1.0) * (q - s.point) / s.distance;
    } else {
      normal = surface.pseudonormal(B.vertices, s);
      if (!(normal.norm() > 1e-12)) continue;
      normal.normalize();
    }
    if (refresh) {
      active.push_back({k, normal, s.point, inside ? 0.0 : s.distance});
      if (!inside) {
        memory.clearance[static_cast<size_t>(k)] = floatBelow(s.distance);
        memory.outside[static_cast<size_t>(k)] = 1;
      }
    } else {
      active[static_cast<size_t>(i)].outward = normal;
      active[static_cast<size_t>(i)].contact = s.point;
      active[static_cast<size_t>(i)].distance = inside ? 0.0 : s.distance;
    }
    // Corrected when inside, or outside but nearer than half the gap (then moved out to the full gap): the
    // hysteresis keeps touching surfaces from trading ever smaller corrections.
    if (!inside && s.distance >= 0.5 * gap) continue;
    out.anyInside = out.anyInside || inside;
    const double pcn = (s.point - q).dot(normal);
    if (!(pcn + gap > 0)) continue;
    const Eigen::Vector3d delta = -(pcn + gap) * normal;  // wanted change of Pc
    double denom = 0;
    for (int c = 0; c < na; ++c) denom += wa[c] * wa[c] * wA;
    for (int c = 0; c < 3; ++c) denom += s.bary[c] * s.bary[c] * wB;
    if (!(denom > 0)) continue;
    const double mbar = 1.0 / denom;
    if (movedA.empty()) {
      movedA.assign(static_cast<size_t>(A.vertexCount()), 0.0);
      movedB.assign(static_cast<size_t>(B.vertexCount()), 0.0);
    }
    for (int c = 0; c < na; ++c) {
      A.vertices.row(ia[c]) -= (wA * wa[c] * mbar) * delta.transpose();
      mostA = std::max(mostA, movedA[static_cast<size_t>(ia[c])] += wA * wa[c] * mbar * delta.norm());
    }
    for (int c = 0; c < 3; ++c) {
      const int corner = B.faces(s.triangle, c);
      B.vertices.row(corner) += (wB * s.bary[c] * mbar) * delta.transpose();
      mostB = std::max(mostB, movedB[static_cast<size_t>(corner)] += wB * s.bary[c] * mbar * delta.norm());
    }
    ++out.applied;
    out.largestMm = std::max(out.largestMm, delta.norm());
  }
  if (refresh) memory.stamp = travel;
  return out;
}

}  // namespace

namespace {

/// Throws ParameterError or Error for inputs separateSurfaces() cannot use.
void checkSeparationInput(const std::vector<TriangleMesh*>& surfaces, const std::vector<double>& inverseMass,
                          const std::vector<SeparationPair>& pairs, const SeparationOptions& opts) {
  if (surfaces.size() != inverseMass.size()) throw Error("separation: one inverse mass per surface is needed");
  if (opts.maxSweeps < 0 || opts.maxSweeps > 10000)
    throw ParameterError("separation sweeps", std::to_string(opts.maxSweeps), "must be 0..10000");
  if (!(opts.maxReachMm >= opts.reachMm) || !std::isfinite(opts.maxReachMm))
    throw ParameterError("separation reach", std::to_string(opts.maxReachMm), "the largest reach must be >= the reach");
  if (!(opts.toleranceMm > 0) || !std::isfinite(opts.toleranceMm))
    throw ParameterError("separation tolerance", std::to_string(opts.toleranceMm), "must be > 0 mm");
  if (opts.threads < 0 || opts.threads > 1024)
    throw ParameterError("separation threads", std::to_string(opts.threads), "must be 0..1024");
  for (double w : inverseMass)
    if (!(w >= 0) || !std::isfinite(w)) throw Error("separation: inverse masses must be finite and non-negative");
  for (const SeparationPair& p : pairs) {
    const int n = static_cast<int>(surfaces.size());
    if (p.a < 0 || p.b < 0 || p.a >= n || p.b >= n || p.a == p.b)
      throw ParameterError("separation pair", std::to_string(p.a) + "," + std::to_string(p.b),
                           "must name two surfaces");
    if (!(p.gapMm >= 0) || !std::isfinite(p.gapMm))
      throw ParameterError("collision gap", std::to_string(p.gapMm), "must be >= 0 mm");
    if (!(opts.reachMm > p.gapMm) || !std::isfinite(opts.reachMm))
      throw ParameterError("separation reach", std::to_string(opts.reachMm), "must exceed the gap");
  }
}

/// Runs `body(begin, end)` over [0, n) on the pool; the first exception a worker throws is rethrown here.
void runGuarded(WorkerPool& pool, int n, const std::function<void(int, int)>& body) {
  std::exception_ptr failure;
  std::mutex failureMutex;
  pool.run(
      n,
      [&](int begin, int end) {
        try {
          body(begin, end);
        } catch (...) {
          const std::lock_guard<std::mutex> lock(failureMutex);
          if (!failure) failure = std::current_exception();
        }
      },
      1);
  if (failure) std::rethrow_exception(failure);
}

/// The reach of each pair: a pair already deeper inside each other than opts.reachMm gets one that covers its deepest
/// vertex (at most opts.maxReachMm).
std::vector<double> pairReaches(const std::vector<TriangleMesh*>& surfaces, const std::vector<SeparationPair>& pairs,
                                const SeparationOptions& opts, WorkerPool& pool) {
  std::vector<double> reach(pairs.size(), opts.reachMm);
  runGuarded(pool, static_cast<int>(pairs.size()), [&](int begin, int end) {
    for (int k = begin; k < end; ++k) {
      const SeparationPair& p = pairs[static_cast<size_t>(k)];
      const TriangleMesh& A = *surfaces[static_cast<size_t>(p.a)];
      const TriangleMesh& B = *surfaces[static_cast<size_t>(p.b)];
      const double deepest = std::max(penetrationDepth(A, B, opts.maxReachMm), penetrationDepth(B, A, opts.maxReachMm));
      reach[static_cast<size_t>(k)] = std::min(opts.maxReachMm, std::max(opts.reachMm, deepest + p.gapMm + 0.5));
    }
  });
  return reach;
}

/// Whether each pair's bounding boxes are farther apart than its reach (it is never tested).
std::vector<bool> farPairs(const std::vector<TriangleMesh*>& surfaces, const std::vector<SeparationPair>& pairs,
                           const std::vector<double>& reach) {
  std::vector<bool> far(pairs.size(), false);
  for (size_t k = 0; k < pairs.size(); ++k) {
    const TriangleMesh& A = *surfaces[static_cast<size_t>(pairs[k].a)];
    const TriangleMesh& B = *surfaces[static_cast<size_t>(pairs[k].b)];
    const Eigen::Vector3d loA = A.vertices.colwise().minCoeff(), hiA = A.vertices.colwise().maxCoeff();
    const Eigen::Vector3d loB = B.vertices.colwise().minCoeff(), hiB = B.vertices.colwise().maxCoeff();
    far[k] = ((loA.array() - reach[k]) > hiB.array()).any() || ((loB.array() - reach[k]) > hiA.array()).any();
  }
  return far;
}

/// The state of a separation across sweeps. A pair whose refresh found nothing inside and corrected nothing is
/// settled; it is skipped for as long as neither of its surfaces is changed by another pair (versions count the
/// passes that moved a surface).
struct SeparationState {
  std::vector<std::vector<ActiveSample>> active;  ///< per pair and direction: samples near the partner
  std::vector<SampleMemory> memory;               ///< per pair and direction: what the samples' queries learnt
  /// Per surface: the sum over the passes of the largest move of any of its vertices in the pass (the difference of
  /// two readings bounds how far any point of it has moved in between), mm
  std::vector<double> travelled;
  std::vector<long> version;     ///< per surface
  std::vector<long> settledAt;   ///< per pair: the larger version of its surfaces when it was found settled (−1: not)
  std::vector<long> examinedAt;  ///< per pair: that version when it was last examined
  std::vector<PassResult> results;  ///< per pair: the last pass
};

/// One sweep: every colour of pairs in turn, the pairs of a colour in parallel, each pair in both directions.
PassResult sweepPairs(std::vector<TriangleMesh*>& surfaces, const std::vector<double>& inverseMass,
                      const std::vector<SeparationPair>& pairs, const Colouring& colours,
                      const std::vector<double>& reach, const std::vector<bool>& far, bool refresh, WorkerPool& pool,
                      SeparationState& st) {
  auto pairVersion = [&](size_t k) {
    return std::max(st.version[static_cast<size_t>(pairs[k].a)], st.version[static_cast<size_t>(pairs[k].b)]);
  };
  PassResult sweep;
  for (int colour = 0; colour < colours.colours(); ++colour) {
    const int begin = colours.start[static_cast<size_t>(colour)],
              size = colours.start[static_cast<size_t>(colour) + 1] - begin;
    runGuarded(pool, size, [&](int lo, int hi) {
      for (int c = lo; c < hi; ++c) {
        const size_t k = static_cast<size_t>(colours.order[static_cast<size_t>(begin + c)]);
        st.results[k] = PassResult{};
        if (far[k] || (st.settledAt[k] >= 0 && pairVersion(k) == st.settledAt[k])) continue;
        const SeparationPair& p = pairs[k];
        TriangleMesh& A = *surfaces[static_cast<size_t>(p.a)];
        TriangleMesh& B = *surfaces[static_cast<size_t>(p.b)];
        const double wA = inverseMass[static_cast<size_t>(p.a)], wB = inverseMass[static_cast<size_t>(p.b)];
        double& travelA = st.travelled[static_cast<size_t>(p.a)];
        double& travelB = st.travelled[static_cast<size_t>(p.b)];
        for (int d = 0; d < 2; ++d) {
          std::vector<ActiveSample>& act = st.active[2 * k + static_cast<size_t>(d)];
          SampleMemory& memory = st.memory[2 * k + static_cast<size_t>(d)];
          const Points startA = A.vertices, startB = B.vertices;
          const PassResult r =
              d == 0 ? separateOnce(A, B, wA, wB, p.gapMm, reach[k], refresh, act, memory, travelA + travelB)
                     : separateOnce(B, A, wB, wA, p.gapMm, reach[k], refresh, act, memory, travelA + travelB);
          if (r.applied > 0) {
            travelA += (A.vertices - startA).rowwise().norm().maxCoeff();
            travelB += (B.vertices - startB).rowwise().norm().maxCoeff();
          }
          st.results[k].applied += r.applied;
          st.results[k].skipped += r.skipped;
          st.results[k].largestMm = std::max(st.results[k].largestMm, r.largestMm);
          st.results[k].anyInside = st.results[k].anyInside || r.anyInside;
        }
      }
    });
    // Bookkeeping after the colour, in pair order (independent of the threads).
    for (int c = 0; c < size; ++c) {
      const size_t k = static_cast<size_t>(colours.order[static_cast<size_t>(begin + c)]);
      const PassResult& r = st.results[k];
      if (r.applied > 0) {
        ++st.version[static_cast<size_t>(pairs[k].a)];
        ++st.version[static_cast<size_t>(pairs[k].b)];
      }
      st.examinedAt[k] = pairVersion(k);
      sweep.applied += r.applied;
      sweep.skipped += r.skipped;
      sweep.largestMm = std::max(sweep.largestMm, r.largestMm);
      sweep.anyInside = sweep.anyInside || r.anyInside;
    }
  }
  // Pairs examined in a refresh that needed nothing are settled at the versions they were examined at (a later
  // colour that moved one of their surfaces has changed that version, which unsettles them).
  if (refresh)
    for (size_t k = 0; k < pairs.size(); ++k)
      if (!far[k] && st.results[k].applied == 0 && !st.results[k].anyInside) st.settledAt[k] = st.examinedAt[k];
  return sweep;
}

}  // namespace

struct SeparationMemory::Samples {
  std::vector<SampleMemory> memory;
};

SeparationMemory::SeparationMemory() = default;
SeparationMemory::~SeparationMemory() = default;

void SeparationMemory::moved(int surface, double mm) {
  if (surface < 0 || static_cast<size_t>(surface) >= travelled.size()) return;  // nothing learnt of it yet
  if (!(mm >= 0) || !std::isfinite(mm)) throw ParameterError("separation move", std::to_string(mm), "must be >= 0 mm");
  travelled[static_cast<size_t>(surface)] += mm;
}

SeparationReport separateSurfaces(std::vector<TriangleMesh*>& surfaces, const std::vector<double>& inverseMass,
                                  const std::vector<SeparationPair>& pairs, const SeparationOptions& opts,
                                  SeparationMemory* memory) {
  checkSeparationInput(surfaces, inverseMass, pairs, opts);
  SeparationReport rep;
  // Samples found near the partner at the last refresh, per pair and direction. A refresh (every sample examined, the
  // side from the winding number) comes every kRefresh sweeps and before the run may stop, so a sample pushed into a
  // partner by another pair's corrections is caught.
  constexpr int kRefresh = 4;
  const size_t np = pairs.size();
  // Pairs are coloured so that the pairs of one colour share no surface: they run in parallel, and the result does
  // not depend on the thread count (colours in order, pairs of a colour independent).
  const Colouring colours = colourConstraints(static_cast<int>(np), 2, [&](int k, int* out) {
    out[0] = pairs[static_cast<size_t>(k)].a;
    out[1] = pairs[static_cast<size_t>(k)].b;
    return 2;
  });
  WorkerPool pool(std::max(1, opts.threads > 0 ? opts.threads : static_cast<int>(std::thread::hardware_concurrency())));
  const std::vector<double> reach = pairReaches(surfaces, pairs, opts, pool);
  const std::vector<bool> far = farPairs(surfaces, pairs, reach);
  SeparationState st;
  st.active.resize(2 * np);
  st.memory.resize(2 * np);
  st.travelled.assign(surfaces.size(), 0.0);
  if (memory && memory->samples && memory->samples->memory.size() == 2 * np &&
      memory->travelled.size() == surfaces.size()) {
    st.memory = std::move(memory->samples->memory);
    st.travelled = memory->travelled;
    // The distance bounds carry over; the triangles found do not: a search guided by the grid of a pass's start finds
    // what a search without them finds only while nothing has moved, so this run starts where a fresh one starts.
    for (SampleMemory& m : st.memory) std::fill(m.triangle.begin(), m.triangle.end(), -1);
  }
  st.version.assign(surfaces.size(), 0);
  st.settledAt.assign(np, -1);
  st.examinedAt.assign(np, -1);
  st.results.resize(np);
  int sinceRefresh = 0;
  bool settled = false;
  for (int sweep = 0; sweep < opts.maxSweeps; ++sweep) {
    const bool refresh = sweep == 0 || sinceRefresh >= kRefresh || settled;
    sinceRefresh = refresh ? 1 : sinceRefresh + 1;
    const PassResult r = sweepPairs(surfaces, inverseMass, pairs, colours, reach, far, refresh, pool, st);
    ++rep.sweeps;
    rep.corrections += r.applied;
    rep.skipped += r.skipped;
    // Done when a refresh sweep finds nothing inside a partner. Between refreshes, a sweep that found nothing inside
    // and corrected nothing by more than the tolerance calls the refresh early (within-gap adjustments between three
    // or more touching surfaces can go on trading hundredths of a millimetre).
    if (refresh && !r.anyInside) {
      rep.clean = true;
      break;
    }
    settled = !r.anyInside && r.largestMm < opts.toleranceMm;
  }
  for (TriangleMesh* s : surfaces)
    if (!s->vertices.allFinite()) throw Error("separation: non-finite vertex position");
  if (memory) {
    if (!memory->samples) memory->samples = std::make_unique<SeparationMemory::Samples>();
    memory->samples->memory = std::move(st.memory);
    memory->travelled = st.travelled;
  }
  return rep;
}

double penetrationDepth(const TriangleMesh& a, const TriangleMesh& b, double reachMm) {
  if (a.vertexCount() == 0 || b.faceCount() == 0) return 0;
  const Eigen::Vector3d lo = b.vertices.colwise().minCoeff(), hi = b.vertices.colwise().maxCoeff();
  const WindingNumber winding(b.vertices, b.faces);
  CollisionSurface surface(b.faces, reachMm);
  surface.update(b.vertices);
  double worst = 0;
  for (int v = 0; v < a.vertexCount(); ++v) {
    const Eigen::Vector3d q = a.vertices.row(v).transpose();
    if (!nearBox(q, lo, hi, 0.0) || !winding.inside(q)) continue;
    const SurfacePoint s = surface.closest(b.vertices, q, reachMm);
    worst = std::max(worst, s.triangle < 0 ? reachMm : s.distance);
  }
  return worst;
}

}  // namespace msk
