#include "msk/core/tet_untangle.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/tet_split.h"

namespace msk {

namespace {

using Vec3 = Eigen::Vector3d;

/// Local face j of a tet (the nodes other than j), listed so that its normal points out of a positive tet.
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

/// One incident tet of a node as a linear function of the node: V(x) = g·x + c (mm³), scaled by 1/R.
struct Plane {
  Vec3 g;
  double c;
  double value(const Vec3& x) const { return g.dot(x) + c; }
};

/// The planes of node `v`'s incident tets, each divided by its reference volume.
void nodePlanes(const TetMesh& m, const std::vector<std::vector<std::pair<int, int>>>& incident, int v,
                const Eigen::VectorXd& ref, std::vector<Plane>& out) {
  out.clear();
  for (const auto& [t, j] : incident[static_cast<size_t>(v)]) {
    const Vec3 f0 = m.nodes.row(m.tets(t, kFace[j][0])).transpose();
    const Vec3 f1 = m.nodes.row(m.tets(t, kFace[j][1])).transpose();
    const Vec3 f2 = m.nodes.row(m.tets(t, kFace[j][2])).transpose();
    const Vec3 n = (f1 - f0).cross(f2 - f0);  // outward, away from node j: V = (f0 − x)·n / 6
    const double r = ref.size() ? ref[t] : 1.0;
    out.push_back({-n / (6.0 * r), f0.dot(n) / (6.0 * r)});
  }
}

/// Penalty of one relative volume u: exp(−k u), continued as its second-order Taylor polynomial beyond −k u = 50 (no
/// overflow, still convex and C²). Returns φ and sets φ′, φ″ (derivatives in u).
double penalty(double u, double k, double& d1, double& d2) {
  const double z = -k * u, z0 = 50.0;
  if (z <= z0) {
    const double e = std::exp(z);
    d1 = -k * e;
    d2 = k * k * e;
    return e;
  }
  const double e0 = std::exp(z0), dz = z - z0;
  d1 = -k * e0 * (1.0 + dz);
  d2 = k * k * e0;
  return e0 * (1.0 + dz + 0.5 * dz * dz);
}

/// Energy of one node: Σ_t φ(u_t(x)) + β |x − anchor|² / L² (the last term only for a finite move limit L).
struct NodeEnergy {
  const std::vector<Plane>& planes;
  double k, beta, limit;
  Vec3 anchor;
  double value(const Vec3& x, Vec3* grad, Eigen::Matrix3d* hess) const {
    double e = 0, d1 = 0, d2 = 0;
    if (grad) grad->setZero(), hess->setZero();
    for (const Plane& p : planes) {
      e += penalty(p.value(x), k, d1, d2);
      if (grad) *grad += d1 * p.g, *hess += d2 * p.g * p.g.transpose();
    }
    if (std::isfinite(limit)) {
      const double w = beta / (limit * limit);
      e += w * (x - anchor).squaredNorm();
      if (grad) *grad += 2 * w * (x - anchor), *hess += 2 * w * Eigen::Matrix3d::Identity();
    }
    return e;
  }
  /// Points further than the limit from the anchor are brought back onto that ball.
  Vec3 clamp(const Vec3& y) const {
    if (!std::isfinite(limit)) return y;
    const Vec3 d = y - anchor;
    const double len = d.norm();
    return len > limit ? Vec3(anchor + (limit / len) * d) : y;
  }
};

/// Damped Newton descent of the node energy from x0 (at most `iterations` steps); returns the end point.
Vec3 descend(const NodeEnergy& en, const Vec3& x0, int iterations) {
  Vec3 x = x0;
  for (int it = 0; it < iterations; ++it) {
    Vec3 g;
    Eigen::Matrix3d h;
    const double f = en.value(x, &g, &h);
    // The Hessian is only semi-definite where the penalised tets do not surround the node: a little damping.
    const double damping = 1e-9 * h.trace() + 1e-300;
    const Vec3 step = -(h + damping * Eigen::Matrix3d::Identity()).ldlt().solve(g);
    if (!step.allFinite()) break;
    double a = 1.0;
    bool moved = false;
    for (int ls = 0; ls < 30; ++ls, a *= 0.5) {
      const Vec3 y = en.clamp(x + a * step);
      if (en.value(y, nullptr, nullptr) < f + 1e-4 * g.dot(y - x)) {
        moved = (y - x).norm() > 0;
        x = y;
        break;
      }
    }
    if (!moved || a * step.norm() < 1e-9 * (1.0 + x.norm())) break;
  }
  return x;
}

}  // namespace

TetUntangleReport untangleTets(TetMesh& mesh, const std::vector<char>& movable, const Eigen::VectorXd& reference,
                               const TetUntangleOptions& opt) {
  if (static_cast<int>(movable.size()) != mesh.nodeCount())
    throw ParameterError("movable nodes", std::to_string(movable.size()),
                         "need one flag per node (" + std::to_string(mesh.nodeCount()) + ")");
  Eigen::VectorXd limit(mesh.nodeCount());
  for (int i = 0; i < mesh.nodeCount(); ++i)
    limit[i] = movable[static_cast<size_t>(i)] ? std::numeric_limits<double>::infinity() : 0.0;
  return untangleTets(mesh, limit, reference, opt);
}

TetUntangleReport untangleTets(TetMesh& mesh, const Eigen::VectorXd& moveLimit, const Eigen::VectorXd& reference,
                               const TetUntangleOptions& opt) {
  const int nn = mesh.nodeCount(), nt = mesh.tetCount();
  if (moveLimit.size() != nn)
    throw ParameterError("node move limits", std::to_string(moveLimit.size()),
                         "need one per node (" + std::to_string(nn) + ")");
  if (nn && !(moveLimit.array() >= 0).all())
    throw ParameterError("node move limits", std::to_string(moveLimit.minCoeff()), "must be ≥ 0");
  if (!(opt.sharpness > 0) || !std::isfinite(opt.sharpness))
    throw ParameterError("untangling sharpness", std::to_string(opt.sharpness), "must be > 0");
  if (!(opt.anchorWeight >= 0) || !(opt.tolerance >= 0))
    throw ParameterError("untangling anchor weight / tolerance",
                         std::to_string(opt.anchorWeight) + " / " + std::to_string(opt.tolerance), "must be ≥ 0");
  const Points start = mesh.nodes;
  if (reference.size() != 0 && reference.size() != nt)
    throw ParameterError("reference volumes", std::to_string(reference.size()),
                         "need none or one per tet (" + std::to_string(nt) + ")");
  if (reference.size() && !(reference.array() > 0).all())
    throw ParameterError("reference volumes", std::to_string(reference.minCoeff()), "must be > 0");
  if (opt.maxSweeps < 0) throw ParameterError("untangling sweeps", std::to_string(opt.maxSweeps), "must be ≥ 0");

  std::vector<std::vector<std::pair<int, int>>> incident(static_cast<size_t>(nn));  // node → (tet, local index)
  for (int t = 0; t < nt; ++t)
    for (int j = 0; j < 4; ++j) incident[static_cast<size_t>(mesh.tets(t, j))].emplace_back(t, j);
  auto relative = [&](int t) {
    const double v = signedTetVolume(mesh.nodes.row(mesh.tets(t, 0)), mesh.nodes.row(mesh.tets(t, 1)),
                                     mesh.nodes.row(mesh.tets(t, 2)), mesh.nodes.row(mesh.tets(t, 3)));
    return reference.size() ? v / reference[t] : v;
  };

  TetUntangleReport rep;
  for (int t = 0; t < nt; ++t) rep.invertedBefore += relative(t) <= 0 ? 1 : 0;
  std::vector<Plane> planes;
  auto anyInverted = [&]() {
    for (int t = 0; t < nt; ++t)
      if (relative(t) <= 0) return true;
    return false;
  };
  // Stages of growing sharpness: while tets stay inverted the energy is made steeper, nearer to max-min volume.
  double k = opt.sharpness;
  for (int sweep = 0; sweep < opt.maxSweeps; ++sweep) {
    int visited = 0, moves = 0;
    double largest = 0, scale = 0;
    for (int v = 0; v < nn; ++v) {
      if (!(moveLimit[v] > 0) || incident[static_cast<size_t>(v)].empty()) continue;
      double lo = std::numeric_limits<double>::infinity();
      for (const auto& tj : incident[static_cast<size_t>(v)]) lo = std::min(lo, relative(tj.first));
      if (!(lo < opt.minRelativeVolume)) continue;
      ++visited;
      nodePlanes(mesh, incident, v, reference, planes);
      const Vec3 x0 = mesh.nodes.row(v).transpose();
      const NodeEnergy en{planes, k, opt.anchorWeight, moveLimit[v], start.row(v).transpose()};
      const Vec3 x = descend(en, x0, 20);
      // A node whose tets are all positive keeps them so (a valid mesh stays valid); one next to an inverted tet may
      // trade, as the energy says.
      auto invertedAt = [&](const Vec3& y) {
        int n = 0;
        for (const Plane& p : planes) n += p.value(y) <= 0 ? 1 : 0;
        return n;
      };
      if (x.allFinite() && x != x0 && (invertedAt(x0) > 0 || invertedAt(x) == 0)) {
        mesh.nodes.row(v) = x.transpose();
        ++moves;
        largest = std::max(largest, (x - x0).norm());
      }
      // Typical length around the node: the cube root of the (reference) volume scale of its tets.
      double vol = 0;
      for (const auto& tj : incident[static_cast<size_t>(v)]) vol += reference.size() ? reference[tj.first] : 1.0;
      scale = std::max(scale, std::cbrt(vol / static_cast<double>(incident[static_cast<size_t>(v)].size())));
    }
    rep.sweeps = sweep + 1;
    rep.moves += moves;
    if (visited == 0) break;
    if (moves == 0 || largest < opt.tolerance * scale) {
      if (k >= 64 * opt.sharpness || !anyInverted()) break;
      k *= 4;
    }
  }
  rep.minRelativeVolumeAfter = std::numeric_limits<double>::infinity();
  for (int t = 0; t < nt; ++t) {
    const double r = relative(t);
    rep.invertedAfter += r <= 0 ? 1 : 0;
    rep.minRelativeVolumeAfter = std::min(rep.minRelativeVolumeAfter, r);
  }
  return rep;
}

TetMeshUntangleReport untangleTetMesh(TetMesh& mesh, const Eigen::VectorXd& reference, double reach,
                                      const TetUntangleOptions& opt) {
  if (!(reach >= 0)) throw ParameterError("boundary reach (mm)", std::to_string(reach), "must be ≥ 0");
  const std::vector<char> onBoundary = boundaryNodeMask(mesh);
  const int nn = mesh.nodeCount(), nt = mesh.tetCount();
  std::vector<char> interior(onBoundary.size());
  for (size_t i = 0; i < interior.size(); ++i) interior[i] = !onBoundary[i];
  TetMeshUntangleReport rep;
  rep.interior = untangleTets(mesh, interior, reference, opt);
  rep.invertedAfter = rep.interior.invertedAfter;
  if (rep.invertedAfter == 0 || !(reach > 0)) return rep;

  // Boundary nodes of every tet that touches a node of an inverted tet may move, up to `reach`.
  const Eigen::VectorXd vol = tetVolumes(mesh);
  std::vector<char> near(static_cast<size_t>(nn), 0);
  for (int t = 0; t < nt; ++t)
    if (vol[t] <= 0)
      for (int k = 0; k < 4; ++k) near[static_cast<size_t>(mesh.tets(t, k))] = 1;
  Eigen::VectorXd limit(nn);
  for (int i = 0; i < nn; ++i)
    limit[i] = interior[static_cast<size_t>(i)] ? std::numeric_limits<double>::infinity() : 0.0;
  for (int t = 0; t < nt; ++t) {
    bool touches = false;
    for (int k = 0; k < 4; ++k) touches = touches || near[static_cast<size_t>(mesh.tets(t, k))];
    if (!touches) continue;
    for (int k = 0; k < 4; ++k) limit[mesh.tets(t, k)] = std::max(limit[mesh.tets(t, k)], reach);
  }
  const Points before = mesh.nodes;
  rep.boundary = untangleTets(mesh, limit, reference, opt);
  rep.invertedAfter = rep.boundary.invertedAfter;
  for (int i = 0; i < nn; ++i) {
    if (interior[static_cast<size_t>(i)]) continue;
    const double d = (mesh.nodes.row(i) - before.row(i)).norm();
    if (d > 0) ++rep.boundaryNodesMoved;
    rep.largestBoundaryMoveMm = std::max(rep.largestBoundaryMoveMm, d);
  }
  return rep;
}

namespace {

/// 6√2 V / l_rms³ of the tet (a, b, c, d).
double shapeQuality(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double l2 = ((b - a).squaredNorm() + (c - a).squaredNorm() + (d - a).squaredNorm() + (c - b).squaredNorm() +
                     (d - b).squaredNorm() + (d - c).squaredNorm()) /
                    6.0;
  if (!(l2 > 0)) return 0;
  return 6.0 * std::sqrt(2.0) * signedTetVolume(a, b, c, d) / (l2 * std::sqrt(l2));
}

}  // namespace

Eigen::VectorXd tetShapeQualities(const TetMesh& m) {
  Eigen::VectorXd q(m.tetCount());
  for (int t = 0; t < m.tetCount(); ++t)
    q[t] = shapeQuality(m.nodes.row(m.tets(t, 0)).transpose(), m.nodes.row(m.tets(t, 1)).transpose(),
                        m.nodes.row(m.tets(t, 2)).transpose(), m.nodes.row(m.tets(t, 3)).transpose());
  return q;
}

double improveTetShapes(TetMesh& mesh, const std::vector<char>& movable, int sweeps) {
  const int nn = mesh.nodeCount(), nt = mesh.tetCount();
  if (static_cast<int>(movable.size()) != nn)
    throw ParameterError("movable nodes", std::to_string(movable.size()),
                         "need one flag per node (" + std::to_string(nn) + ")");
  std::vector<std::vector<std::pair<int, int>>> incident(static_cast<size_t>(nn));
  for (int t = 0; t < nt; ++t)
    for (int j = 0; j < 4; ++j) incident[static_cast<size_t>(mesh.tets(t, j))].emplace_back(t, j);
  // Smallest quality of node v's tets with v at x.
  auto worst = [&](int v, const Vec3& x) {
    double lo = std::numeric_limits<double>::infinity();
    for (const auto& [t, j] : incident[static_cast<size_t>(v)]) {
      Vec3 p[4];
      for (int k = 0; k < 4; ++k) p[k] = k == j ? x : Vec3(mesh.nodes.row(mesh.tets(t, k)).transpose());
      lo = std::min(lo, shapeQuality(p[0], p[1], p[2], p[3]));
    }
    return lo;
  };
  const Vec3 dirs[6] = {Vec3::UnitX(), -Vec3::UnitX(), Vec3::UnitY(), -Vec3::UnitY(), Vec3::UnitZ(), -Vec3::UnitZ()};
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    int moves = 0;
    for (int v = 0; v < nn; ++v) {
      if (!movable[static_cast<size_t>(v)] || incident[static_cast<size_t>(v)].empty()) continue;
      const Vec3 x0 = mesh.nodes.row(v).transpose();
      double edge = 0;
      int edges = 0;
      for (const auto& tj : incident[static_cast<size_t>(v)])
        for (int k = 0; k < 4; ++k)
          if (k != tj.second) edge += (mesh.nodes.row(mesh.tets(tj.first, k)).transpose() - x0).norm(), ++edges;
      edge /= std::max(edges, 1);
      Vec3 x = x0;
      double best = worst(v, x);
      for (double h = 0.25 * edge; h > 1e-3 * edge;) {
        Vec3 pick = x;
        double pickQ = best;
        for (const Vec3& d : dirs) {
          const Vec3 y = x + h * d;
          const double q = worst(v, y);
          if (q > pickQ) pickQ = q, pick = y;
        }
        if (pickQ > best) {
          best = pickQ;
          x = pick;
        } else {
          h *= 0.5;
        }
      }
      if (x != x0) {
        mesh.nodes.row(v) = x.transpose();
        ++moves;
      }
    }
    if (moves == 0) break;
  }
  return nt ? tetShapeQualities(mesh).minCoeff() : 0.0;
}

double improveWorstTetShapes(TetMesh& mesh, double below, int sweeps) {
  if (std::isnan(below)) throw ParameterError("shape quality threshold", "NaN", "must be a number");
  const Eigen::VectorXd q = tetShapeQualities(mesh);
  const std::vector<char> onBoundary = boundaryNodeMask(mesh);
  std::vector<char> movable(onBoundary.size(), 0);
  for (int t = 0; t < mesh.tetCount(); ++t) {
    if (!(q[t] < below)) continue;
    for (int k = 0; k < 4; ++k) {
      const auto v = static_cast<size_t>(mesh.tets(t, k));
      movable[v] = !onBoundary[v];
    }
  }
  return improveTetShapes(mesh, movable, sweeps);
}

}  // namespace msk
