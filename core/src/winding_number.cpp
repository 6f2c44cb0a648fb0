#include "msk/core/winding_number.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <utility>

#include "msk/core/error.h"

namespace msk {

namespace {
constexpr double kFourPi = 4.0 * 3.14159265358979323846;

/// The solid angle of triangle (a, b, c) seen from q as 2·atan2(num, den) (Van Oosterom and Strackee 1983): den + i·num
/// is the complex number whose argument is half that angle.
struct HalfSolidAngle {
  double num, den;
};
HalfSolidAngle halfSolidAngle(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                              const Eigen::Vector3d& c) {
  const Eigen::Vector3d x = a - q, y = b - q, z = c - q;
  const double lx = x.norm(), ly = y.norm(), lz = z.norm();
  return {x.dot(y.cross(z)), lx * ly * lz + x.dot(y) * lz + y.dot(z) * lx + z.dot(x) * ly};
}
}  // namespace

double triangleWindingNumber(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c) {
  const HalfSolidAngle h = halfSolidAngle(q, a, b, c);
  return 2.0 * std::atan2(h.num, h.den) / kFourPi;
}

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
  // An octree of cubic cells: leaves of size clusterMm, each level's cells twice the size of the one below, from the
  // surface's lowest corner. The triangles sorted by the Morton code of their centroid's leaf cell (its bits
  // interleaved from the top), so that the triangles of every node and the children of every node are contiguous.
  // (Cells four times larger per level take about 15 % more time per query.)
  const Eigen::Vector3d lo = v_.colwise().minCoeff().transpose();
  constexpr int kBits = 21;  // per axis: 63 bits of code
  std::vector<uint64_t> code(static_cast<size_t>(nf));
  for (int t = 0; t < nf; ++t) {
    const Eigen::Vector3d c = (v_.row(f_(t, 0)) + v_.row(f_(t, 1)) + v_.row(f_(t, 2))).transpose() / 3.0;
    uint64_t m = 0;
    for (int a = 0; a < 3; ++a) {
      const double u = std::floor((c[a] - lo[a]) / clusterMm);
      const uint64_t i = !(u > 0) ? 0 : u >= (1 << kBits) - 1 ? (1u << kBits) - 1 : static_cast<uint64_t>(u);
      for (int bit = 0; bit < kBits; ++bit) m |= ((i >> bit) & 1u) << (3 * bit + a);
    }
    code[static_cast<size_t>(t)] = m;
  }
  order_.resize(static_cast<size_t>(nf));
  std::iota(order_.begin(), order_.end(), 0);
  std::stable_sort(order_.begin(), order_.end(),
                   [&](int x, int y) { return code[static_cast<size_t>(x)] < code[static_cast<size_t>(y)]; });
  auto codeAt = [&](int k) { return code[static_cast<size_t>(order_[static_cast<size_t>(k)])]; };
  // Leaves: runs of triangles with the same finest cell.
  std::vector<int> level;    // the nodes of the level being built (indices into nodes_)
  std::vector<int> firstOf;  // each node's first triangle (a position in order_)
  for (int k = 0; k < nf;) {
    int e = k + 1;
    while (e < nf && codeAt(e) == codeAt(k)) ++e;
    Node n;
    n.begin = k;
    n.end = e;
    n.leaf = true;
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero(), plain = Eigen::Vector3d::Zero();
    for (int i = k; i < e; ++i) {
      const int t = order_[static_cast<size_t>(i)];
      const Eigen::Vector3d a = v_.row(f_(t, 0)), b = v_.row(f_(t, 1)), c = v_.row(f_(t, 2));
      const Eigen::Vector3d an = 0.5 * (b - a).cross(c - a);  // area × unit normal
      const double ar = an.norm();
      n.dipole += an;
      weighted += ar * (a + b + c) / 3.0;
      plain += (a + b + c) / 3.0;
      n.area += ar;
    }
    n.centre = n.area > 0 ? Eigen::Vector3d(weighted / n.area) : Eigen::Vector3d(plain / (e - k));
    for (int i = k; i < e; ++i)
      for (int j = 0; j < 3; ++j)
        n.radius = std::max(n.radius, (v_.row(f_(order_[static_cast<size_t>(i)], j)).transpose() - n.centre).norm());
    level.push_back(static_cast<int>(nodes_.size()));
    nodes_.push_back(n);
    firstOf.push_back(k);
    k = e;
  }
  // Each coarser level: runs of the finer level's nodes whose first triangles share the cell at that level.
  for (int l = 1; level.size() > 1 && l <= kBits; ++l) {
    auto sameCell = [&](int x, int y) {
      return (codeAt(firstOf[static_cast<size_t>(x)]) >> (3 * l)) ==
             (codeAt(firstOf[static_cast<size_t>(y)]) >> (3 * l));
    };
    std::vector<std::pair<size_t, size_t>> runs;
    for (size_t k = 0; k < level.size();) {
      size_t e = k + 1;
      while (e < level.size() && sameCell(level[k], level[e])) ++e;
      runs.emplace_back(k, e);
      k = e;
    }
    if (runs.size() == level.size()) continue;  // nothing merges at this size: no node that would equal its child
    std::vector<int> next;
    for (const auto& [k, e] : runs) {
      Node n;
      n.begin = level[k];
      n.end = level[e - 1] + 1;  // the finer level's nodes are contiguous in nodes_
      Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
      for (int c = n.begin; c < n.end; ++c) {
        n.dipole += nodes_[static_cast<size_t>(c)].dipole;
        n.area += nodes_[static_cast<size_t>(c)].area;
        weighted += nodes_[static_cast<size_t>(c)].area * nodes_[static_cast<size_t>(c)].centre;
      }
      if (n.area > 0) {
        n.centre = weighted / n.area;
      } else {
        for (int c = n.begin; c < n.end; ++c) n.centre += nodes_[static_cast<size_t>(c)].centre / (n.end - n.begin);
      }
      for (int c = n.begin; c < n.end; ++c)
        n.radius = std::max(n.radius, (nodes_[static_cast<size_t>(c)].centre - n.centre).norm() +
                                          nodes_[static_cast<size_t>(c)].radius);
      next.push_back(static_cast<int>(nodes_.size()));
      nodes_.push_back(n);
      firstOf.push_back(firstOf[static_cast<size_t>(n.begin)]);
    }
    level.swap(next);
  }
  roots_ = level;
}

namespace {
/// The sum of the arguments of complex factors (each in (−π, π]) as one product and a count of its turns: one atan2
/// for the whole sum instead of one per factor. A factor's argument has the sign of its imaginary part (π for a
/// negative real one), so a product that passes the negative real axis is seen by the signs of its imaginary part
/// before and after; the product is rescaled now and then to stay within the range of doubles.
class ArgumentSum {
 public:
  void add(double re, double im) {
    if (re == 0 && im == 0) return;  // atan2(0, 0) = 0
    const double r = re_ * re - im_ * im, i = re_ * im + im_ * re;
    if (im > 0 || (im == 0 && re < 0)) {  // counterclockwise by (0, π]: from the upper half past π
      if (im_ >= 0 && (i < 0 || (i == 0 && r > 0))) ++turns_;
    } else if (im < 0) {  // clockwise by (0, π): from the lower half past −π
      if ((im_ < 0 || (im_ == 0 && re_ > 0)) && (i > 0 || (i == 0 && r < 0))) --turns_;
    }
    re_ = r;
    im_ = i;
    if (++sinceScale_ == 8) {
      sinceScale_ = 0;
      const double m = std::max(std::abs(re_), std::abs(im_));
      if (m > 0 && std::isfinite(m)) {
        int e = 0;
        std::frexp(m, &e);
        re_ = std::ldexp(re_, -e);
        im_ = std::ldexp(im_, -e);
      }
    }
  }
  /// The sum of the factors' arguments.
  double value() const { return std::atan2(im_, re_) + 2.0 * 3.14159265358979323846 * turns_; }

 private:
  double re_ = 1, im_ = 0;
  long turns_ = 0;
  int sinceScale_ = 0;
};
}  // namespace

template <class Corner>
double WindingNumber::sum(const Eigen::Vector3d& q, const Corner& corner) const {
  double w = 0;
  // The near triangles' solid angles, 2·atan2(num, den) each (triangleWindingNumber()), summed as one argument.
  ArgumentSum near;
  // Depth first from the roots: a node seen from farther than far_ times its radius gives its dipole, a nearer leaf
  // its triangles one by one, a nearer inner node its children.
  thread_local std::vector<int> stack;
  stack.assign(roots_.rbegin(), roots_.rend());
  while (!stack.empty()) {
    const Node& n = nodes_[static_cast<size_t>(stack.back())];
    stack.pop_back();
    const Eigen::Vector3d d = n.centre - q;
    const double dist2 = d.squaredNorm(), reach = far_ * n.radius;
    if (dist2 > reach * reach && dist2 > 0) {
      w += n.dipole.dot(d) / (kFourPi * dist2 * std::sqrt(dist2));
      continue;
    }
    if (!n.leaf) {
      for (int c = n.end - 1; c >= n.begin; --c) stack.push_back(c);  // last first: visited in order
      continue;
    }
    for (int k = n.begin; k < n.end; ++k) {
      const int t = order_[static_cast<size_t>(k)];
      const HalfSolidAngle h = halfSolidAngle(q, corner(t, 0), corner(t, 1), corner(t, 2));
      near.add(h.den, h.num);
    }
  }
  return w + 2.0 * near.value() / kFourPi;
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
