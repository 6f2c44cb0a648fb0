#include "msk/core/winding_number.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <string>
#include <tuple>

#include "msk/core/error.h"

namespace msk {

namespace {
constexpr double kFourPi = 4.0 * 3.14159265358979323846;
}

double triangleWindingNumber(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c) {
  const Eigen::Vector3d x = a - q, y = b - q, z = c - q;
  const double lx = x.norm(), ly = y.norm(), lz = z.norm();
  const double num = x.dot(y.cross(z));
  const double den = lx * ly * lz + x.dot(y) * lz + y.dot(z) * lx + z.dot(x) * ly;
  return 2.0 * std::atan2(num, den) / kFourPi;
}

namespace {
using CellKey = std::tuple<long, long, long>;
CellKey cellKey(const Eigen::Vector3d& c, double size) {
  return {std::lround(std::floor(c.x() / size)), std::lround(std::floor(c.y() / size)),
          std::lround(std::floor(c.z() / size))};
}
}  // namespace

WindingNumber::WindingNumber(const Points& vertices, const Triangles& faces, double clusterMm, double farFactor)
    : f_(faces), given_(faces), givenRows_(static_cast<int>(vertices.rows())), far_(farFactor) {
  if (!(farFactor >= 1) || !std::isfinite(farFactor))
    throw ParameterError("winding far factor", std::to_string(farFactor), "must be >= 1");
  const int nf = static_cast<int>(f_.rows());
  if (nf == 0) return;
  // Keep only the vertices the faces use (the faces may index a much larger stacked array).
  {
    std::vector<int> local(static_cast<size_t>(vertices.rows()), -1);
    int used = 0;
    for (int t = 0; t < nf; ++t)
      for (int k = 0; k < 3; ++k) {
        if (faces(t, k) < 0 || faces(t, k) >= vertices.rows()) throw Error("winding number: face index out of range");
        int& l = local[static_cast<size_t>(faces(t, k))];
        if (l < 0) l = used++;
        f_(t, k) = l;
      }
    v_.resize(used, 3);
    for (size_t i = 0; i < local.size(); ++i)
      if (local[i] >= 0) v_.row(local[i]) = vertices.row(static_cast<Eigen::Index>(i));
  }
  if (!(clusterMm > 0)) {
    double sum = 0;
    for (int t = 0; t < nf; ++t) sum += (v_.row(f_(t, 0)) - v_.row(f_(t, 1))).norm();
    clusterMm = 2.0 * sum / nf;
  }
  if (!(clusterMm > 0)) clusterMm = 1.0;
  // Triangles by the fine cell of their centroid, fine cells by the coarse cell (4× larger) they fall in; the map
  // order keeps each coarse group's fine cells contiguous.
  std::map<std::pair<CellKey, CellKey>, std::vector<int>> cells;
  for (int t = 0; t < nf; ++t) {
    const Eigen::Vector3d c = (v_.row(f_(t, 0)) + v_.row(f_(t, 1)) + v_.row(f_(t, 2))).transpose() / 3.0;
    cells[{cellKey(c, 4.0 * clusterMm), cellKey(c, clusterMm)}].push_back(t);
  }
  order_.reserve(static_cast<size_t>(nf));
  const CellKey none{0, 0, 0};
  CellKey current = none;
  bool open = false;
  auto closeGroup = [&]() {
    if (!open) return;
    Cluster& g = groups_.back();
    g.end = static_cast<int>(clusters_.size());
    double area = 0;
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
    for (int c = g.begin; c < g.end; ++c) {
      g.dipole += clusters_[static_cast<size_t>(c)].dipole;
      const double a = clusters_[static_cast<size_t>(c)].dipole.norm() + 1e-300;
      weighted += a * clusters_[static_cast<size_t>(c)].centre;
      area += a;
    }
    g.centre = weighted / area;
    for (int c = g.begin; c < g.end; ++c) {
      const Cluster& cl = clusters_[static_cast<size_t>(c)];
      g.radius = std::max(g.radius, (cl.centre - g.centre).norm() + cl.radius);
    }
  };
  for (const auto& kv : cells) {
    if (!open || kv.first.first != current) {
      closeGroup();
      groups_.emplace_back();
      groups_.back().begin = static_cast<int>(clusters_.size());
      current = kv.first.first;
      open = true;
    }
    Cluster cl;
    cl.begin = static_cast<int>(order_.size());
    double area = 0;
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero(), plain = Eigen::Vector3d::Zero();
    for (int t : kv.second) {
      order_.push_back(t);
      const Eigen::Vector3d a = v_.row(f_(t, 0)), b = v_.row(f_(t, 1)), c = v_.row(f_(t, 2));
      const Eigen::Vector3d an = 0.5 * (b - a).cross(c - a);  // area × unit normal
      const double ar = an.norm();
      cl.dipole += an;
      weighted += ar * (a + b + c) / 3.0;
      plain += (a + b + c) / 3.0;
      area += ar;
    }
    cl.end = static_cast<int>(order_.size());
    cl.centre = area > 0 ? Eigen::Vector3d(weighted / area) : Eigen::Vector3d(plain / kv.second.size());
    for (int t : kv.second)
      for (int k = 0; k < 3; ++k) cl.radius = std::max(cl.radius, (v_.row(f_(t, k)).transpose() - cl.centre).norm());
    clusters_.push_back(cl);
  }
  closeGroup();
}

template <class Corner>
double WindingNumber::sum(const Eigen::Vector3d& q, const Corner& corner) const {
  auto dipole = [&](const Cluster& c, double& w) {
    const Eigen::Vector3d d = c.centre - q;
    const double dist = d.norm();
    if (!(dist > far_ * c.radius && dist > 0)) return false;
    w += c.dipole.dot(d) / (kFourPi * dist * dist * dist);
    return true;
  };
  double w = 0;
  for (const Cluster& g : groups_) {
    if (dipole(g, w)) continue;
    for (int ci = g.begin; ci < g.end; ++ci) {
      const Cluster& cl = clusters_[static_cast<size_t>(ci)];
      if (dipole(cl, w)) continue;
      for (int k = cl.begin; k < cl.end; ++k) {
        const int t = order_[static_cast<size_t>(k)];
        w += triangleWindingNumber(q, corner(t, 0), corner(t, 1), corner(t, 2));
      }
    }
  }
  return w;
}

double WindingNumber::at(const Eigen::Vector3d& q) const {
  return sum(q, [&](int t, int k) -> Eigen::Vector3d { return v_.row(f_(t, k)).transpose(); });
}

double WindingNumber::at(const Eigen::Vector3d& q, const Points& live) const {
  if (live.rows() < givenRows_) throw Error("winding number: the live vertex array has fewer rows than the one given");
  return sum(q, [&](int t, int k) -> Eigen::Vector3d { return live.row(given_(t, k)).transpose(); });
}

double WindingNumber::exactAt(const Eigen::Vector3d& q) const {
  double w = 0;
  for (int t = 0; t < f_.rows(); ++t)
    w += triangleWindingNumber(q, v_.row(f_(t, 0)).transpose(), v_.row(f_(t, 1)).transpose(),
                               v_.row(f_(t, 2)).transpose());
  return w;
}

}  // namespace msk
