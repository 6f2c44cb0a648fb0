#include "msk/core/collision_surface.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "msk/core/error.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

namespace {
long long edgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<long long>(a) << 32) | static_cast<unsigned>(b);
}
}  // namespace

CollisionSurface::CollisionSurface(const Triangles& triangles, double reachMm, double cellEdges)
    : tri_(triangles), reach_(reachMm), cellEdges_(cellEdges) {
  if (!(reachMm > 0) || !std::isfinite(reachMm))
    throw ParameterError("collision reach", std::to_string(reachMm), "must be > 0 mm");
  if (!(cellEdges > 0) || !std::isfinite(cellEdges))
    throw ParameterError("collision grid cell", std::to_string(cellEdges), "must be > 0 mean edges");
  if (tri_.rows() == 0) return;
  idxLo_ = tri_.minCoeff();
  idxHi_ = tri_.maxCoeff();
}

void CollisionSurface::buildTopology() const {
  // Vertex → incident triangles (CSR over the particle range), for vertex normals on demand.
  vtStart_.assign(static_cast<size_t>(idxHi_ - idxLo_ + 2), 0);
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) ++vtStart_[static_cast<size_t>(tri_(t, k) - idxLo_) + 1];
  for (size_t i = 1; i < vtStart_.size(); ++i) vtStart_[i] += vtStart_[i - 1];
  vtTri_.assign(static_cast<size_t>(vtStart_.back()), 0);
  std::vector<int> fill(vtStart_.begin(), vtStart_.end() - 1);
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) vtTri_[static_cast<size_t>(fill[static_cast<size_t>(tri_(t, k) - idxLo_)]++)] = t;
  // Triangle → the triangles sharing a corner with it, itself included, each once.
  ttStart_.assign(static_cast<size_t>(tri_.rows()) + 1, 0);
  ttTri_.clear();
  for (int t = 0; t < tri_.rows(); ++t) {
    const auto from = static_cast<std::ptrdiff_t>(ttTri_.size());
    for (int k = 0; k < 3; ++k) {
      const size_t local = static_cast<size_t>(tri_(t, k) - idxLo_);
      for (int j = vtStart_[local]; j < vtStart_[local + 1]; ++j) {
        const int u = vtTri_[static_cast<size_t>(j)];
        if (std::find(ttTri_.begin() + from, ttTri_.end(), u) == ttTri_.end()) ttTri_.push_back(u);
      }
    }
    ttStart_[static_cast<size_t>(t) + 1] = static_cast<int>(ttTri_.size());
  }
  // Edge → the two triangles sharing it (an open edge, not expected for closed partners, names its one triangle twice).
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      auto [it, fresh] = edgeFaces_.try_emplace(edgeKey(tri_(t, k), tri_(t, (k + 1) % 3)), t, t);
      if (!fresh) it->second.second = t;
    }
}

void CollisionSurface::update(const Points& p) {
  const int nt = static_cast<int>(tri_.rows());
  if (nt == 0) {
    winding_.reset();
    grid_ = TriangleGrid();
    return;
  }
  // Nothing to do when the surface's particles are where they were at the last update (as between the collision-only
  // sweeps of sets whose corrections did not touch this surface): the grid and winding number stay valid.
  const Eigen::Index rows = idxHi_ - idxLo_ + 1;
  if (p.rows() > idxHi_ && built_.rows() == rows && built_ == p.middleRows(idxLo_, rows)) return;
  winding_.reset();
  if (p.rows() > idxHi_) {
    if (built_.rows() == rows) travelled_ += (p.middleRows(idxLo_, rows) - built_).rowwise().norm().maxCoeff();
    built_ = p.middleRows(idxLo_, rows);
  }
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  double extent = 0;
  for (int t = 0; t < nt; ++t) {
    const Eigen::Vector3d x[3] = {p.row(tri_(t, 0)), p.row(tri_(t, 1)), p.row(tri_(t, 2))};
    lo = lo.cwiseMin(x[0].cwiseMin(x[1]).cwiseMin(x[2]));
    hi = hi.cwiseMax(x[0].cwiseMax(x[1]).cwiseMax(x[2]));
    extent += (x[0] - x[1]).norm();
  }
  // A dense grid over the bounding box grown by the reach; cell size the reach or cellEdges_ typical triangle extents,
  // whichever is larger (and coarser if the box would need too many cells), so each query scans at most 27 cells.
  TriangleGrid::Layout layout;
  layout.lo = lo.array() - reach_;
  boxHi_ = hi.array() + reach_;
  meanEdge_ = extent / nt;
  layout.cell = std::max(reach_, cellEdges_ * meanEdge_);
  const Eigen::Vector3d size = boxHi_ - layout.lo;
  while ((size / layout.cell).array().ceil().prod() > 4e6) layout.cell *= 1.5;
  layout.dims = (size / layout.cell).array().floor().cast<int>() + 1;
  grid_.build(layout, p, tri_);
}

SurfacePoint CollisionSurface::closest(const Points& p, const Eigen::Vector3d& q, double maxDistance, int hint,
                                       double* clearance) const {
  if (clearance) *clearance = 0;
  if (grid_.empty()) return {};
  if ((q.array() < grid_.layout().lo.array()).any() || (q.array() > boxHi_.array()).any()) {
    // Outside the triangles' bounding box grown by the reach: no triangle is nearer than that box.
    if (clearance) {
      const Eigen::Vector3d lo = grid_.layout().lo.array() + reach_, hi = boxHi_.array() - reach_;
      *clearance = (lo - q).cwiseMax(q - hi).cwiseMax(0.0).norm();
    }
    return {};
  }
  return grid_.closestWithin(p, tri_, q, std::min(maxDistance, reach_), hint, clearance);
}

SurfacePoint CollisionSurface::closestAround(const Points& p, const Eigen::Vector3d& q, int around, double maxDistance,
                                             int maxWalk) const {
  if (around < 0 || around >= tri_.rows()) return {};
  std::call_once(topologyBuilt_, [this] { buildTopology(); });
  int centre = around;
  for (int walk = 0; walk <= maxWalk; ++walk) {
    SurfacePoint best;
    best.distance = std::numeric_limits<double>::infinity();
    for (int j = ttStart_[static_cast<size_t>(centre)]; j < ttStart_[static_cast<size_t>(centre) + 1]; ++j) {
      const int t = ttTri_[static_cast<size_t>(j)];
      Eigen::Vector3d bc;
      const Eigen::Vector3d cp = closestPointOnTriangle(q, p.row(tri_(t, 0)).transpose(), p.row(tri_(t, 1)).transpose(),
                                                        p.row(tri_(t, 2)).transpose(), &bc);
      const double d = (cp - q).norm();
      if (d < best.distance || (d == best.distance && t < best.triangle)) {
        best.distance = d;
        best.point = cp;
        best.triangle = t;
        for (int i = 0; i < 3; ++i) best.bary[i] = bc[i];
      }
    }
    if (best.triangle != centre) {  // a nearer triangle at the patch's edge: walk on around it
      centre = best.triangle;
      continue;
    }
    if (!(best.distance < std::min(maxDistance, reach_))) return {};
    return best;
  }
  return {};
}

Eigen::Vector3d CollisionSurface::faceNormal(const Points& p, int t) const {
  const Eigen::Vector3d a = p.row(tri_(t, 0)), b = p.row(tri_(t, 1)), c = p.row(tri_(t, 2));
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

Eigen::Vector3d CollisionSurface::vertexNormal(const Points& p, int i, bool angleWeighted) const {
  std::call_once(topologyBuilt_, [this] { buildTopology(); });
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const size_t local = static_cast<size_t>(i - idxLo_);
  for (int k = vtStart_[local]; k < vtStart_[local + 1]; ++k) {
    const int t = vtTri_[static_cast<size_t>(k)];
    const Eigen::Vector3d n = faceNormal(p, t);
    if (!angleWeighted) {
      sum += n;
      continue;
    }
    int c = 0;
    while (tri_(t, c) != i) ++c;
    const Eigen::Vector3d e1 = (p.row(tri_(t, (c + 1) % 3)) - p.row(i)).transpose(),
                          e2 = (p.row(tri_(t, (c + 2) % 3)) - p.row(i)).transpose();
    sum += std::atan2(e1.cross(e2).norm(), e1.dot(e2)) * n;
  }
  const double len = sum.norm();
  return len > 0 ? Eigen::Vector3d(sum / len) : Eigen::Vector3d::Zero();
}

Eigen::Vector3d CollisionSurface::pseudonormal(const Points& p, const SurfacePoint& s) const {
  constexpr double kFeature = 1e-9;
  const int t = s.triangle;
  int zeros = 0, zeroAt = -1, oneAt = -1;
  for (int k = 0; k < 3; ++k) {
    if (s.bary[k] < kFeature) {
      ++zeros;
      zeroAt = k;
    }
    if (s.bary[k] > 1.0 - kFeature) oneAt = k;
  }
  if (oneAt >= 0) return vertexNormal(p, tri_(t, oneAt), true);
  if (zeros == 1) {
    std::call_once(topologyBuilt_, [this] { buildTopology(); });
    auto e = edgeFaces_.find(edgeKey(tri_(t, (zeroAt + 1) % 3), tri_(t, (zeroAt + 2) % 3)));
    if (e != edgeFaces_.end()) return faceNormal(p, e->second.first) + faceNormal(p, e->second.second);
  }
  return faceNormal(p, t);
}

const WindingNumber& CollisionSurface::winding(const Points& p) const {
  std::lock_guard<std::mutex> lock(windingMutex_);
  // Built at the current positions (no stale far field), so clusters can be small: leaves of one edge (1–1.5 edges
  // are fastest on icospheres of 5 k to 82 k triangles, kernels_bench BM_WindingNumberNearSurface).
  if (!winding_) winding_ = std::make_unique<WindingNumber>(p, tri_, meanEdge_);
  return *winding_;
}

Eigen::Vector3d CollisionSurface::smoothNormal(const Points& p, const SurfacePoint& s) const {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) n += s.bary[k] * vertexNormal(p, tri_(s.triangle, k), false);
  return n;
}

}  // namespace msk
