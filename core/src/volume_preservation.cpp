#include "msk/core/volume_preservation.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/triangle_mesh.h"

namespace msk {

VolumePreservation::VolumePreservation(const SimplexMesh& surface, const VolumePreservationOptions& options)
    : opt_(options) {
  checkUnitInterval("volume preservation stiffness", opt_.stiffness);
  checkUnitInterval("volume preservation tolerance", opt_.tolerance);
  if (opt_.maxObserveProjections < 0)
    throw ParameterError("volume preservation observed projections", std::to_string(opt_.maxObserveProjections),
                         "must be ≥ 0");
  if (!(opt_.settleRate >= 0) || !std::isfinite(opt_.settleRate))
    throw ParameterError("volume preservation settle rate", std::to_string(opt_.settleRate), "must be ≥ 0");
  MSK_ASSERT(surface.k == 2 && surface.faceCount() > 0, "volume preservation needs a 2-simplex surface with faces");
  const int ns = surface.vertexCount(), nf = surface.faceCount();
  triangles_ = trianglesFromSimplex(surface).faces;  // row t: the triangle of simplex vertex t
  // The same recovery as trianglesFromSimplex(): μ relative to the mean diagonal of CᵀC.
  mu_ = 1e-3 * (static_cast<double>(ns) / 3.0) / static_cast<double>(nf);
  std::vector<Eigen::Triplet<double>> tc, tf;
  for (int t = 0; t < ns; ++t)
    for (int i = 0; i < 3; ++i) tc.emplace_back(t, triangles_(t, i), 1.0 / 3.0);
  for (int f = 0; f < nf; ++f) {
    const int b0 = surface.faceOffsets[static_cast<size_t>(f)], b1 = surface.faceOffsets[static_cast<size_t>(f) + 1];
    for (int i = b0; i < b1; ++i) tf.emplace_back(f, surface.faceVertices[static_cast<size_t>(i)], 1.0 / (b1 - b0));
  }
  c_.resize(ns, nf);
  c_.setFromTriplets(tc.begin(), tc.end());
  f_.resize(nf, ns);
  f_.setFromTriplets(tf.begin(), tf.end());
  Eigen::SparseMatrix<double> a = c_.transpose() * c_;
  for (int f = 0; f < nf; ++f) a.coeffRef(f, f) += mu_;
  ldlt_.compute(a);
  MSK_ASSERT(ldlt_.info() == Eigen::Success, "volume preservation: factorisation failed");
  reference_ = volume(surface.positions);
  if (!(reference_ > 0) || !std::isfinite(reference_))
    throw Error("volume preservation: the surface encloses no volume (" + std::to_string(reference_) + " mm³)");
  if (opt_.maxObserveProjections == 0) decision_ = VolumeDecision::Holding;
}

Points VolumePreservation::recover(const Points& p) const {
  const Eigen::MatrixXd rhs = c_.transpose() * Eigen::MatrixXd(p) + mu_ * (f_ * Eigen::MatrixXd(p));
  return ldlt_.solve(rhs);
}

double VolumePreservation::volume(const Points& p) const {
  const Points t = recover(p);
  double v = 0;
  for (Eigen::Index k = 0; k < triangles_.rows(); ++k) {
    const Eigen::Vector3d a = t.row(triangles_(k, 0)), b = t.row(triangles_(k, 1)), c = t.row(triangles_(k, 2));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

Points VolumePreservation::volumeGradient(const Points& p) const {
  const Points t = recover(p);
  Eigen::MatrixXd gt = Eigen::MatrixXd::Zero(t.rows(), 3);  // ∂V/∂T: a·(b×c)/6 → (b×c, c×a, a×b)/6
  for (Eigen::Index k = 0; k < triangles_.rows(); ++k) {
    const Eigen::Vector3d a = t.row(triangles_(k, 0)), b = t.row(triangles_(k, 1)), c = t.row(triangles_(k, 2));
    gt.row(triangles_(k, 0)) += b.cross(c).transpose() / 6.0;
    gt.row(triangles_(k, 1)) += c.cross(a).transpose() / 6.0;
    gt.row(triangles_(k, 2)) += a.cross(b).transpose() / 6.0;
  }
  const Eigen::MatrixXd y = ldlt_.solve(gt);  // A symmetric: ∇_P V = (C + μFᵀ) A⁻¹ ∇_T V
  return c_ * y + mu_ * (f_.transpose() * y);
}

void VolumePreservation::project(Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(c_.rows());
  MSK_ASSERT(pAll.rows() >= first_ + n && wAll.size() == pAll.rows(), "volume preservation: size mismatch");
  const Points p = pAll.middleRows(first_, n);
  lastVolume_ = volume(p);
  if (decision_ == VolumeDecision::Observing) {
    const bool settled = seen_ >= std::max(1, opt_.minObserveProjections) &&
                         std::fabs(lastVolume_ - previous_) < opt_.settleRate * reference_;
    previous_ = lastVolume_;
    if (settled || ++seen_ >= opt_.maxObserveProjections)
      decision_ = std::fabs(lastVolume_ / reference_ - 1.0) <= opt_.tolerance ? VolumeDecision::Holding
                                                                              : VolumeDecision::Following;
  }
  if (decision_ != VolumeDecision::Holding || opt_.stiffness == 0) return;
  const Points g = volumeGradient(p);
  const auto w = wAll.segment(first_, n);
  const double denom = (g.rowwise().squaredNorm().array() * w.array()).sum();
  if (!(denom > 0) || !std::isfinite(denom) || !std::isfinite(lastVolume_)) return;
  const double lambda = -opt_.stiffness * (lastVolume_ - reference_) / denom;
  for (int i = 0; i < n; ++i) pAll.row(first_ + i) += (lambda * w[i]) * g.row(i);
}

}  // namespace msk
