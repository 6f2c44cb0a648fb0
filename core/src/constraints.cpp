#include "msk/core/constraints.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <Eigen/Dense>

#include "msk/core/error.h"

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

bool simplexShapeTarget(const Eigen::Vector3d pi[3], const double epsRef[3], double hOverR, Eigen::Vector3d& target) {
  double r = 0;
  Eigen::Vector3d n;
  if (!triangleFrame(pi[0], pi[1], pi[2], r, n)) return false;
  target = epsRef[0] * pi[0] + epsRef[1] * pi[1] + epsRef[2] * pi[2] + hOverR * r * n;
  return target.allFinite();
}

bool simplexInternalCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target,
                               double w, const double wi[3], const double eps[3], double gamma, Eigen::Vector3d& dp,
                               Eigen::Vector3d dpi[3], bool* torqueFree) {
  const Eigen::Vector3d d = target - p;
  if (!d.allFinite()) return false;
  if (w <= 0 && wi[0] <= 0 && wi[1] <= 0 && wi[2] <= 0) return false;
  const Eigen::Vector3d a1 = pi[0] - p, a2 = pi[1] - p, a3 = pi[2] - p;
  // Cramer's rule without the determinant: λ'i ∝ μi, and λi = μi / Σμ (the determinant cancels), so the
  // normalised weights stay finite as P approaches its neighbours' plane (they tend to εi there).
  const Eigen::Vector3d mu(d.dot(a2.cross(a3)), d.dot(a3.cross(a1)), d.dot(a1.cross(a2)));
  const double sumMu = mu.sum();
  Eigen::Vector3d lambda;
  bool split = false;
  if (std::fabs(sumMu) > 0.05 * mu.cwiseAbs().sum() && std::fabs(sumMu) > 0) {
    lambda = mu / sumMu;
    split = true;
  } else {
    // d (nearly) parallel to the neighbours' plane: no torque-free split exists; share like the 3-simplex
    // constraint (linear momentum still conserved).
    lambda << eps[0], eps[1], eps[2];
  }
  // The reduced mass m̄ = 1/(w + Σ ε̃i λi wi) must not exceed the plain one: a denominator below w (negative
  // λ-weighted reactions) or extreme λ makes the linearised step overshoot, and repeated projection diverges.
  double denom = w + eps[0] * lambda[0] * wi[0] + eps[1] * lambda[1] * wi[1] + eps[2] * lambda[2] * wi[2];
  if (!(denom >= w) || !std::isfinite(denom) || lambda.cwiseAbs().maxCoeff() > 3.0) {
    lambda << eps[0], eps[1], eps[2];
    denom = w + eps[0] * eps[0] * wi[0] + eps[1] * eps[1] * wi[1] + eps[2] * eps[2] * wi[2];
    if (!(denom > 0)) return false;
    split = false;
  }
  if (torqueFree) *torqueFree = split;
  const double mbar = gamma / denom;
  dp = (w * mbar) * d;
  for (int i = 0; i < 3; ++i) dpi[i] = (-wi[i] * lambda[i] * mbar) * d;
  return true;
}

bool targetCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double w, double gamma,
                      Eigen::Vector3d& dp) {
  if (w <= 0) return false;
  dp = gamma * (target - p);
  return dp.allFinite();
}

// ------------------------------------------------------------------------------------------------ internal set

SimplexInternalConstraints::SimplexInternalConstraints(const SimplexMesh& reference, double gamma, InternalMode mode)
    : nb_(reference.neighbors), gamma_(gamma), mode_(mode) {
  checkUnitInterval("internal stiffness", gamma);
  MSK_ASSERT(reference.k == 2 && nb_.cols() == 3, "2-simplex mesh expected");
  const int n = reference.vertexCount();
  eps_.resize(n, 3);
  hOverR_.resize(n);
  for (int v = 0; v < n; ++v) {
    Eigen::Vector3d pi[3] = {reference.positions.row(nb_(v, 0)), reference.positions.row(nb_(v, 1)),
                             reference.positions.row(nb_(v, 2))};
    const Eigen::Vector3d p = reference.positions.row(v);
    double r = 0;
    Eigen::Vector3d nrm;
    if (!triangleFrame(pi[0], pi[1], pi[2], r, nrm)) {
      eps_.row(v).setConstant(1.0 / 3.0);
      hOverR_[v] = 0;
      continue;
    }
    // Barycentric coordinates of P's projection on the neighbours' plane.
    const double h = (p - pi[0]).dot(nrm);
    const Eigen::Vector3d q = p - h * nrm;
    const Eigen::Vector3d e0 = pi[1] - pi[0], e1 = pi[2] - pi[0], f = q - pi[0];
    const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = f.dot(e0), d21 = f.dot(e1);
    const double den = d00 * d11 - d01 * d01;
    const double b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den;
    eps_.row(v) << 1.0 - b1 - b2, b1, b2;
    hOverR_[v] = h / r;
  }
}

void SimplexInternalConstraints::project(Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(nb_.rows());
  MSK_ASSERT(pAll.rows() >= first_ + n && wAll.size() == pAll.rows(), "internal constraints: size mismatch");
  auto p = pAll.middleRows(first_, n);
  const auto w = wAll.segment(first_, n);
  skipped_ = 0;
  Eigen::VectorXd smoothH;
  if (mode_ == InternalMode::Smoothing) {
    // Current scale-free heights, then their neighbourhood means (one Jacobi pass per projection).
    Eigen::VectorXd hr(n);
    for (int v = 0; v < n; ++v) {
      Eigen::Vector3d pi[3] = {p.row(nb_(v, 0)), p.row(nb_(v, 1)), p.row(nb_(v, 2))};
      double r = 0;
      Eigen::Vector3d nrm;
      hr[v] = triangleFrame(pi[0], pi[1], pi[2], r, nrm) ? (p.row(v).transpose() - pi[0]).dot(nrm) / r : 0.0;
    }
    smoothH.resize(n);
    for (int v = 0; v < n; ++v) smoothH[v] = (hr[nb_(v, 0)] + hr[nb_(v, 1)] + hr[nb_(v, 2)]) / 3.0;
  }
  static const double third[3] = {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
  for (int v = 0; v < n; ++v) {
    const int i0 = nb_(v, 0), i1 = nb_(v, 1), i2 = nb_(v, 2);
    Eigen::Vector3d pi[3] = {p.row(i0), p.row(i1), p.row(i2)};
    const double* eps = mode_ == InternalMode::Smoothing ? third : eps_.row(v).data();
    double epsCopy[3];
    if (mode_ == InternalMode::ShapeMemory) {
      epsCopy[0] = eps_(v, 0);
      epsCopy[1] = eps_(v, 1);
      epsCopy[2] = eps_(v, 2);
      eps = epsCopy;
    }
    const double hr = mode_ == InternalMode::Smoothing ? smoothH[v] : hOverR_[v];
    Eigen::Vector3d target;
    if (!simplexShapeTarget(pi, eps, hr, target)) {
      ++skipped_;
      continue;
    }
    const double wi[3] = {w[i0], w[i1], w[i2]};
    Eigen::Vector3d dp, dpi[3];
    if (!simplexInternalCorrection(p.row(v).transpose(), pi, target, w[v], wi, eps, gamma_, dp, dpi)) {
      ++skipped_;
      continue;
    }
    p.row(v) += dp.transpose();
    p.row(i0) += dpi[0].transpose();
    p.row(i1) += dpi[1].transpose();
    p.row(i2) += dpi[2].transpose();
  }
}

// ------------------------------------------------------------------------------------------------ targets

TargetConstraints::TargetConstraints(double gamma) : gamma_(gamma) { checkUnitInterval("image stiffness", gamma); }

void TargetConstraints::setTargets(const Points& targets, const Eigen::VectorXd& weights) {
  MSK_ASSERT(targets.rows() == weights.size(), "targets and weights differ in size");
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

void ShapeMatchingConstraint::project(Points& pAll, const Eigen::VectorXd& wAll) {
  const int n = static_cast<int>(ref_.rows());
  MSK_ASSERT(pAll.rows() >= first_ + n, "global prior: size mismatch");
  if (lambda_ <= 0) return;
  auto p = pAll.middleRows(first_, n);
  const Eigen::VectorXd w = wAll.segment(first_, n);
  // Mass weights: fixed particles (w = 0) weigh like a very heavy particle.
  const double wmax = w.maxCoeff();
  Eigen::VectorXd mass(w.size());
  for (int i = 0; i < w.size(); ++i) mass[i] = w[i] > 0 ? 1.0 / w[i] : 1e6 / std::max(wmax, 1e-300);
  last_ = fitTransform(ref_, Points(p), mass, transform_);
  const Eigen::Matrix3d m = last_.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = last_.topRightCorner<3, 1>();
  for (int i = 0; i < p.rows(); ++i) {
    if (w[i] <= 0) continue;
    const Eigen::Vector3d goal = m * ref_.row(i).transpose() + t;
    p.row(i) += lambda_ * (goal.transpose() - p.row(i));
  }
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
  const Eigen::Vector3d delta = target - pc;  // wanted change of Pc = Σ bi Pi − P
  const double denom = w + bary[0] * bary[0] * wi[0] + bary[1] * bary[1] * wi[1] + bary[2] * bary[2] * wi[2];
  if (!(denom > 0) || !delta.allFinite()) return false;
  const double mbar = 1.0 / denom;
  dp = (-w * mbar) * delta;
  for (int i = 0; i < 3; ++i) dpi[i] = (wi[i] * bary[i] * mbar) * delta;
  return true;
}

CollisionConstraints::CollisionConstraints(int firstA, int vertexCount, const Triangles& trianglesB, double gapMm,
                                           double proximityMm, double friction)
    : firstA_(firstA), count_(vertexCount), tri_(trianglesB), gap_(gapMm), proximity_(proximityMm), friction_(friction) {
  if (!(gapMm >= 0) || !std::isfinite(gapMm)) throw ParameterError("collision gap", std::to_string(gapMm), "must be >= 0 mm");
  if (!(proximityMm > 0) || !std::isfinite(proximityMm))
    throw ParameterError("collision proximity", std::to_string(proximityMm), "must be > 0 mm");
  checkUnitInterval("collision friction", friction);
  first_ = firstA;
  if (tri_.rows() > 0) {
    idxLo_ = tri_.minCoeff();
    idxHi_ = tri_.maxCoeff();
  }
  // Vertex → incident triangles (CSR over B's particle range), for vertex normals on demand.
  vtStart_.assign(static_cast<size_t>(idxHi_ - idxLo_ + 2), 0);
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) ++vtStart_[static_cast<size_t>(tri_(t, k) - idxLo_) + 1];
  for (size_t i = 1; i < vtStart_.size(); ++i) vtStart_[i] += vtStart_[i - 1];
  vtTri_.assign(static_cast<size_t>(vtStart_.back()), 0);
  {
    std::vector<int> fill(vtStart_.begin(), vtStart_.end() - 1);
    for (int t = 0; t < tri_.rows(); ++t)
      for (int k = 0; k < 3; ++k) vtTri_[static_cast<size_t>(fill[static_cast<size_t>(tri_(t, k) - idxLo_)]++)] = t;
  }
  // Edge → the two triangles sharing it (connectivity is fixed; positions change every step).
  for (int t = 0; t < tri_.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      auto& slot = edgeFaces_[edgeKey(tri_(t, k), tri_(t, (k + 1) % 3))];
      if (slot[0] < 0) slot[0] = t;
      else slot[1] = t;
    }
  for (auto& kv : edgeFaces_)
    if (kv.second[1] < 0) kv.second[1] = kv.second[0];  // open edge (not expected for closed partners)
}

void CollisionConstraints::detect(const Points& p, bool insideTest) {
  contacts_.clear();
  const int nt = static_cast<int>(tri_.rows());
  if (nt == 0 || count_ == 0) return;
  const double reach = gap_ + proximity_;
  // Face normals and angle-weighted vertex normals of B: with the edge normals these are the pseudonormals that give
  // the correct inside/outside sign at any closest feature of a closed mesh (Bærentzen & Aanæs 2005); an
  // interpolated or single face normal does not beside edges, creases and thin wedges.
  // Normals are computed on demand, only for the features that hold a contact.
  auto faceNormal = [&](int t) -> Eigen::Vector3d {
    const Eigen::Vector3d n = (p.row(tri_(t, 1)) - p.row(tri_(t, 0))).transpose().cross((p.row(tri_(t, 2)) - p.row(tri_(t, 0))).transpose());
    const double len = n.norm();
    return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
  };
  auto vertexNormal = [&](int i, bool angleWeighted) -> Eigen::Vector3d {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    const int local = i - idxLo_;
    for (int k = vtStart_[static_cast<size_t>(local)]; k < vtStart_[static_cast<size_t>(local) + 1]; ++k) {
      const int t = vtTri_[static_cast<size_t>(k)];
      const Eigen::Vector3d n = faceNormal(t);
      if (!angleWeighted) {
        sum += n;
        continue;
      }
      int c = 0;
      while (tri_(t, c) != i) ++c;
      const Eigen::Vector3d e1 = (p.row(tri_(t, (c + 1) % 3)) - p.row(i)).transpose(),
                            e2 = (p.row(tri_(t, (c + 2) % 3)) - p.row(i)).transpose();
      sum += std::atan2(e1.cross(e2).norm(), e1.dot(e2)) * n;
    }
    const double len = sum.norm();
    return len > 0 ? Eigen::Vector3d(sum / len) : Eigen::Vector3d::Zero();
  };
  Points lo(nt, 3), hi(nt, 3);  // triangle bounding boxes
  double extent = 0;
  for (int t = 0; t < nt; ++t) {
    const Eigen::Vector3d x[3] = {p.row(tri_(t, 0)), p.row(tri_(t, 1)), p.row(tri_(t, 2))};
    lo.row(t) = x[0].cwiseMin(x[1]).cwiseMin(x[2]).transpose();
    hi.row(t) = x[0].cwiseMax(x[1]).cwiseMax(x[2]).transpose();
    extent += (x[0] - x[1]).norm();
  }
  // Dense grid (CSR) over B's bounding box grown by the reach; cell size the reach or the typical triangle extent,
  // whichever is larger (and coarser if the box would need too many cells), so each query scans 27 cells.
  const Eigen::Vector3d boxLo = lo.colwise().minCoeff().transpose().array() - reach;
  const Eigen::Vector3d boxHi = hi.colwise().maxCoeff().transpose().array() + reach;
  double h = std::max(reach, extent / nt);
  const Eigen::Vector3d size = boxHi - boxLo;
  while ((size / h).array().ceil().prod() > 4e6) h *= 1.5;
  const Eigen::Vector3i dims = (size / h).array().floor().cast<int>() + 1;
  auto cellOf = [&](const Eigen::Vector3d& x) -> Eigen::Vector3i {
    return ((x - boxLo) / h).array().floor().cast<int>().cwiseMax(0).cwiseMin(dims.array() - 1);
  };
  const size_t cells = static_cast<size_t>(dims[0]) * static_cast<size_t>(dims[1]) * static_cast<size_t>(dims[2]);
  auto cellIndex = [&](int x, int y, int z) {
    return (static_cast<size_t>(z) * static_cast<size_t>(dims[1]) + static_cast<size_t>(y)) * static_cast<size_t>(dims[0]) +
           static_cast<size_t>(x);
  };
  std::vector<int> start(cells + 1, 0), items;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      for (size_t i = 0; i < cells; ++i) start[i + 1] += start[i];
      items.resize(static_cast<size_t>(start[cells]));
    }
    std::vector<int> fill = pass == 1 ? std::vector<int>(start.begin(), start.end() - 1) : std::vector<int>();
    for (int t = 0; t < nt; ++t) {
      const Eigen::Vector3i a = cellOf(lo.row(t).transpose()), b = cellOf(hi.row(t).transpose());
      for (int z = a[2]; z <= b[2]; ++z)
        for (int y = a[1]; y <= b[1]; ++y)
          for (int x = a[0]; x <= b[0]; ++x) {
            const size_t ci = cellIndex(x, y, z);
            if (pass == 0) ++start[ci + 1];
            else items[static_cast<size_t>(fill[ci]++)] = t;
          }
    }
  }
  for (int v = 0; v < count_; ++v) {
    const Eigen::Vector3d q = p.row(firstA_ + v).transpose();
    if ((q.array() < boxLo.array()).any() || (q.array() > boxHi.array()).any()) continue;
    const Eigen::Vector3i c = cellOf(q);
    double best = reach;
    Contact found{v, -1, {0, 0, 0}, Eigen::Vector3d::Zero()};
    Eigen::Vector3d closest = Eigen::Vector3d::Zero();
    for (int z = std::max(0, c[2] - 1); z <= std::min(dims[2] - 1, c[2] + 1); ++z)
      for (int y = std::max(0, c[1] - 1); y <= std::min(dims[1] - 1, c[1] + 1); ++y)
        for (int x = std::max(0, c[0] - 1); x <= std::min(dims[0] - 1, c[0] + 1); ++x) {
          const size_t ci = cellIndex(x, y, z);
          for (int k = start[ci]; k < start[ci + 1]; ++k) {
            const int t = items[static_cast<size_t>(k)];
            // Cheap rejection: distance to the triangle's box already beyond the best found.
            const double boxDist =
                (lo.row(t).transpose() - q).cwiseMax(q - hi.row(t).transpose()).cwiseMax(0.0).norm();
            if (boxDist >= best) continue;
            Eigen::Vector3d bc;
            const Eigen::Vector3d cp = closestPointOnTriangle(q, p.row(tri_(t, 0)).transpose(), p.row(tri_(t, 1)).transpose(),
                                                              p.row(tri_(t, 2)).transpose(), &bc);
            const double d = (cp - q).norm();
            if (d < best) {
              best = d;
              closest = cp;
              found.triangle = t;
              found.bary[0] = bc[0];
              found.bary[1] = bc[1];
              found.bary[2] = bc[2];
            }
          }
        }
    if (found.triangle < 0) continue;
    // Pseudonormal of the closest feature: face interior, edge (the two faces sharing it) or vertex.
    const int t = found.triangle;
    constexpr double kFeature = 1e-9;
    int zeros = 0, zeroAt = -1, oneAt = -1;
    for (int k = 0; k < 3; ++k) {
      if (found.bary[k] < kFeature) {
        ++zeros;
        zeroAt = k;
      }
      if (found.bary[k] > 1.0 - kFeature) oneAt = k;
    }
    Eigen::Vector3d pseudo = faceNormal(t);
    if (oneAt >= 0) {
      pseudo = vertexNormal(tri_(t, oneAt), true);
    } else if (zeros == 1) {
      const int u = tri_(t, (zeroAt + 1) % 3), w = tri_(t, (zeroAt + 2) % 3);
      auto e = edgeFaces_.find(edgeKey(u, w));
      if (e != edgeFaces_.end()) pseudo = faceNormal(e->second[0]) + faceNormal(e->second[1]);
    }
    if (!(pseudo.norm() > 1e-12)) continue;
    // Second opinion from the smooth (interpolated vertex) normal: where the two disagree on the side, the partner's
    // surface is folded or stretched there and the contact is ambiguous; it is skipped rather than pushed the wrong way.
    Eigen::Vector3d smooth = Eigen::Vector3d::Zero();
    if (insideTest)
      for (int k = 0; k < 3; ++k) smooth += found.bary[k] * vertexNormal(tri_(t, k), false);
    // Contact normal: the direction from the closest point to the vertex, signed by the pseudonormal (outward of B).
    const Eigen::Vector3d off = q - closest;
    const double dist = off.norm();
    if (dist > 1e-9 * (1.0 + q.norm())) {
      // Without the inside test every vertex is taken to be outside (true when each step starts collision-free):
      // the normal points from B to the vertex and a correction can never push a vertex through B.
      const bool inside = insideTest && off.dot(pseudo) < 0 && off.dot(smooth) < 0;
      found.normal = (inside ? -1.0 : 1.0) * off / dist;
    } else {
      found.normal = pseudo.normalized();
    }
    contacts_.push_back(found);
  }
}

void CollisionConstraints::project(Points& p, const Eigen::VectorXd& w) {
  for (const Contact& c : contacts_) {
    const int a = firstA_ + c.vertex;
    const int i0 = tri_(c.triangle, 0), i1 = tri_(c.triangle, 1), i2 = tri_(c.triangle, 2);
    const Eigen::Vector3d pi[3] = {p.row(i0).transpose(), p.row(i1).transpose(), p.row(i2).transpose()};
    const double wi[3] = {w[i0], w[i1], w[i2]};
    Eigen::Vector3d dp, dpi[3];
    if (!collisionCorrection(p.row(a).transpose(), pi, c.bary, c.normal, gap_, friction_, w[a], wi, dp, dpi)) continue;
    p.row(a) += dp.transpose();
    p.row(i0) += dpi[0].transpose();
    p.row(i1) += dpi[1].transpose();
    p.row(i2) += dpi[2].transpose();
  }
}

double CollisionConstraints::maxPenetration(const Points& p) const {
  double worst = 0;
  for (const Contact& c : contacts_) {
    const Eigen::Vector3d pbar = c.bary[0] * p.row(tri_(c.triangle, 0)).transpose() +
                                 c.bary[1] * p.row(tri_(c.triangle, 1)).transpose() +
                                 c.bary[2] * p.row(tri_(c.triangle, 2)).transpose();
    const double pen = (pbar - p.row(firstA_ + c.vertex).transpose()).dot(c.normal);
    worst = std::max(worst, pen);
  }
  return worst;
}

}  // namespace msk
