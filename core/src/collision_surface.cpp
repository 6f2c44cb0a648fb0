#include "msk/core/collision_surface.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "msk/core/error.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

namespace {
long long edgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<long long>(a) << 32) | static_cast<unsigned>(b);
}
}  // namespace

CollisionSurface::CollisionSurface(const Triangles& triangles, double reachMm) : tri_(triangles), reach_(reachMm) {
  if (!(reachMm > 0) || !std::isfinite(reachMm))
    throw ParameterError("collision reach", std::to_string(reachMm), "must be > 0 mm");
  if (tri_.rows() == 0) return;
  idxLo_ = tri_.minCoeff();
  idxHi_ = tri_.maxCoeff();
  // Vertex → incident triangles (CSR over the particle range), for vertex normals on demand.
  vtStart_.assign(static_cast<size_t>(idxHi_ - idxLo_ + 2), 0);
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) ++vtStart_[static_cast<size_t>(tri_(t, k) - idxLo_) + 1];
  for (size_t i = 1; i < vtStart_.size(); ++i) vtStart_[i] += vtStart_[i - 1];
  vtTri_.assign(static_cast<size_t>(vtStart_.back()), 0);
  std::vector<int> fill(vtStart_.begin(), vtStart_.end() - 1);
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) vtTri_[static_cast<size_t>(fill[static_cast<size_t>(tri_(t, k) - idxLo_)]++)] = t;
  // Edge → the two triangles sharing it (an open edge, not expected for closed partners, names its one triangle twice).
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      auto [it, fresh] = edgeFaces_.try_emplace(edgeKey(tri_(t, k), tri_(t, (k + 1) % 3)), t, t);
      if (!fresh) it->second.second = t;
    }
}

size_t CollisionSurface::cellIndex(int x, int y, int z) const {
  return (static_cast<size_t>(z) * static_cast<size_t>(dims_[1]) + static_cast<size_t>(y)) * static_cast<size_t>(dims_[0]) +
         static_cast<size_t>(x);
}

Eigen::Vector3i CollisionSurface::cellOf(const Eigen::Vector3d& x) const {
  return ((x - boxLo_) / cell_).array().floor().cast<int>().cwiseMax(0).cwiseMin(dims_.array() - 1);
}

void CollisionSurface::update(const Points& p) {
  winding_.reset();
  const int nt = static_cast<int>(tri_.rows());
  start_.clear();
  items_.clear();
  if (nt == 0) return;
  lo_.resize(nt, 3);
  hi_.resize(nt, 3);
  double extent = 0;
  for (int t = 0; t < nt; ++t) {
    const Eigen::Vector3d x[3] = {p.row(tri_(t, 0)), p.row(tri_(t, 1)), p.row(tri_(t, 2))};
    lo_.row(t) = x[0].cwiseMin(x[1]).cwiseMin(x[2]).transpose();
    hi_.row(t) = x[0].cwiseMax(x[1]).cwiseMax(x[2]).transpose();
    extent += (x[0] - x[1]).norm();
  }
  // Dense grid (CSR) over the bounding box grown by the reach; cell size the reach or the typical triangle extent,
  // whichever is larger (and coarser if the box would need too many cells), so each query scans 27 cells.
  boxLo_ = lo_.colwise().minCoeff().transpose().array() - reach_;
  boxHi_ = hi_.colwise().maxCoeff().transpose().array() + reach_;
  cell_ = std::max(reach_, extent / nt);
  const Eigen::Vector3d size = boxHi_ - boxLo_;
  while ((size / cell_).array().ceil().prod() > 4e6) cell_ *= 1.5;
  dims_ = (size / cell_).array().floor().cast<int>() + 1;
  const size_t cells = static_cast<size_t>(dims_[0]) * static_cast<size_t>(dims_[1]) * static_cast<size_t>(dims_[2]);
  start_.assign(cells + 1, 0);
  auto forCells = [&](int t, auto&& visit) {
    const Eigen::Vector3i a = cellOf(lo_.row(t).transpose()), b = cellOf(hi_.row(t).transpose());
    for (int z = a[2]; z <= b[2]; ++z)
      for (int y = a[1]; y <= b[1]; ++y)
        for (int x = a[0]; x <= b[0]; ++x) visit(cellIndex(x, y, z));
  };
  for (int t = 0; t < nt; ++t) forCells(t, [&](size_t ci) { ++start_[ci + 1]; });
  for (size_t i = 0; i < cells; ++i) start_[i + 1] += start_[i];
  items_.resize(static_cast<size_t>(start_[cells]));
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (int t = 0; t < nt; ++t) {
    CellItem item;
    for (int a = 0; a < 3; ++a) {
      item.lo[a] = lo_(t, a);
      item.hi[a] = hi_(t, a);
    }
    item.triangle = t;
    forCells(t, [&](size_t ci) { items_[static_cast<size_t>(fill[ci]++)] = item; });
  }
}

SurfacePoint CollisionSurface::closest(const Points& p, const Eigen::Vector3d& q, double maxDistance) const {
  SurfacePoint best;
  if (start_.empty() || (q.array() < boxLo_.array()).any() || (q.array() > boxHi_.array()).any()) return best;
  const double radius = std::min(maxDistance, reach_);
  best.distance = radius;
  // Only the cells the ball of `radius` around q touches (at most 2 per axis, as cells are at least the reach wide),
  // within the 3×3×3 block around q's cell. The result is that of scanning the whole block in z, y, x order, each
  // cell's triangles by index, keeping the first of equally close ones (a vertex or edge shared by several triangles
  // is a tie): a tie goes to the triangle the block scan meets first, its first cell in the block, then its index.
  const Eigen::Vector3i c = cellOf(q);
  const double pad = radius * (1 + 1e-9) + 1e-9;  // a superset of the touched cells despite rounding
  const Eigen::Vector3i from = cellOf((q.array() - pad).matrix()).cwiseMax(c - Eigen::Vector3i::Ones());
  const Eigen::Vector3i to = cellOf((q.array() + pad).matrix()).cwiseMin(c + Eigen::Vector3i::Ones());
  size_t bestKey = 0;
  for (int z = from[2]; z <= to[2]; ++z)
    for (int y = from[1]; y <= to[1]; ++y)
      for (int x = from[0]; x <= to[0]; ++x) {
        const size_t ci = cellIndex(x, y, z);
        for (int k = start_[ci]; k < start_[ci + 1]; ++k) {
          const CellItem& item = items_[static_cast<size_t>(k)];
          // Cheap rejection: the triangle's box is already farther than the best found.
          double boxSq = 0;
          for (int a = 0; a < 3; ++a) {
            const double out = std::max(std::max(item.lo[a] - q[a], q[a] - item.hi[a]), 0.0);
            boxSq += out * out;
          }
          if (boxSq > best.distance * best.distance) continue;
          const int t = item.triangle;
          Eigen::Vector3d bc;
          const Eigen::Vector3d cp = closestPointOnTriangle(q, p.row(tri_(t, 0)).transpose(), p.row(tri_(t, 1)).transpose(),
                                                            p.row(tri_(t, 2)).transpose(), &bc);
          const double d = (cp - q).norm();
          if (!(d <= best.distance)) continue;
          // Where the block scan meets t first: its first cell in the block (the box product's smallest corner), then t.
          const Eigen::Vector3i first =
              cellOf(Eigen::Vector3d(item.lo[0], item.lo[1], item.lo[2])).cwiseMax(c - Eigen::Vector3i::Ones());
          const size_t key = cellIndex(first[0], first[1], first[2]) * static_cast<size_t>(tri_.rows()) +
                             static_cast<size_t>(t);
          if (d == best.distance && (best.triangle < 0 || key >= bestKey)) continue;
          best.distance = d;
          best.point = cp;
          best.triangle = t;
          bestKey = key;
          for (int i = 0; i < 3; ++i) best.bary[i] = bc[i];
        }
      }
  return best;
}

Eigen::Vector3d CollisionSurface::faceNormal(const Points& p, int t) const {
  const Eigen::Vector3d a = p.row(tri_(t, 0)), b = p.row(tri_(t, 1)), c = p.row(tri_(t, 2));
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

Eigen::Vector3d CollisionSurface::vertexNormal(const Points& p, int i, bool angleWeighted) const {
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
    auto e = edgeFaces_.find(edgeKey(tri_(t, (zeroAt + 1) % 3), tri_(t, (zeroAt + 2) % 3)));
    if (e != edgeFaces_.end()) return faceNormal(p, e->second.first) + faceNormal(p, e->second.second);
  }
  return faceNormal(p, t);
}

const WindingNumber& CollisionSurface::winding(const Points& p) const {
  std::lock_guard<std::mutex> lock(windingMutex_);
  if (!winding_) winding_ = std::make_unique<WindingNumber>(p, tri_);
  return *winding_;
}

Eigen::Vector3d CollisionSurface::smoothNormal(const Points& p, const SurfacePoint& s) const {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) n += s.bary[k] * vertexNormal(p, tri_(s.triangle, k), false);
  return n;
}

}  // namespace msk
