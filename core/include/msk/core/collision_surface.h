#pragma once
/// The partner side of vertex–surface collisions (DESIGN-NOTES §3): a closed triangulated surface whose corners are
/// particles of a stacked system, with its connectivity set up once and a uniform grid over its triangles rebuilt
/// once per step (TriangleGrid), shared by every collision set that tests vertices against it.
#include <Eigen/Core>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "msk/core/triangle_grid.h"
#include "msk/core/triangle_mesh.h"
#include "msk/core/winding_number.h"

namespace msk {

/// A partner surface: triangles over global particle indices, queried for closest points and side normals.
class CollisionSurface {
 public:
  /// `triangles` (outward, closed) index particles of the stacked system; queries reach `reachMm` (> 0). The grid's
  /// cells are the reach or `cellEdges` (> 0) times the triangles' mean edge wide, whichever is larger: larger cells
  /// mean fewer cells per query and more triangles per cell (the same answers either way).
  CollisionSurface(const Triangles& triangles, double reachMm, double cellEdges = 1.0);
  /// Rebuilds the grid over the triangles at positions `p` (call once per step, before the queries); keeps it, and the
  /// winding number, if the surface's particles have not moved since the last update().
  void update(const Points& p);
  /// The closest point of the surface to `q` within min(`maxDistance`, reach()) at the positions of the last update();
  /// `hint` a triangle likely to be it (TriangleGrid::closestWithin(), the same answer with or without); `clearance`
  /// (optional): when nothing is found, a distance no triangle is nearer than (from the scan of the grid, or for a
  /// point outside the triangles' bounding box grown by the reach, the distance to that box), else 0.
  SurfacePoint closest(const Points& p, const Eigen::Vector3d& q, double maxDistance, int hint = -1,
                       double* clearance = nullptr) const;
  /// The closest point to `q` on the triangles around `around` (those sharing a corner with it), walked on: while the
  /// closest of them is another triangle, the triangles around that one, at most `maxWalk` times. A local answer for a
  /// point that found `around` in a recent query and has moved little since: another part of the surface nearer than
  /// the walk's patch is not seen. Nothing (triangle −1) if the walk ends farther than min(`maxDistance`, reach()) or
  /// does not settle. Of equally close triangles the lower index wins. Thread-safe.
  SurfacePoint closestAround(const Points& p, const Eigen::Vector3d& q, int around, double maxDistance,
                             int maxWalk = 3) const;
  /// Whether a walk (closestAround()) is cheaper than a scan of the grid: the triangles are less than half the reach
  /// across (mean edge at the last update()), so that each of the cells a scan visits (the reach wide) lists many.
  bool walkPays() const { return meanEdge_ > 0 && meanEdge_ < 0.5 * reach_; }
  /// The sum over the updates of the largest move of any of the surface's particles since the one before: the
  /// difference of two readings bounds how far any point of the surface has moved in between, mm.
  double travelled() const { return travelled_; }
  /// Pseudonormal of the closest feature of `s` (face, edge: sum of its two faces, vertex: angle-weighted), not unit:
  /// its sign against q − point is exact for a closed, non-self-intersecting surface (Bærentzen & Aanæs 2005).
  Eigen::Vector3d pseudonormal(const Points& p, const SurfacePoint& s) const;
  /// The surface's winding number at positions `p` (those of the last update()), built on the first call after each
  /// update() and shared by every set against this surface (thread-safe).
  const WindingNumber& winding(const Points& p) const;
  /// Smooth normal at `s`: the corners' (unweighted) vertex normals interpolated with the barycentric weights.
  Eigen::Vector3d smoothNormal(const Points& p, const SurfacePoint& s) const;
  /// The triangles (global particle indices).
  const Triangles& triangles() const { return tri_; }
  /// Largest query distance the grid supports, mm.
  double reach() const { return reach_; }

 private:
  Eigen::Vector3d faceNormal(const Points& p, int t) const;
  Eigen::Vector3d vertexNormal(const Points& p, int i, bool angleWeighted) const;

  Triangles tri_;
  double reach_;
  double cellEdges_;
  int idxLo_ = 0, idxHi_ = -1;  ///< range of the surface's particle indices
  /// The connectivity below, built on the first normal a query needs (most surfaces, as those of each pass of the
  /// output separation, never need one): thread-safe through `topologyBuilt_`.
  void buildTopology() const;
  mutable std::once_flag topologyBuilt_;
  mutable std::vector<int> vtStart_, vtTri_;  ///< vertex → incident triangles (CSR, vertex i at i − idxLo_)
  mutable std::vector<int> ttStart_, ttTri_;  ///< triangle → the triangles sharing a corner with it, itself too (CSR)
  mutable std::unordered_map<long long, std::pair<int, int>> edgeFaces_;  ///< edge (sorted corner pair) → its two
                                                                          ///< triangles
  TriangleGrid grid_;                                ///< over the triangles at the positions of the last update()
  Eigen::Vector3d boxHi_ = Eigen::Vector3d::Zero();  ///< the upper corner of the grid's box (the lower is its layout's)
  Points built_;                                     ///< the particles [idxLo_, idxHi_] at the last update()
  double meanEdge_ = 0;                              ///< mean length of the triangles' first edges at the last update()
  double travelled_ = 0;                             ///< see travelled()
  mutable std::unique_ptr<WindingNumber> winding_;   ///< of the last update(), built on demand
  mutable std::mutex windingMutex_;
};

}  // namespace msk
