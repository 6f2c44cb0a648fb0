#include "msk/segmentation/surface_fit.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/simplex_mesh.h"
#include "msk/segmentation/surface_quality.h"

namespace msk {

namespace {

/// Each vertex's neighbours along the mesh's edges.
std::vector<std::vector<int>> vertexNeighbours(const TriangleMesh& m) {
  std::vector<std::vector<int>> nb(static_cast<size_t>(m.vertexCount()));
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = m.faces(f, k), b = m.faces(f, (k + 1) % 3);
      nb[static_cast<size_t>(a)].push_back(b);
      nb[static_cast<size_t>(b)].push_back(a);
    }
  for (auto& n : nb) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  return nb;
}

/// `sweeps` Jacobi sweeps of d_v ← (d_v + mean of the neighbours' d) / 2.
void smoothField(Points& d, const std::vector<std::vector<int>>& nb, int sweeps) {
  Points next(d.rows(), 3);
  for (int s = 0; s < sweeps; ++s) {
    for (Eigen::Index v = 0; v < d.rows(); ++v) {
      const auto& n = nb[static_cast<size_t>(v)];
      Eigen::RowVector3d mean = Eigen::RowVector3d::Zero();
      for (int j : n) mean += d.row(j);
      next.row(v) = n.empty() ? Eigen::RowVector3d(d.row(v)) : Eigen::RowVector3d(0.5 * (d.row(v) + mean / n.size()));
    }
    d.swap(next);
  }
}

/// Per vertex: where the fitted surface should go, half from its own closest target point, half from the target
/// vertices whose closest fitted point lies on its triangles (weighted by their barycentric weights). The second
/// half reaches into parts of the target no vertex is closest to (a protrusion the template lacks).
Points pulls(const TriangleMesh& now, const TriangleMesh& target) {
  const SurfaceTransfer toTarget(target, now.vertices);
  Points forward = toTarget.apply(target.vertices) - now.vertices;
  const SurfaceTransfer fromTarget(now, target.vertices);
  const Points onNow = fromTarget.apply(now.vertices);
  Points back = Points::Zero(now.vertices.rows(), 3);
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(now.vertices.rows());
  for (Eigen::Index j = 0; j < target.vertices.rows(); ++j) {
    const Eigen::RowVector3d r = target.vertices.row(j) - onNow.row(j);
    for (int k = 0; k < 3; ++k) {
      const int v = fromTarget.corners()(j, k);
      const double w = fromTarget.weights()(j, k);
      back.row(v) += w * r;
      weight[v] += w;
    }
  }
  for (Eigen::Index v = 0; v < forward.rows(); ++v)
    if (weight[v] > 1e-6) forward.row(v) = 0.5 * (forward.row(v) + back.row(v) / weight[v]);
  return forward;
}

double meanOf(const Eigen::VectorXd& x) { return x.size() > 0 ? x.mean() : 0.0; }

}  // namespace

TriangleMesh fitSurface(const TriangleMesh& moving, const TriangleMesh& target, const SurfaceFitOptions& opts,
                        SurfaceFitReport* report) {
  if (const std::string p = closedMeshProblem(moving); !p.empty()) throw Error("surface fit: the template " + p);
  if (const std::string p = closedMeshProblem(target); !p.empty()) throw Error("surface fit: the target " + p);
  TriangleMesh now = moving;
  now.pointData.clear();
  SurfaceFitReport rep;

  // Similarity by symmetric closest points: fitted points paired with their closest target points, and target
  // vertices with their closest fitted points (a surface inside a larger one would otherwise only shrink onto it).
  for (int it = 0; it < opts.similarityIterations; ++it) {
    const SurfaceTransfer toTarget(target, now.vertices);
    const SurfaceTransfer fromTarget(now, target.vertices);
    const Eigen::Index n = now.vertices.rows(), m = target.vertices.rows();
    Eigen::Matrix3Xd src(3, n + m), dst(3, n + m);
    src.leftCols(n) = now.vertices.transpose();
    dst.leftCols(n) = toTarget.apply(target.vertices).transpose();
    src.rightCols(m) = fromTarget.apply(now.vertices).transpose();
    dst.rightCols(m) = target.vertices.transpose();
    const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
    transformMesh(now, t);
    rep.scale *= std::cbrt(t.topLeftCorner<3, 3>().determinant());
    if ((t - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff() < 1e-6) break;
  }

  const auto nb = vertexNeighbours(now);
  const int steps = std::max(0, opts.iterations);
  for (int it = 0; it < steps; ++it) {
    // Stiffness falls geometrically from the first to the last smoothing.
    const double f = steps > 1 ? static_cast<double>(it) / (steps - 1) : 1.0;
    const int sweeps = static_cast<int>(std::lround(
        std::max(1, opts.smoothingFirst) *
        std::pow(std::max(1, opts.smoothingLast) / static_cast<double>(std::max(1, opts.smoothingFirst)), f)));
    Points d = pulls(now, target);
    smoothField(d, nb, sweeps);
    now.vertices += d;
    // Tangential relaxation: each vertex toward its neighbours' mean within its tangent plane (the triangles keep
    // their shape; the surface does not move along its normal).
    const Points normals = vertexNormals(now);
    Points moved = now.vertices;
    for (Eigen::Index v = 0; v < now.vertices.rows(); ++v) {
      const auto& n = nb[static_cast<size_t>(v)];
      if (n.empty()) continue;
      Eigen::RowVector3d mean = Eigen::RowVector3d::Zero();
      for (int j : n) mean += now.vertices.row(j);
      Eigen::RowVector3d l = mean / n.size() - now.vertices.row(v);
      const Eigen::RowVector3d nv = normals.row(v);
      l -= l.dot(nv) * nv;
      moved.row(v) += 0.5 * l;
    }
    now.vertices = moved;
  }

  const SurfaceTransfer toTarget(target, now.vertices);
  rep.meanDistanceMm = meanOf(toTarget.distances());
  rep.maxDistanceMm = toTarget.distances().size() > 0 ? toTarget.distances().maxCoeff() : 0.0;
  rep.meanReverseDistanceMm = meanOf(SurfaceTransfer(now, target.vertices).distances());
  const double vt = enclosedVolume(target);
  rep.volumeRatio = vt != 0 ? enclosedVolume(now) / vt : 0.0;
  rep.selfIntersections = selfIntersections(now);
  if (report) *report = rep;
  return now;
}

}  // namespace msk
