// Surface proximity: per surface the distances to its faces (cgal_aabb.h, exact point-to-triangle distances) and its
// winding number for inside tests (msk/core/winding_number.h, the inside test of the collision response).
#include "msk/segmentation/surface_proximity.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "cgal_aabb.h"
#include "msk/core/error.h"
#include "msk/core/winding_number.h"

namespace msk {

namespace {

/// Axis-aligned bounding box of a vertex set, mm.
struct Box {
  Eigen::Vector3d lo, hi;
  explicit Box(const Points& v) : lo(v.colwise().minCoeff().transpose()), hi(v.colwise().maxCoeff().transpose()) {}
  /// True if the boxes, each grown by `margin` on every side, meet (equivalently, one grown by 2·margin).
  bool meets(const Box& o, double margin) const {
    return ((lo.array() - margin <= o.hi.array() + margin) && (o.lo.array() - margin <= hi.array() + margin)).all();
  }
  /// True if `p` lies in the box grown by `margin`.
  bool holds(const Eigen::Vector3d& p, double margin) const {
    return ((p.array() >= lo.array() - margin) && (p.array() <= hi.array() + margin)).all();
  }
};

/// One closed surface prepared for distance and inside queries.
class Surface {
 public:
  explicit Surface(const TriangleMesh& m)
      : vertices_(m.vertices), box_(m.vertices), distance_(m, "surface proximity"), winding_(m.vertices, m.faces) {}
  const Points& vertices() const { return vertices_; }
  const Box& box() const { return box_; }
  /// Distance from `p` to the surface, or 0 if `p` is inside or on it.
  double distanceOrInside(const Eigen::Vector3d& p) const {
    const double d = distance_.distance(p);
    return d == 0 || winding_.inside(p) ? 0.0 : d;
  }

 private:
  Points vertices_;
  Box box_;
  detail::TriangleDistance distance_;
  WindingNumber winding_;
};

/// Smallest distanceOrInside of the vertices of `from` against `to`, over the vertices inside `to`'s box grown by
/// `margin` (infinity if none); stops early at 0.
double oneWay(const Surface& from, const Surface& to, double margin) {
  double best = std::numeric_limits<double>::infinity();
  for (Eigen::Index v = 0; v < from.vertices().rows() && best > 0; ++v) {
    const Eigen::Vector3d p = from.vertices().row(v).transpose();
    if (to.box().holds(p, margin)) best = std::min(best, to.distanceOrInside(p));
  }
  return best;
}

}  // namespace

double surfaceSeparationMm(const TriangleMesh& a, const TriangleMesh& b) {
  const Surface sa(a), sb(b);
  const double inf = std::numeric_limits<double>::infinity();
  const double ab = oneWay(sa, sb, inf);
  return ab == 0 ? 0.0 : std::min(ab, oneWay(sb, sa, inf));
}

std::vector<std::pair<int, int>> surfacesWithin(const std::vector<const TriangleMesh*>& surfaces, double withinMm) {
  if (!(withinMm >= 0) || !std::isfinite(withinMm))
    throw ParameterError("within_mm", std::to_string(withinMm), "must be a finite distance >= 0");
  const int n = static_cast<int>(surfaces.size());
  std::vector<Box> boxes;
  for (const TriangleMesh* m : surfaces) boxes.emplace_back(m->vertices);
  std::vector<std::unique_ptr<Surface>> built(static_cast<size_t>(n));  // prepared on first use only
  auto surface = [&](int i) -> const Surface& {
    auto& s = built[static_cast<size_t>(i)];
    if (!s) s = std::make_unique<Surface>(*surfaces[static_cast<size_t>(i)]);
    return *s;
  };
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      // Boxes apart by more than D: no point of one is within D of the other, and neither holds the other.
      if (!boxes[static_cast<size_t>(i)].meets(boxes[static_cast<size_t>(j)], 0.5 * withinMm)) continue;
      // A vertex outside the partner's box grown by D is farther than D from it and not inside it.
      if (oneWay(surface(i), surface(j), withinMm) <= withinMm || oneWay(surface(j), surface(i), withinMm) <= withinMm)
        pairs.emplace_back(i, j);
    }
  return pairs;
}

}  // namespace msk
