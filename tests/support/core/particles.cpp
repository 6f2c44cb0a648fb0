#include "msk/test/particles.h"

#include <cstring>

namespace msk::test {

LinearMomentum linearMomentum(const Points& before, const Points& after, const Eigen::VectorXd& w) {
  LinearMomentum m;
  for (Eigen::Index i = 0; i < before.rows(); ++i) {
    if (!(w[i] > 0)) continue;
    const Eigen::Vector3d d = (after.row(i) - before.row(i)).transpose() / w[i];
    m.sum += d;
    m.scale += d.norm();
  }
  return m;
}

bool bitwiseEqual(const Points& a, const Points& b) {
  return a.rows() == b.rows() && std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

}  // namespace msk::test
