#include "msk/segmentation/overlap_repair.h"

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <string>

#include "msk/core/collision_surface.h"
#include "msk/core/error.h"
#include "msk/imaging/rasterize.h"

namespace msk {

std::vector<size_t> insideVoxels(const TriangleMesh& surface, const Grid& grid) {
  return insideVoxelIndices(surface, grid);
}

OverlapRepairReport repairOverlapVoxels(const std::vector<TriangleMesh*>& surfaces,
                                        const std::vector<std::pair<int, int>>& pairs, const Grid& grid,
                                        double marginMm, std::vector<std::vector<size_t>>& inside, int maxRounds) {
  if (!(std::isfinite(marginMm) && marginMm >= 0))
    throw ParameterError("overlap repair margin", std::to_string(marginMm), "must be finite and ≥ 0 mm");
  if (maxRounds < 0) throw ParameterError("overlap repair rounds", std::to_string(maxRounds), "must be ≥ 0");
  if (inside.size() != surfaces.size())
    throw ParameterError("inside lists", std::to_string(inside.size()), "must be one per surface");
  const int n = static_cast<int>(surfaces.size());
  for (const auto& [a, b] : pairs)
    if (a < 0 || b < 0 || a >= n || b >= n || a == b)
      throw ParameterError("overlap repair pair", std::to_string(a) + "," + std::to_string(b), "index out of range");
  for (const std::vector<size_t>& list : inside)
    if (!list.empty() && list.back() >= grid.voxelCount())
      throw ParameterError("inside voxel", std::to_string(list.back()), "is not a voxel of the grid");

  OverlapRepairReport report;
  const double reach = 4.0 * grid.spacing.maxCoeff() + marginMm;
  const Eigen::Index nx = grid.dims[0], ny = grid.dims[1];
  auto sharedCentres = [&] {
    std::vector<std::pair<size_t, size_t>> shared;  // (voxel, pair index): sorted lists intersected pair by pair
    for (size_t k = 0; k < pairs.size(); ++k) {
      const std::vector<size_t>& a = inside[static_cast<size_t>(pairs[k].first)];
      const std::vector<size_t>& b = inside[static_cast<size_t>(pairs[k].second)];
      for (size_t i = 0, j = 0; i < a.size() && j < b.size();) {
        if (a[i] < b[j]) {
          ++i;
        } else if (b[j] < a[i]) {
          ++j;
        } else {
          shared.emplace_back(a[i], k);
          ++i, ++j;
        }
      }
    }
    return shared;
  };
  std::vector<std::pair<size_t, size_t>> shared = sharedCentres();
  for (int round = 0; round < maxRounds && !shared.empty(); ++round) {
    ++report.rounds;
    // Closest-point queries at the positions the round starts from; every move is decided before any is applied.
    std::vector<std::unique_ptr<CollisionSurface>> query(surfaces.size());
    std::vector<Points> shift(surfaces.size());
    for (const auto& [voxel, k] : shared) {
      const Eigen::Index v = static_cast<Eigen::Index>(voxel);
      const Eigen::Vector3d c =
          grid.toWorld(Eigen::Vector3d(double(v % nx), double((v / nx) % ny), double(v / (nx * ny))));
      SurfacePoint best;
      int owner = -1;
      for (int o : {pairs[k].first, pairs[k].second}) {
        const TriangleMesh& m = *surfaces[static_cast<size_t>(o)];
        auto& q = query[static_cast<size_t>(o)];
        if (!q) {
          q = std::make_unique<CollisionSurface>(m.faces, reach);
          q->update(m.vertices);
        }
        const SurfacePoint sp = q->closest(m.vertices, c, reach);
        if (sp.triangle >= 0 && (owner < 0 || sp.distance < best.distance)) best = sp, owner = o;
      }
      if (owner < 0) continue;
      const TriangleMesh& m = *surfaces[static_cast<size_t>(owner)];
      const Eigen::Vector3i f = m.faces.row(best.triangle).transpose();
      const Eigen::Vector3d normal = (m.vertices.row(f[1]) - m.vertices.row(f[0]))
                                         .transpose()
                                         .cross((m.vertices.row(f[2]) - m.vertices.row(f[0])).transpose());
      if (!(normal.norm() > 0)) continue;
      const Eigen::RowVector3d move = -(best.distance + marginMm) * normal.normalized().transpose();
      Points& s = shift[static_cast<size_t>(owner)];
      if (s.rows() == 0) s = Points::Zero(m.vertices.rows(), 3);
      for (int corner = 0; corner < 3; ++corner)
        if (move.squaredNorm() > s.row(f[corner]).squaredNorm()) s.row(f[corner]) = move;
      ++report.handedOver;
    }
    for (size_t o = 0; o < surfaces.size(); ++o)
      if (shift[o].rows() > 0) {
        surfaces[o]->vertices += shift[o];
        inside[o] = insideVoxels(*surfaces[o], grid);
      }
    shared = sharedCentres();
  }
  report.remaining = shared.size();
  return report;
}

}  // namespace msk
