#include "msk/core/winding_number.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <string>
#include <tuple>

#include <Eigen/Geometry>

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

WindingNumber::WindingNumber(const Points& vertices, const Triangles& faces, double clusterMm, double farFactor)
    : v_(vertices), f_(faces), far_(farFactor) {
  if (!(farFactor >= 1) || !std::isfinite(farFactor))
    throw ParameterError("winding far factor", std::to_string(farFactor), "must be >= 1");
  const int nf = static_cast<int>(f_.rows());
  if (nf == 0) return;
  if (!(clusterMm > 0)) {
    double sum = 0;
    for (int t = 0; t < nf; ++t) sum += (v_.row(f_(t, 0)) - v_.row(f_(t, 1))).norm();
    clusterMm = 4.0 * sum / nf;
  }
  if (!(clusterMm > 0)) clusterMm = 1.0;
  // Cluster the triangles by the cubic cell of their centroid.
  std::map<std::tuple<long, long, long>, std::vector<int>> cells;
  for (int t = 0; t < nf; ++t) {
    const Eigen::Vector3d c = (v_.row(f_(t, 0)) + v_.row(f_(t, 1)) + v_.row(f_(t, 2))).transpose() / 3.0;
    cells[{std::lround(std::floor(c.x() / clusterMm)), std::lround(std::floor(c.y() / clusterMm)),
           std::lround(std::floor(c.z() / clusterMm))}]
        .push_back(t);
  }
  order_.reserve(static_cast<size_t>(nf));
  for (const auto& kv : cells) {
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
}

double WindingNumber::at(const Eigen::Vector3d& q) const {
  double w = 0;
  for (const Cluster& cl : clusters_) {
    const Eigen::Vector3d d = cl.centre - q;
    const double dist = d.norm();
    if (dist > far_ * cl.radius && dist > 0) {
      w += cl.dipole.dot(d) / (kFourPi * dist * dist * dist);
      continue;
    }
    for (int k = cl.begin; k < cl.end; ++k) {
      const int t = order_[static_cast<size_t>(k)];
      w += triangleWindingNumber(q, v_.row(f_(t, 0)).transpose(), v_.row(f_(t, 1)).transpose(),
                                 v_.row(f_(t, 2)).transpose());
    }
  }
  return w;
}

double WindingNumber::exactAt(const Eigen::Vector3d& q) const {
  double w = 0;
  for (int t = 0; t < f_.rows(); ++t)
    w += triangleWindingNumber(q, v_.row(f_(t, 0)).transpose(), v_.row(f_(t, 1)).transpose(), v_.row(f_(t, 2)).transpose());
  return w;
}

}  // namespace msk
