#include "msk/core/constraint_row.h"

#include <gtest/gtest.h>

#include <random>

#include "msk/core/medial_axis.h"
#include "msk/core/triangle_mesh.h"
#include "msk/core/volume_simplex.h"

namespace {

using msk::Points;

/// The correction one row gives alone (PBD, Δλ = −γ C / W), as a full #V×3 displacement.
Points rowCorrection(const msk::ConstraintRow& r, const Eigen::VectorXd& w, int n) {
  Points d = Points::Zero(n, 3);
  double W = 0;
  for (int j = 0; j < r.count; ++j) W += r.grad[j] * r.react[j] * w[r.index[j]];
  const Eigen::Vector3d dl = (-r.gamma / W) * r.c;
  for (int j = 0; j < r.count; ++j) d.row(r.index[j]) += (w[r.index[j]] * r.react[j] * dl).transpose();
  return d;
}

}  // namespace

// The rows of the radial and 3-simplex sets reproduce their kernels (radialCorrection, volumeSimplexCorrection).
TEST(ConstraintRows, RadialAndVolumeRowsReproduceTheirKernels) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> mass(0.3, 3.0), jitter(-0.5, 0.5);
  // Radial: an icosphere around a 5-vertex axis, squeezed and jittered; axis particles after the surface.
  const msk::TriangleMesh sphere = msk::makeIcosphere(8.0, 2);
  Points axis(5, 3);
  for (int j = 0; j < 5; ++j) axis.row(j) << 0, 0, -6.0 + 3.0 * j;
  const msk::RadialAttachment att = msk::attachToAxis(sphere.vertices, axis);
  const int nv = sphere.vertexCount(), n = nv + 5;
  Points p(n, 3);
  p.topRows(nv) = 0.8 * sphere.vertices;
  p.bottomRows(5) = axis;
  for (int i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) p(i, d) += jitter(rng);
  Eigen::VectorXd w(n);
  for (int i = 0; i < n; ++i) w[i] = 1.0 / mass(rng);
  msk::RadialConstraints radial(att, nv, 0.7);
  ASSERT_EQ(radial.rowCount(), nv);
  for (int r = 0; r < nv; ++r) {
    msk::ConstraintRow row;
    ASSERT_TRUE(radial.row(r, p, w, row));
    const Points d = rowCorrection(row, w, n);
    const int a = nv + att.axisIndex(r, 0), b = nv + att.axisIndex(r, 1);
    const Eigen::Vector3d q[2] = {p.row(a).transpose(), p.row(b).transpose()};
    const double c[2] = {att.weights(r, 0), att.weights(r, 1)}, wq[2] = {w[a], w[b]};
    Eigen::Vector3d dp, dq[2];
    ASSERT_TRUE(msk::radialCorrection(p.row(r).transpose(), q, c, att.radius[r], w[r], wq, 0.7, dp, dq));
    Points k = Points::Zero(n, 3);
    k.row(r) += dp.transpose();
    k.row(a) += dq[0].transpose();
    k.row(b) += dq[1].transpose();
    EXPECT_LT((d - k).cwiseAbs().maxCoeff(), 1e-12) << "radial row " << r;
  }
  // 3-simplex: a jittered 2×2×2 cube model, ghosts constrained too.
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(msk::makeCubeTets(2, 5.0));
  const int nvol = vm.vertexCount();
  Points pv = vm.simplex.positions;
  for (int i = 0; i < nvol; ++i)
    for (int d = 0; d < 3; ++d) pv(i, d) += jitter(rng);
  Eigen::VectorXd wv(nvol);
  for (int i = 0; i < nvol; ++i) wv[i] = 1.0 / mass(rng);
  msk::VolumeSimplexConstraints vol(vm, 0.6, msk::VolumeBoundary::Constrained);
  int checked = 0;
  for (int r = 0; r < vol.rowCount(); ++r) {
    msk::ConstraintRow row;
    if (!vol.row(r, pv, wv, row)) continue;
    ++checked;
    const Points d = rowCorrection(row, wv, nvol);
    const int v = row.index[0];  // the row's vertex
    Eigen::Vector3d pi[4], dp, dpi[4];
    double wi[4], eps[4];
    for (int i = 0; i < 4; ++i) {
      pi[i] = pv.row(vm.simplex.neighbors(v, i)).transpose();
      wi[i] = wv[vm.simplex.neighbors(v, i)];
      eps[i] = vm.epsilon(v, i);
    }
    ASSERT_TRUE(msk::volumeSimplexCorrection(pv.row(v).transpose(), pi, wv[v], wi, eps, 0.6, dp, dpi));
    Points k = Points::Zero(nvol, 3);
    k.row(v) += dp.transpose();
    for (int i = 0; i < 4; ++i) k.row(vm.simplex.neighbors(v, i)) += dpi[i].transpose();
    EXPECT_LT((d - k).cwiseAbs().maxCoeff(), 1e-12) << "volume row " << r;
  }
  EXPECT_GT(checked, nvol / 2);
}
