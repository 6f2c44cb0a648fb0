#include "msk/core/constraints.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Dense>

#include "msk/core/error.h"
#include "msk/core/winding_number.h"

namespace msk {

namespace {

/// Circumradius of triangle (a, b, c) and its unit normal (b−a)×(c−a); false if degenerate.
bool triangleFrame(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& radius,
                   Eigen::Vector3d& normal) {
  const Eigen::Vector3d x = (b - a).cross(c - a);
  const double twiceArea = x.norm();
  const double la = (b - c).norm(), lb = (c - a).norm(), lc = (a - b).norm();
  const double scale = std::max({la, lb, lc});
  if (!(twiceArea > 1e-12 * scale * scale) || !std::isfinite(twiceArea)) return false;
  radius = la * lb * lc / (2.0 * twiceArea);
  normal = x / twiceArea;
  return true;
}
}  // namespace

std::uint64_t ConstraintSet::newUid() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1);
}

namespace {
/// simplexShapeTarget(), inline so that the sweeps keep the neighbours in registers (no stack round trip).
inline bool shapeTarget(const Eigen::Vector3d pi[3], const double epsRef[3], double hOverR, Eigen::Vector3d& target) {
  double r = 0;
  Eigen::Vector3d n;
  if (!triangleFrame(pi[0], pi[1], pi[2], r, n)) return false;
  target = epsRef[0] * pi[0] + epsRef[1] * pi[1] + epsRef[2] * pi[2] + hOverR * r * n;
  return target.allFinite();
}
}  // namespace

bool simplexShapeTarget(const Eigen::Vector3d pi[3], const double epsRef[3], double hOverR, Eigen::Vector3d& target) {
  return shapeTarget(pi, epsRef, hOverR, target);
}

namespace {
/// Reaction weights λ of the 2-simplex internal constraint (method 2) for the correction d = P̃ − P and the
/// denominator 1/m̄ = w + Σ ε̃i λi wi; falls back to λ = ε̃ where no torque-free split exists. False if degenerate.
inline bool internalSplit(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& d, double w,
                          const double wi[3], const double eps[3], Eigen::Vector3d& lambda, double& denom, bool& split) {
  if (!d.allFinite()) return false;
  if (w <= 0 && wi[0] <= 0 && wi[1] <= 0 && wi[2] <= 0) return false;
  const Eigen::Vector3d a1 = pi[0] - p, a2 = pi[1] - p, a3 = pi[2] - p;
  // Cramer's rule without the determinant: λ'i ∝ μi, and λi = μi / Σμ (the determinant cancels), so the
  // normalised weights stay finite as P approaches its neighbours' plane (they tend to εi there).
  const Eigen::Vector3d mu(d.dot(a2.cross(a3)), d.dot(a3.cross(a1)), d.dot(a1.cross(a2)));
  const double sumMu = mu.sum();
  split = false;
  const Eigen::Vector3d epsV(eps[0], eps[1], eps[2]);
  if (std::fabs(sumMu) > 0.05 * mu.cwiseAbs().sum() && std::fabs(sumMu) > 0) {
    lambda = mu / sumMu;
    split = true;
    // The reactions λ are not the constraint gradient ε̃, so sequential projection is not a projection onto the
    // constraint set; far from ε̃ a mode grows over many sweeps (a resting sphere drifted and then diverged,
    // tests/core/extremes_test.cpp). Keep max|λi − ε̃i| ≤ 0.75 by pulling λ toward ε̃ (Σλ = 1 is kept, so linear
    // momentum still is; only the exact split is torque-free).
    const double deviation = (lambda - epsV).cwiseAbs().maxCoeff();
    if (deviation > 0.75) {
      lambda = epsV + (0.75 / deviation) * (lambda - epsV);
      split = false;
    }
  } else {
    // d (nearly) parallel to the neighbours' plane: no torque-free split exists; share like the 3-simplex
    // constraint (linear momentum still conserved).
    lambda = epsV;
  }
  // The reduced mass m̄ = 1/(w + Σ ε̃i λi wi) must stay near the plain one 1/(w + Σ ε̃i² wi): a denominator below
  // w + ½ Σ ε̃i² wi (negative λ-weighted reactions, terms cancelling when the wi differ by orders of magnitude) or
  // extreme λ makes the linearised step overshoot, and repeated projection diverges.
  const double plain = eps[0] * eps[0] * wi[0] + eps[1] * eps[1] * wi[1] + eps[2] * eps[2] * wi[2];
  denom = w + eps[0] * lambda[0] * wi[0] + eps[1] * lambda[1] * wi[1] + eps[2] * lambda[2] * wi[2];
  if (!(denom >= w + 0.5 * plain) || !std::isfinite(denom) || lambda.cwiseAbs().maxCoeff() > 3.0) {
    lambda << eps[0], eps[1], eps[2];
    denom = w + eps[0] * eps[0] * wi[0] + eps[1] * eps[1] * wi[1] + eps[2] * eps[2] * wi[2];
    if (!(denom > 0)) return false;
    split = false;
  }
  return true;
}

/// The smoothing mode's target (ε̃ = ⅓, h̃ = the neighbourhood mean `hOverR` of the scale-free heights) with the
/// component along the neighbours' normal taken a quarter of the way. The full step is not consistent: moving P along
/// the normal also moves each neighbour's height, which the mean fed back, and on the alternating mode of the
/// 3-regular mesh (every vertex up by δ, its neighbours down by δ) the full step maps δ to −3δ, a growth by 3 per
/// sweep (a resting 10 mm sphere reached 83 mm in 30 sweeps). A quarter (1 / (1 + 3 neighbours)) maps that mode to
/// 0, a lone bump δ to ⅔δ, and leaves smooth shapes (target ≈ P) as they are. False if the neighbours are degenerate.
inline bool smoothingTarget(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], double hOverR,
                            Eigen::Vector3d& target) {
  double r = 0;
  Eigen::Vector3d n;
  if (!triangleFrame(pi[0], pi[1], pi[2], r, n)) return false;
  const Eigen::Vector3d full = (pi[0] + pi[1] + pi[2]) / 3.0 + hOverR * r * n;
  const Eigen::Vector3d d = full - p;
  target = p + d - 0.75 * d.dot(n) * n;
  return target.allFinite();
}

/// The smoothing mode's split: the reactions are ε̃ = ⅓ (the constraint's gradient; linear momentum conserved). Its
/// corrections are mostly tangential, where method 2's torque-free split does not exist (Σλ' → 0) and its clamped
/// stand-in drove a resting sphere outward over sweeps (10 → 15 mm in 2000 at γ = 0.3).
inline bool smoothingSplit(double w, const double wi[3], Eigen::Vector3d& lambda, double& denom) {
  lambda.setConstant(1.0 / 3.0);
  denom = w + (wi[0] + wi[1] + wi[2]) / 9.0;
  return denom > 0 && std::isfinite(denom);
}

/// The corrections of a split (reactions `lambda`, denominator 1/m̄ = `denom`) for the correction d = P̃ − P.
inline void applySplit(const Eigen::Vector3d& d, double w, const double wi[3], const Eigen::Vector3d& lambda,
                       double denom, double gamma, Eigen::Vector3d& dp, Eigen::Vector3d dpi[3]) {
  const double mbar = gamma / denom;
  dp = (w * mbar) * d;
  for (int i = 0; i < 3; ++i) dpi[i] = (-wi[i] * lambda[i] * mbar) * d;
}

/// simplexInternalCorrection(), inline for the sweeps (as shapeTarget()).
inline bool internalCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target,
                               double w, const double wi[3], const double eps[3], double gamma, Eigen::Vector3d& dp,
                               Eigen::Vector3d dpi[3], bool* torqueFree) {
  const Eigen::Vector3d d = target - p;
  Eigen::Vector3d lambda;
  double denom = 0;
  bool split = false;
  if (!internalSplit(p, pi, d, w, wi, eps, lambda, denom, split)) return false;
  if (torqueFree) *torqueFree = split;
  applySplit(d, w, wi, lambda, denom, gamma, dp, dpi);
  return true;
}
}  // namespace

bool simplexInternalCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target,
                               double w, const double wi[3], const double eps[3], double gamma, Eigen::Vector3d& dp,
                               Eigen::Vector3d dpi[3], bool* torqueFree) {
  return internalCorrection(p, pi, target, w, wi, eps, gamma, dp, dpi, torqueFree);
}

bool targetCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double w, double gamma,
                      Eigen::Vector3d& dp) {
  if (w <= 0) return false;
  dp = gamma * (target - p);
  return dp.allFinite();
}

// ------------------------------------------------------------------------------------------------ internal set

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

SimplexInternalBatch* SimplexInternalConstraints::batch() {
  if (mode_ != InternalMode::ShapeMemory) return nullptr;
  if (!batch_) batch_ = std::make_unique<SimplexInternalBatch>(nb_, eps_, hOverR_, gamma_);
  batch_->setFirstParticle(first_);
  return batch_.get();
}

Eigen::VectorXd SimplexInternalConstraints::smoothingHeights(const Eigen::Ref<const Points>& p) const {
  // Current scale-free heights, then their neighbourhood means (one Jacobi pass per projection).
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

void SimplexInternalConstraints::project(Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(nb_.rows());
  MSK_ASSERT(pAll.rows() >= first_ + n && wAll.size() == pAll.rows(), "internal constraints: size mismatch");
  auto p = pAll.middleRows(first_, n);
  const auto w = wAll.segment(first_, n);
  skipped_ = 0;
  Eigen::VectorXd smoothH;
  if (mode_ == InternalMode::Smoothing) smoothH = smoothingHeights(p);
  for (int v = 0; v < n; ++v) {
    const int i0 = nb_(v, 0), i1 = nb_(v, 1), i2 = nb_(v, 2);
    Eigen::Vector3d pi[3] = {p.row(i0), p.row(i1), p.row(i2)};
    const double wi[3] = {w[i0], w[i1], w[i2]};
    Eigen::Vector3d dp, dpi[3];
    if (mode_ == InternalMode::Smoothing) {
      const Eigen::Vector3d pv = p.row(v).transpose();
      Eigen::Vector3d target, lambda;
      double denom = 0;
      if (!smoothingTarget(pv, pi, smoothH[v], target) || !smoothingSplit(w[v], wi, lambda, denom)) {
        ++skipped_;
        continue;
      }
      applySplit(target - pv, w[v], wi, lambda, denom, gamma_, dp, dpi);
    } else {
      const double eps[3] = {eps_(v, 0), eps_(v, 1), eps_(v, 2)};
      Eigen::Vector3d target;
      if (!shapeTarget(pi, eps, hOverR_[v], target) ||
          !internalCorrection(p.row(v).transpose(), pi, target, w[v], wi, eps, gamma_, dp, dpi, nullptr)) {
        ++skipped_;
        continue;
      }
    }
    p.row(v) += dp.transpose();
    p.row(i0) += dpi[0].transpose();
    p.row(i1) += dpi[1].transpose();
    p.row(i2) += dpi[2].transpose();
  }
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
  const int idx[4] = {first_ + r, first_ + nb_(r, 0), first_ + nb_(r, 1), first_ + nb_(r, 2)};
  const Eigen::Vector3d p = pAll.row(idx[0]).transpose();
  const Eigen::Vector3d pi[3] = {pAll.row(idx[1]).transpose(), pAll.row(idx[2]).transpose(),
                                 pAll.row(idx[3]).transpose()};
  double eps[3] = {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
  if (mode_ == InternalMode::ShapeMemory)
    for (int i = 0; i < 3; ++i) eps[i] = eps_(r, i);
  const bool smoothing = mode_ == InternalMode::Smoothing;
  Eigen::Vector3d target;
  if (smoothing ? !smoothingTarget(p, pi, rowHeights_[r], target) : !simplexShapeTarget(pi, eps, hOverR_[r], target))
    return false;
  const double wi[3] = {wAll[idx[1]], wAll[idx[2]], wAll[idx[3]]};
  const Eigen::Vector3d d = target - p;
  Eigen::Vector3d lambda;
  double denom = 0;
  bool split = false;
  if (smoothing ? !smoothingSplit(wAll[idx[0]], wi, lambda, denom)
                : !internalSplit(p, pi, d, wAll[idx[0]], wi, eps, lambda, denom, split))
    return false;
  out.count = 4;
  out.c = -d;  // C = P − P̃
  out.gamma = gamma_;
  out.direction = false;
  out.index[0] = idx[0];
  out.grad[0] = 1.0;
  out.react[0] = 1.0;
  for (int i = 0; i < 3; ++i) {
    out.index[i + 1] = idx[i + 1];
    out.grad[i + 1] = -eps[i];
    out.react[i + 1] = -lambda[i];
  }
  return true;
}

// ------------------------------------------------------------------------------------------------ targets

TargetConstraints::TargetConstraints(double gamma) : gamma_(gamma) { checkUnitInterval("image stiffness", gamma); }

void TargetConstraints::setTargets(const Points& targets, const Eigen::VectorXd& weights) {
  MSK_ASSERT(targets.rows() == weights.size(), "targets and weights differ in size");
  if (targets.rows() != targets_.rows()) rowLayoutChanged();
  targets_ = targets;
  weights_ = weights.cwiseMax(0.0).cwiseMin(1.0);
}

void TargetConstraints::project(Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(targets_.rows());
  if (n == 0) return;
  MSK_ASSERT(pAll.rows() >= first_ + n, "targets: size mismatch");
  auto p = pAll.middleRows(first_, n);
  const auto w = wAll.segment(first_, n);
  for (int v = 0; v < n; ++v) {
    if (weights_[v] <= 0) continue;
    Eigen::Vector3d dp;
    if (targetCorrection(p.row(v).transpose(), targets_.row(v).transpose(), w[v], gamma_ * weights_[v], dp))
      p.row(v) += dp.transpose();
  }
}

int TargetConstraints::rowParticles(int r, int index[kMaxRowParticles]) const {
  index[0] = first_ + r;
  return 1;
}

bool TargetConstraints::row(int r, const Points& pAll, const Eigen::VectorXd& wAll, ConstraintRow& out) const {
  const int i = first_ + r;
  if (!(weights_[r] > 0) || !(wAll[i] > 0)) return false;
  out.count = 1;
  out.index[0] = i;
  out.grad[0] = 1.0;
  out.react[0] = 1.0;
  out.c = (pAll.row(i) - targets_.row(r)).transpose();
  out.gamma = gamma_ * weights_[r];
  out.direction = true;
  return out.c.allFinite();
}

// ------------------------------------------------------------------------------------------------ global prior

Eigen::Matrix4d fitTransform(const Points& from, const Points& to, const Eigen::VectorXd& weights,
                             PriorTransform transform) {
  MSK_ASSERT(from.rows() == to.rows() && from.rows() == weights.size(), "fitTransform: size mismatch");
  const double wsum = weights.sum();
  MSK_ASSERT(wsum > 0, "fitTransform: weights sum to zero");
  const Eigen::RowVector3d cf = (weights.asDiagonal() * from).colwise().sum() / wsum;
  const Eigen::RowVector3d ct = (weights.asDiagonal() * to).colwise().sum() / wsum;
  const Eigen::MatrixX3d a = from.rowwise() - cf, b = to.rowwise() - ct;
  Eigen::Matrix3d m;
  if (transform == PriorTransform::Affine) {
    const Eigen::Matrix3d aa = a.transpose() * weights.asDiagonal() * a;
    const Eigen::Matrix3d ab = a.transpose() * weights.asDiagonal() * b;
    Eigen::FullPivLU<Eigen::Matrix3d> lu(aa);
    if (!lu.isInvertible()) transform = PriorTransform::Similarity;  // planar or collinear input
    else m = (lu.solve(ab)).transpose();
  }
  if (transform != PriorTransform::Affine) {
    const Eigen::Matrix3d cov = b.transpose() * weights.asDiagonal() * a / wsum;  // Σ w (to)(from)ᵀ
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) s(2, 2) = -1;
    const Eigen::Matrix3d r = svd.matrixU() * s * svd.matrixV().transpose();
    double scale = 1.0;
    if (transform == PriorTransform::Similarity) {
      const double varFrom = (weights.asDiagonal() * a.rowwise().squaredNorm()).sum() / wsum;
      if (varFrom > 0) scale = (svd.singularValues().asDiagonal() * s).trace() / varFrom;
    }
    m = scale * r;
  }
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = m;
  t.topRightCorner<3, 1>() = ct.transpose() - m * cf.transpose();
  return t;
}

ShapeMatchingConstraint::ShapeMatchingConstraint(const Points& reference, PriorTransform transform, double lambda)
    : ref_(reference), transform_(transform), lambda_(lambda) {
  checkUnitInterval("global prior weight", lambda);
}

void ShapeMatchingConstraint::setLambda(double lambda) {
  checkUnitInterval("global prior weight", lambda);
  lambda_ = lambda;
}

void ShapeMatchingConstraint::fit(const Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(ref_.rows());
  const Eigen::VectorXd w = wAll.segment(first_, n);
  // Mass weights: fixed particles (w = 0) weigh like a very heavy particle.
  const double wmax = w.maxCoeff();
  Eigen::VectorXd mass(w.size());
  for (int i = 0; i < w.size(); ++i) mass[i] = w[i] > 0 ? 1.0 / w[i] : 1e6 / std::max(wmax, 1e-300);
  // A non-finite particle takes no part in the fit (weight 0, and a finite stand-in, since 0 · NaN is NaN), so one
  // bad position cannot make every goal NaN; with no finite particle the last transform is kept.
  Points current = pAll.middleRows(first_, n);
  for (int i = 0; i < n; ++i)
    if (!current.row(i).allFinite()) {
      mass[i] = 0;
      current.row(i) = ref_.row(i);
    }
  if (mass.maxCoeff() > 0) last_ = fitTransform(ref_, current, mass, transform_);
}

void ShapeMatchingConstraint::project(Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(ref_.rows());
  MSK_ASSERT(pAll.rows() >= first_ + n, "global prior: size mismatch");
  if (lambda_ <= 0) return;
  auto p = pAll.middleRows(first_, n);
  const auto w = wAll.segment(first_, n);
  fit(pAll, wAll);
  const Eigen::Matrix3d m = last_.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = last_.topRightCorner<3, 1>();
  for (int i = 0; i < p.rows(); ++i) {
    if (w[i] <= 0 || !p.row(i).allFinite()) continue;  // a non-finite particle is left for the solver to report
    const Eigen::Vector3d goal = m * ref_.row(i).transpose() + t;
    p.row(i) += lambda_ * (goal.transpose() - p.row(i));
  }
}

int ShapeMatchingConstraint::rowParticles(int r, int index[kMaxRowParticles]) const {
  index[0] = first_ + r;
  return 1;
}

void ShapeMatchingConstraint::beginRows(const Points& pAll, const Eigen::VectorXd& wAll) {
  MSK_ASSERT(pAll.rows() >= first_ + ref_.rows() && wAll.size() == pAll.rows(), "global prior: size mismatch");
  if (lambda_ > 0) fit(pAll, wAll);
}

bool ShapeMatchingConstraint::row(int r, const Points& pAll, const Eigen::VectorXd& wAll, ConstraintRow& out) const {
  const int i = first_ + r;
  if (!(lambda_ > 0) || !(wAll[i] > 0)) return false;
  const Eigen::Vector3d goal = last_.topLeftCorner<3, 3>() * ref_.row(r).transpose() + last_.topRightCorner<3, 1>();
  out.count = 1;
  out.index[0] = i;
  out.grad[0] = 1.0;
  out.react[0] = 1.0;
  out.c = pAll.row(i).transpose() - goal;
  out.gamma = lambda_;
  out.direction = false;
  return out.c.allFinite();
}

}  // namespace msk

// ------------------------------------------------------------------------------------------------ collisions

namespace msk {

bool collisionCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const double bary[3],
                         const Eigen::Vector3d& normal, double gap, double friction, double w, const double wi[3],
                         Eigen::Vector3d& dp, Eigen::Vector3d dpi[3]) {
  const Eigen::Vector3d pbar = bary[0] * pi[0] + bary[1] * pi[1] + bary[2] * pi[2];
  const Eigen::Vector3d pc = pbar - p;
  const double pcn = pc.dot(normal);
  if (!(pcn + gap > 0)) return false;  // at least `gap` outside: nothing to do
  const Eigen::Vector3d tangential = pc - pcn * normal;
  const Eigen::Vector3d target = (1.0 - friction) * tangential - gap * normal;
  return shareContactChange(target - pc, bary, w, wi, dp, dpi);  // the wanted change of Pc = Σ bi Pi − P
}

namespace {
void checkContactParameters(double gapMm, double proximityMm, double friction) {
  if (!(gapMm >= 0) || !std::isfinite(gapMm)) throw ParameterError("collision gap", std::to_string(gapMm), "must be >= 0 mm");
  if (!(proximityMm > 0) || !std::isfinite(proximityMm))
    throw ParameterError("collision proximity", std::to_string(proximityMm), "must be > 0 mm");
  checkUnitInterval("collision friction", friction);
}
}  // namespace

CollisionConstraints::CollisionConstraints(int firstA, int vertexCount, std::shared_ptr<CollisionSurface> surfaceB,
                                           double gapMm, double proximityMm, double friction,
                                           const CollisionResponse& response)
    : firstA_(firstA), count_(vertexCount), surface_(std::move(surfaceB)), ownsSurface_(false), gap_(gapMm),
      proximity_(proximityMm), friction_(friction), response_(response),
      dref_(static_cast<size_t>(std::max(vertexCount, 0)), std::numeric_limits<double>::quiet_NaN()) {
  checkContactParameters(gapMm, proximityMm, friction);
  MSK_ASSERT(surface_ && surface_->reach() >= gapMm + proximityMm, "collision surface reach below gap + proximity");
  first_ = firstA;
}

CollisionConstraints::CollisionConstraints(int firstA, int vertexCount, const Triangles& trianglesB, double gapMm,
                                           double proximityMm, double friction, const CollisionResponse& response)
    : CollisionConstraints(firstA, vertexCount,
                           (checkContactParameters(gapMm, proximityMm, friction),
                            std::make_shared<CollisionSurface>(trianglesB, gapMm + proximityMm)),
                           gapMm, proximityMm, friction, response) {
  ownsSurface_ = true;
}

void CollisionConstraints::resetReference() {
  std::fill(dref_.begin(), dref_.end(), std::numeric_limits<double>::quiet_NaN());
}

void CollisionConstraints::detect(const Points& p, bool insideTest) {
  contacts_.clear();
  if (surface_->triangles().rows() == 0 || count_ == 0) return;
  if (ownsSurface_) surface_->update(p);
  const double reach = gap_ + proximity_;
  const WindingNumber* winding = nullptr;  // of B at p (shared with the other sets against B), when a side is needed
  const bool reference = response_.target == CollisionTarget::Reference;
  for (int v = 0; v < count_; ++v) {
    const Eigen::Vector3d q = p.row(firstA_ + v).transpose();
    const SurfacePoint s = surface_->closest(p, q, reach);
    if (s.triangle < 0) continue;
    Contact found{v, s.triangle, {s.bary[0], s.bary[1], s.bary[2]}, Eigen::Vector3d::Zero(), s.point - q};
    // Contact normal: the direction from the closest point to the vertex. Without the inside test every vertex is
    // taken to be outside (true when each step starts collision-free), so a correction can never push it through B.
    // With it, the side comes from B's winding number, which stays right where B folds or is stretched (a face or
    // pseudonormal there can point the wrong way and push the vertex through).
    const Eigen::Vector3d off = q - s.point;
    if (s.distance > 1e-9 * (1.0 + q.norm())) {
      if (insideTest && !winding) winding = &surface_->winding(p);
      const bool inside = insideTest && winding->inside(q);
      found.normal = (inside ? -1.0 : 1.0) * off / s.distance;
    } else {  // on the surface: B's outward side
      const Eigen::Vector3d pseudo = surface_->pseudonormal(p, s);
      if (!(pseudo.norm() > 1e-12)) continue;
      found.normal = pseudo.normalized();
    }
    // Reference target: the distance of the first detection is the one kept (at least the gap outside).
    if (reference && std::isnan(dref_[static_cast<size_t>(v)]))
      dref_[static_cast<size_t>(v)] = std::min(found.pc0.dot(found.normal), -gap_);
    contacts_.push_back(found);
  }
}

Eigen::Vector3d CollisionConstraints::relative(const Contact& c, const Points& q) const {
  const Triangles& tri = surface_->triangles();
  return c.bary[0] * q.row(tri(c.triangle, 0)).transpose() + c.bary[1] * q.row(tri(c.triangle, 1)).transpose() +
         c.bary[2] * q.row(tri(c.triangle, 2)).transpose() - q.row(firstA_ + c.vertex).transpose();
}

void CollisionConstraints::apply(const Contact& c, const Eigen::Vector3d& delta, const Eigen::VectorXd& w,
                                 Points& q) const {
  const Triangles& tri = surface_->triangles();
  const int a = firstA_ + c.vertex;
  const int i0 = tri(c.triangle, 0), i1 = tri(c.triangle, 1), i2 = tri(c.triangle, 2);
  const double wi[3] = {w[i0], w[i1], w[i2]};
  Eigen::Vector3d dp, dpi[3];
  if (!shareContactChange(delta, c.bary, w[a], wi, dp, dpi)) return;
  q.row(a) += dp.transpose();
  q.row(i0) += dpi[0].transpose();
  q.row(i1) += dpi[1].transpose();
  q.row(i2) += dpi[2].transpose();
}

void CollisionConstraints::project(Points& p, const Eigen::VectorXd& w) {
  if (response_.mode != CollisionMode::Position) projectDeep(p, w);
  else if (response_.resolution == CollisionResolution::Sequential) projectPositions(p, w);
}

void CollisionConstraints::projectDeep(Points& p, const Eigen::VectorXd& w) {
  if (!std::isfinite(response_.positionBeyondMm)) return;
  const ContactParameters spring{gap_, proximity_, friction_, CollisionTarget::Spring};
  for (const Contact& c : contacts_) {
    const Eigen::Vector3d pc = relative(c, p);
    if (!(pc.dot(c.normal) > response_.positionBeyondMm)) continue;
    Eigen::Vector3d delta;
    if (contactPositionChange(pc, c.pc0, c.normal, spring, 0.0, delta)) apply(c, delta, w, p);
  }
}

void CollisionConstraints::projectPositions(Points& p, const Eigen::VectorXd& w) {
  if (response_.target == CollisionTarget::Spring) {
    // The seed's position correction with a spring target (collisionCorrection(), kept as the reference kernel).
    for (const Contact& c : contacts_) {
      const int a = firstA_ + c.vertex;
      const Triangles& tri = surface_->triangles();
      const int i0 = tri(c.triangle, 0), i1 = tri(c.triangle, 1), i2 = tri(c.triangle, 2);
      const Eigen::Vector3d pi[3] = {p.row(i0).transpose(), p.row(i1).transpose(), p.row(i2).transpose()};
      const double wi[3] = {w[i0], w[i1], w[i2]};
      Eigen::Vector3d dp, dpi[3];
      if (!collisionCorrection(p.row(a).transpose(), pi, c.bary, c.normal, gap_, friction_, w[a], wi, dp, dpi)) continue;
      p.row(a) += dp.transpose();
      p.row(i0) += dpi[0].transpose();
      p.row(i1) += dpi[1].transpose();
      p.row(i2) += dpi[2].transpose();
    }
    return;
  }
  const ContactParameters prm = parameters();
  for (const Contact& c : contacts_) {
    Eigen::Vector3d delta;
    if (contactPositionChange(relative(c, p), c.pc0, c.normal, prm, dref_[static_cast<size_t>(c.vertex)], delta))
      apply(c, delta, w, p);
  }
}

void CollisionConstraints::correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (response_.mode != CollisionMode::Acceleration || response_.resolution != CollisionResolution::Sequential) return;
  const ContactParameters prm = parameters();
  for (const Contact& c : contacts_) {
    Eigen::Vector3d delta;
    if (contactAccelerationChange(relative(c, x), relative(c, v), c.normal, prm, dref_[static_cast<size_t>(c.vertex)],
                                  h, delta))
      apply(c, delta, w, v);
  }
}

void CollisionConstraints::correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (response_.mode != CollisionMode::Velocity || response_.resolution != CollisionResolution::Sequential) return;
  const ContactParameters prm = parameters();
  for (const Contact& c : contacts_) {
    Eigen::Vector3d delta;
    if (contactVelocityChange(relative(c, x), relative(c, v), c.normal, prm, dref_[static_cast<size_t>(c.vertex)], h,
                              delta))
      apply(c, delta, w, v);
  }
}

void CollisionConstraints::appendRows(CollisionMode mode, const Points& x, const Points& v, double h,
                                      std::vector<ContactRow>& rows) const {
  const ContactParameters prm = parameters();
  const Triangles& tri = surface_->triangles();
  for (const Contact& c : contacts_) {
    const double dref = dref_[static_cast<size_t>(c.vertex)];
    const Eigen::Vector3d pc = relative(c, x);
    ContactRow r;
    bool any = false;
    switch (mode) {
      case CollisionMode::Position: any = contactPositionChange(pc, c.pc0, c.normal, prm, dref, r.change); break;
      case CollisionMode::Velocity:
        any = contactVelocityChange(pc, relative(c, v), c.normal, prm, dref, h, r.change);
        break;
      case CollisionMode::Acceleration:
        any = contactAccelerationChange(pc, relative(c, v), c.normal, prm, dref, h, r.change);
        break;
    }
    if (!any) continue;
    r.index[0] = firstA_ + c.vertex;
    r.weight[0] = -1.0;
    for (int i = 0; i < 3; ++i) {
      r.index[i + 1] = tri(c.triangle, i);
      r.weight[i + 1] = c.bary[i];
    }
    r.normal = c.normal;
    r.unilateral = response_.target != CollisionTarget::Reference;
    rows.push_back(r);
  }
}

double CollisionConstraints::maxPenetration(const Points& p) const {
  double worst = 0;
  for (const Contact& c : contacts_) {
    const Triangles& tri = surface_->triangles();
    const Eigen::Vector3d pbar = c.bary[0] * p.row(tri(c.triangle, 0)).transpose() +
                                 c.bary[1] * p.row(tri(c.triangle, 1)).transpose() +
                                 c.bary[2] * p.row(tri(c.triangle, 2)).transpose();
    worst = std::max(worst, (pbar - p.row(firstA_ + c.vertex).transpose()).dot(c.normal));
  }
  return worst;
}

GlobalCollisionResolution::GlobalCollisionResolution(CollisionMode mode, const GlobalContactOptions& opts)
    : mode_(mode), opts_(opts) {
  if (opts.maxIterations < 1)
    throw ParameterError("global collision cg iterations", std::to_string(opts.maxIterations), "must be at least 1");
  if (!(opts.tolerance > 0) || !std::isfinite(opts.tolerance))
    throw ParameterError("global collision cg tolerance", std::to_string(opts.tolerance), "must be positive");
  if (!(opts.regularization >= 0) || !std::isfinite(opts.regularization))
    throw ParameterError("global collision regularization", std::to_string(opts.regularization), "must be >= 0");
}

void GlobalCollisionResolution::add(CollisionConstraints* set) {
  MSK_ASSERT(set != nullptr, "global collision resolution: null member");
  if (set->response().resolution != CollisionResolution::Global)
    throw ParameterError("collision resolution", collisionResolutionName(set->response().resolution),
                         "a member of a global resolution must be built with resolution \"global\"");
  if (set->response().mode != mode_)
    throw ParameterError("collision mode", collisionModeName(set->response().mode),
                         std::string("differs from the global resolution's mode \"") + collisionModeName(mode_) + "\"");
  members_.push_back(set);
}

void GlobalCollisionResolution::solve(CollisionMode mode, const Points& x, const Points& v, double h,
                                      const Eigen::VectorXd& w, Points& q) {
  // Position mode: a few passes, contacts that the previous solve left short (or newly violated) solved again together
  // (the velocity and acceleration changes are not idempotent: one solve).
  report_ = GlobalContactReport{};
  const int passes = mode == CollisionMode::Position ? kPasses : 1;
  for (int pass = 0; pass < passes; ++pass) {
    rows_.clear();
    for (const CollisionConstraints* m : members_) m->appendRows(mode, x, v, h, rows_);
    if (rows_.empty()) break;
    const GlobalContactReport r = solveContactsGlobal(rows_, w, q, opts_);
    if (pass == 0) report_ = r;
    else {
      report_.iterations += r.iterations;
      report_.dropped += r.dropped;
      report_.residual = r.residual;
    }
  }
}

void GlobalCollisionResolution::project(Points& p, const Eigen::VectorXd& w) {
  if (mode_ == CollisionMode::Position) projectPositions(p, w);
  else
    for (CollisionConstraints* m : members_) m->projectDeep(p, w);
}

void GlobalCollisionResolution::projectPositions(Points& p, const Eigen::VectorXd& w) {
  solve(CollisionMode::Position, p, p, 1.0, w, p);
}

void GlobalCollisionResolution::correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (mode_ == CollisionMode::Acceleration) solve(mode_, x, v, h, w, v);
}

void GlobalCollisionResolution::correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (mode_ == CollisionMode::Velocity) solve(mode_, x, v, h, w, v);
}

}  // namespace msk
