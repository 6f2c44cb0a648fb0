#include "msk/core/simplex_internal_constraint.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "msk/core/error.h"
#include "msk/core/simplex_batch.h"

namespace msk {

using namespace simplex_internal;

namespace {

/// Circumradius of triangle (a, b, c) and its unit normal (b−a)×(c−a); false if degenerate.
bool triangleFrame(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& radius,
                   Eigen::Vector3d& normal) {
  const Eigen::Vector3d x = (b - a).cross(c - a);
  const double twiceArea = x.norm();
  const double la = (b - c).norm(), lb = (c - a).norm(), lc = (a - b).norm();
  const double scale = std::max({la, lb, lc});
  if (!(twiceArea > kMinFrameRatio * scale * scale) || !std::isfinite(twiceArea)) return false;
  radius = la * lb * lc / (2.0 * twiceArea);
  normal = x / twiceArea;
  return true;
}

/// Reaction weights λ of the shape-memory row for the correction d = P̃ − P; falls back to λ = ε̃ where no torque-free
/// split exists (the tests of simplex_internal). False if degenerate.
bool internalSplit(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& d, double w,
                   const double wi[3], const double eps[3], Eigen::Vector3d& lambda, bool& split) {
  if (!d.allFinite()) return false;
  if (w <= 0 && wi[0] <= 0 && wi[1] <= 0 && wi[2] <= 0) return false;
  const Eigen::Vector3d a1 = pi[0] - p, a2 = pi[1] - p, a3 = pi[2] - p;
  // Cramer's rule without the determinant: λ'i ∝ μi, and λi = μi / Σμ (the determinant cancels), so the normalised
  // weights stay finite as P approaches its neighbours' plane (they tend to εi there).
  const Eigen::Vector3d mu(d.dot(a2.cross(a3)), d.dot(a3.cross(a1)), d.dot(a1.cross(a2)));
  const double sumMu = mu.sum();
  split = false;
  const Eigen::Vector3d epsV(eps[0], eps[1], eps[2]);
  if (std::fabs(sumMu) > kMinSplitShare * mu.cwiseAbs().sum() && std::fabs(sumMu) > 0) {
    lambda = mu / sumMu;
    split = true;
    // The reactions λ are not the constraint gradient ε̃, so sequential projection is not a projection onto the
    // constraint set; far from ε̃ a mode grows over many sweeps. Keep max|λi − ε̃i| ≤ kMaxSplitDeviation by pulling λ
    // toward ε̃ (Σλ = 1 is kept, so linear momentum still is; only the exact split is torque-free).
    const double deviation = (lambda - epsV).cwiseAbs().maxCoeff();
    if (deviation > kMaxSplitDeviation) {
      lambda = epsV + (kMaxSplitDeviation / deviation) * (lambda - epsV);
      split = false;
    }
  } else {
    // d (nearly) parallel to the neighbours' plane: no torque-free split exists; share like the 3-simplex
    // constraint (linear momentum still conserved).
    lambda = epsV;
  }
  // The reduced mass m̄ = 1/(w + Σ ε̃i λi wi) must stay near the plain one 1/(w + Σ ε̃i² wi): a smaller W (negative
  // λ-weighted reactions, terms cancelling when the wi differ by orders of magnitude) or extreme λ makes the linearised
  // step overshoot, and repeated projection diverges.
  const double plain = eps[0] * eps[0] * wi[0] + eps[1] * eps[1] * wi[1] + eps[2] * eps[2] * wi[2];
  const double W = w + eps[0] * lambda[0] * wi[0] + eps[1] * lambda[1] * wi[1] + eps[2] * lambda[2] * wi[2];
  if (!(W >= w + kMinInverseMassShare * plain) || !std::isfinite(W) || lambda.cwiseAbs().maxCoeff() > kMaxReaction) {
    lambda << eps[0], eps[1], eps[2];
    if (!(w + plain > 0)) return false;
    split = false;
  }
  return true;
}

/// The smoothing mode's target (ε̃ = ⅓, h̃ = the neighbourhood mean `hOverR` of the scale-free heights) with the
/// component along the neighbours' normal taken kSmoothingNormalStep of the way. The full step is not consistent:
/// moving P along the normal also moves each neighbour's height, which the mean fed back, and on the alternating mode
/// of the 3-regular mesh (every vertex up by δ, its neighbours down by δ) the full step maps δ to −3δ. A quarter maps
/// that mode to 0, a lone bump δ to ⅔δ, and leaves smooth shapes (target ≈ P) as they are. False if degenerate.
bool smoothingTarget(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], double hOverR, Eigen::Vector3d& target) {
  double r = 0;
  Eigen::Vector3d n;
  if (!triangleFrame(pi[0], pi[1], pi[2], r, n)) return false;
  const Eigen::Vector3d full = (pi[0] + pi[1] + pi[2]) / 3.0 + hOverR * r * n;
  const Eigen::Vector3d d = full - p;
  target = p + d - (1.0 - kSmoothingNormalStep) * d.dot(n) * n;
  return target.allFinite();
}

/// A row over (P, P1, P2, P3) with C = P − P̃ (d = P̃ − P), g = (1, −ε̃), r = (1, −λ).
void fillRow(const Eigen::Vector3d& d, const double eps[3], const Eigen::Vector3d& lambda, double gamma,
             ConstraintRow& row) {
  row.count = 4;
  row.c = -d;
  row.gamma = gamma;
  row.direction = false;
  row.compliant = true;
  row.index[0] = 0;
  row.grad[0] = 1.0;
  row.react[0] = 1.0;
  for (int i = 0; i < 3; ++i) {
    row.index[i + 1] = i + 1;
    row.grad[i + 1] = -eps[i];
    row.react[i + 1] = -lambda[i];
  }
}

}  // namespace

bool simplexShapeTarget(const Eigen::Vector3d pi[3], const double epsRef[3], double hOverR, Eigen::Vector3d& target) {
  double r = 0;
  Eigen::Vector3d n;
  if (!triangleFrame(pi[0], pi[1], pi[2], r, n)) return false;
  target = epsRef[0] * pi[0] + epsRef[1] * pi[1] + epsRef[2] * pi[2] + hOverR * r * n;
  return target.allFinite();
}

bool simplexInternalRow(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target, double w,
                        const double wi[3], const double eps[3], double gamma, ConstraintRow& row, bool* torqueFree) {
  const Eigen::Vector3d d = target - p;
  Eigen::Vector3d lambda;
  bool split = false;
  if (!internalSplit(p, pi, d, w, wi, eps, lambda, split)) return false;
  if (torqueFree) *torqueFree = split;
  fillRow(d, eps, lambda, gamma, row);
  return true;
}

bool simplexInternalCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target,
                               double w, const double wi[3], const double eps[3], double gamma, Eigen::Vector3d& dp,
                               Eigen::Vector3d dpi[3], bool* torqueFree) {
  ConstraintRow row;
  if (!simplexInternalRow(p, pi, target, w, wi, eps, gamma, row, torqueFree)) return false;
  return pbdCorrections(row, w, wi, dp, dpi);
}

void simplexReferenceParameters(const SimplexMesh& reference, Eigen::MatrixX3d& eps, Eigen::VectorXd& hOverR) {
  const NeighborTable& nb = reference.neighbors;
  MSK_ASSERT(reference.k == 2 && nb.cols() == 3 && nb.rows() == reference.vertexCount(), "2-simplex mesh expected");
  const int n = reference.vertexCount();
  eps.resize(n, 3);
  hOverR.resize(n);
  for (int v = 0; v < n; ++v) {
    for (int j = 0; j < 3; ++j) MSK_ASSERT(nb(v, j) >= 0 && nb(v, j) < n, "neighbour index out of range");
    const Eigen::Vector3d pi[3] = {reference.positions.row(nb(v, 0)), reference.positions.row(nb(v, 1)),
                                   reference.positions.row(nb(v, 2))};
    const Eigen::Vector3d p = reference.positions.row(v);
    double r = 0;
    Eigen::Vector3d nrm;
    if (!triangleFrame(pi[0], pi[1], pi[2], r, nrm)) {
      eps.row(v).setConstant(1.0 / 3.0);
      hOverR[v] = 0;
      continue;
    }
    // Barycentric coordinates of P's projection on the neighbours' plane.
    const double h = (p - pi[0]).dot(nrm);
    const Eigen::Vector3d q = p - h * nrm;
    const Eigen::Vector3d e0 = pi[1] - pi[0], e1 = pi[2] - pi[0], f = q - pi[0];
    const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = f.dot(e0), d21 = f.dot(e1);
    const double den = d00 * d11 - d01 * d01;
    const double b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den;
    eps.row(v) << 1.0 - b1 - b2, b1, b2;
    hOverR[v] = h / r;
  }
}

SimplexInternalConstraints::SimplexInternalConstraints(const SimplexMesh& reference, double gamma, InternalMode mode)
    : nb_(reference.neighbors), gamma_(gamma), mode_(mode) {
  checkUnitInterval("internal stiffness", gamma);
  MSK_ASSERT(reference.k == 2 && nb_.cols() == 3, "2-simplex mesh expected");
  simplexReferenceParameters(reference, eps_, hOverR_);
}

SimplexInternalConstraints::~SimplexInternalConstraints() = default;

SimplexInternalBatch* SimplexInternalConstraints::batch() {
  if (mode_ != InternalMode::ShapeMemory) return nullptr;
  if (!batch_) batch_ = std::make_unique<SimplexInternalBatch>(nb_, eps_, hOverR_, gamma_);
  batch_->setFirstParticle(first_);
  return batch_.get();
}

Eigen::VectorXd SimplexInternalConstraints::smoothingHeights(const Eigen::Ref<const Points>& p) const {
  // Current scale-free heights, then their neighbourhood means (one Jacobi pass per row pass).
  const int n = static_cast<int>(nb_.rows());
  Eigen::VectorXd hr(n);
  for (int v = 0; v < n; ++v) {
    Eigen::Vector3d pi[3] = {p.row(nb_(v, 0)), p.row(nb_(v, 1)), p.row(nb_(v, 2))};
    double r = 0;
    Eigen::Vector3d nrm;
    hr[v] = triangleFrame(pi[0], pi[1], pi[2], r, nrm) ? (p.row(v).transpose() - pi[0]).dot(nrm) / r : 0.0;
  }
  Eigen::VectorXd smoothH(n);
  for (int v = 0; v < n; ++v) smoothH[v] = (hr[nb_(v, 0)] + hr[nb_(v, 1)] + hr[nb_(v, 2)]) / 3.0;
  return smoothH;
}

int SimplexInternalConstraints::rowParticles(int r, int index[kMaxRowParticles]) const {
  index[0] = first_ + r;
  for (int i = 0; i < 3; ++i) index[i + 1] = first_ + nb_(r, i);
  return 4;
}

void SimplexInternalConstraints::beginRows(const Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(nb_.rows());
  MSK_ASSERT(pAll.rows() >= first_ + n && wAll.size() == pAll.rows(), "internal constraints: size mismatch");
  if (mode_ == InternalMode::Smoothing) rowHeights_ = smoothingHeights(pAll.middleRows(first_, n));
}

bool SimplexInternalConstraints::row(int r, const Points& pAll, const Eigen::VectorXd& wAll, ConstraintRow& out) const {
  int idx[4];
  rowParticles(r, idx);
  const Eigen::Vector3d p = pAll.row(idx[0]).transpose();
  const Eigen::Vector3d pi[3] = {pAll.row(idx[1]).transpose(), pAll.row(idx[2]).transpose(),
                                 pAll.row(idx[3]).transpose()};
  if (mode_ == InternalMode::Smoothing) {
    // ε̃ = λ = ⅓: the constraint's gradient (linear momentum conserved). Its corrections are mostly tangential, where
    // the torque-free split does not exist.
    const double third[3] = {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
    Eigen::Vector3d target;
    if (!smoothingTarget(p, pi, rowHeights_[r], target)) return false;
    fillRow(target - p, third, Eigen::Vector3d::Constant(1.0 / 3.0), gamma_, out);
  } else {
    const double eps[3] = {eps_(r, 0), eps_(r, 1), eps_(r, 2)};
    const double wi[3] = {wAll[idx[1]], wAll[idx[2]], wAll[idx[3]]};
    Eigen::Vector3d target;
    if (!simplexShapeTarget(pi, eps, hOverR_[r], target) ||
        !simplexInternalRow(p, pi, target, wAll[idx[0]], wi, eps, gamma_, out))
      return false;
  }
  for (int j = 0; j < 4; ++j) out.index[j] = idx[j];
  return true;
}

}  // namespace msk
