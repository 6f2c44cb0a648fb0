#include "msk/core/medial_axis.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <vector>

#include "msk/core/error.h"

namespace msk {

namespace {

using Vec3 = Eigen::Vector3d;

void checkAttachment(const RadialAttachment& a, const char* caller) {
  const Eigen::Index n = a.radius.size();
  if (a.axisIndex.rows() != n || a.weights.rows() != n)
    throw Error(std::string(caller) + ": attachment arrays differ in length (" + std::to_string(a.axisIndex.rows()) +
                ", " + std::to_string(a.weights.rows()) + ", " + std::to_string(n) + ")");
  if (n > 0 && a.axisIndex.minCoeff() < 0) throw Error(std::string(caller) + ": negative axis index in attachment");
}

/// Closest point on segment [a, b] to p: parameter t ∈ [0, 1] (0 for a zero-length segment).
double segmentParameter(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double ee = e.squaredNorm();
  if (!(ee > 0)) return 0.0;
  return std::clamp((p - a).dot(e) / ee, 0.0, 1.0);
}

}  // namespace

// ------------------------------------------------------------------------------------------------ building

SimplexMesh openCurveMesh(const Points& vertices) {
  const int n = static_cast<int>(vertices.rows());
  if (n < 3)
    throw Error("openCurveMesh: an open 1-simplex curve needs at least 3 vertices (got " + std::to_string(n) + ")");
  SimplexMesh m;
  m.k = 1;
  m.positions = vertices;
  m.neighbors.resize(n, 2);
  for (int j = 0; j < n; ++j) {
    m.neighbors(j, 0) = (j + n - 1) % n;
    m.neighbors(j, 1) = (j + 1) % n;
  }
  return m;
}

MedialAxis buildMedialAxis(const TriangleMesh& surface, const MedialAxisOptions& opts) {
  if (!(opts.spacingMm > 0) || !std::isfinite(opts.spacingMm))
    throw ParameterError("medial axis spacing", std::to_string(opts.spacingMm), "must be a finite length > 0 mm");
  if (opts.slices < 0 || opts.slices == 1 || opts.slices == 2)
    throw ParameterError("medial axis slices", std::to_string(opts.slices), "must be 0 (automatic) or >= 3");
  const std::string problem = closedMeshProblem(surface);
  if (!problem.empty()) throw Error("buildMedialAxis: surface is not closed: " + problem);

  const int nv = surface.vertexCount();
  const Points& x = surface.vertices;
  // Vertex areas: a third of each incident triangle.
  Eigen::VectorXd area = Eigen::VectorXd::Zero(nv);
  for (int f = 0; f < surface.faceCount(); ++f) {
    const int a = surface.faces(f, 0), b = surface.faces(f, 1), c = surface.faces(f, 2);
    const double third = (x.row(b) - x.row(a)).cross(x.row(c) - x.row(a)).norm() / 6.0;
    area[a] += third;
    area[b] += third;
    area[c] += third;
  }
  const double total = area.sum();
  if (!(total > 0) || !std::isfinite(total)) throw Error("buildMedialAxis: surface has no area");

  MedialAxis axis;
  axis.center = (area.asDiagonal() * x).colwise().sum().transpose() / total;
  const Eigen::MatrixX3d centred = x.rowwise() - axis.center.transpose();
  const Eigen::Matrix3d cov = centred.transpose() * area.asDiagonal() * centred / total;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Vec3 d = eig.eigenvectors().col(2);  // eigenvalues ascending: the last one spreads most
  Eigen::Index big = 0;
  d.cwiseAbs().maxCoeff(&big);
  if (d[big] < 0) d = -d;
  axis.direction = d.normalized();

  const Eigen::VectorXd s = centred * axis.direction;
  const double smin = s.minCoeff(), smax = s.maxCoeff();
  axis.lengthMm = smax - smin;
  if (!(axis.lengthMm > 0)) throw Error("buildMedialAxis: surface has no extent along its principal axis");

  int n = opts.slices;
  if (n == 0) {
    const double ratio = std::min(axis.lengthMm / opts.spacingMm, static_cast<double>(nv));
    n = std::max(3, std::min(nv, static_cast<int>(std::lround(ratio))));
  }
  const double slab = axis.lengthMm / n;

  // Each vertex's area goes to the two slabs whose centres it lies between, in proportion to its nearness (a tent
  // over each centre; the end halves to the end slabs alone). Hard slabs would put a ring of vertices lying on a slab
  // boundary (a symmetric mesh has such rings) wholly or partly on one side by rounding alone, and its centroid off
  // the axis by up to the radius; shared, a vertex's contribution moves continuously with its position.
  Eigen::VectorXd mass = Eigen::VectorXd::Zero(n);
  Points sum = Points::Zero(n, 3);
  for (int v = 0; v < nv; ++v) {
    const double t = std::clamp((s[v] - smin) / slab - 0.5, 0.0, static_cast<double>(n - 1));  // in slab centres
    const int j = std::min(static_cast<int>(std::floor(t)), n - 2);
    const double upper = t - j;
    mass[j] += (1.0 - upper) * area[v];
    sum.row(j) += ((1.0 - upper) * area[v]) * x.row(v);
    mass[j + 1] += upper * area[v];
    sum.row(j + 1) += (upper * area[v]) * x.row(v);
  }
  // The extreme vertices fall in the first and last slabs, so only interior slabs can be empty (or weigh nothing:
  // isolated vertices have no area); interpolate those linearly between the nearest weighted slabs.
  Points q(n, 3);
  std::vector<int> filled;
  for (int j = 0; j < n; ++j) {
    if (mass[j] > 0) {
      q.row(j) = sum.row(j) / mass[j];
      filled.push_back(j);
    }
  }
  if (filled.empty()) throw Error("buildMedialAxis: no slab holds surface area");
  for (int j = 0; j < n; ++j) {
    if (mass[j] > 0) continue;
    const auto hi = std::lower_bound(filled.begin(), filled.end(), j);
    if (hi == filled.begin() || hi == filled.end()) {
      // No weighted slab on one side (only when end vertices carry no area): shift the nearest one along the axis.
      const int k = hi == filled.end() ? filled.back() : *hi;
      q.row(j) = q.row(k) + ((j - k) * slab) * axis.direction.transpose();
      continue;
    }
    const int b = *hi, a = *(hi - 1);
    const double t = static_cast<double>(j - a) / (b - a);
    q.row(j) = (1.0 - t) * q.row(a) + t * q.row(b);
  }
  axis.curve = openCurveMesh(q);
  return axis;
}

// ------------------------------------------------------------------------------------------------ attachment

RadialAttachment attachToAxis(const Points& surface, const Points& axis) {
  const int na = static_cast<int>(axis.rows());
  if (na < 2) throw Error("attachToAxis: the axis needs at least 2 vertices (got " + std::to_string(na) + ")");
  if (!axis.allFinite() || !surface.allFinite()) throw Error("attachToAxis: non-finite coordinates");
  const int nv = static_cast<int>(surface.rows());
  RadialAttachment att;
  att.axisIndex.resize(nv, 2);
  att.weights.resize(nv, 2);
  att.radius.resize(nv);
  for (int v = 0; v < nv; ++v) {
    const Vec3 p = surface.row(v);
    double best = std::numeric_limits<double>::infinity(), bestT = 0;
    int bestJ = 0;
    for (int j = 0; j + 1 < na; ++j) {
      const Vec3 a = axis.row(j), b = axis.row(j + 1);
      const double t = segmentParameter(p, a, b);
      const double d2 = ((1.0 - t) * a + t * b - p).squaredNorm();
      if (d2 < best) {
        best = d2;
        bestT = t;
        bestJ = j;
      }
    }
    att.axisIndex(v, 0) = bestJ;
    att.axisIndex(v, 1) = bestJ + 1;
    att.weights(v, 0) = 1.0 - bestT;
    att.weights(v, 1) = bestT;
    att.radius[v] = std::sqrt(best);
  }
  return att;
}

Eigen::VectorXd axisInverseMass(const RadialAttachment& att, int na, const Eigen::VectorXd& wSurface) {
  checkAttachment(att, "axisInverseMass");
  const int nv = att.vertexCount();
  if (wSurface.size() != nv)
    throw Error("axisInverseMass: " + std::to_string(wSurface.size()) + " inverse masses for " + std::to_string(nv) +
                " attached vertices");
  if (nv > 0 && (att.axisIndex.maxCoeff() >= na || !(wSurface.minCoeff() >= 0)))
    throw Error("axisInverseMass: attachment beyond the axis or negative inverse mass");
  Eigen::VectorXd mass = Eigen::VectorXd::Zero(na), touched = Eigen::VectorXd::Zero(na);
  for (int v = 0; v < nv; ++v) {
    for (int k = 0; k < 2; ++k) {
      const int j = att.axisIndex(v, k);
      const double c = att.weights(v, k);
      if (!(c > 0)) continue;
      touched[j] = 1;
      mass[j] += wSurface[v] > 0 ? c / wSurface[v] : std::numeric_limits<double>::infinity();
    }
  }
  const double meanW = nv > 0 ? wSurface.mean() : 1.0;
  Eigen::VectorXd w(na);
  for (int j = 0; j < na; ++j) w[j] = touched[j] > 0 ? (std::isinf(mass[j]) ? 0.0 : 1.0 / mass[j]) : meanW;
  return w;
}

// ------------------------------------------------------------------------------------------------ kernel

bool radialRow(const Eigen::Vector3d& p, const Eigen::Vector3d q[2], const double weights[2], double radius,
               double gamma, ConstraintRow& row) {
  if (!(radius >= 0) || !std::isfinite(radius)) return false;
  if (!std::isfinite(weights[0]) || !std::isfinite(weights[1])) return false;
  const Vec3 pc = weights[0] * q[0] + weights[1] * q[1] - p;  // Q̄ − P
  if (!pc.allFinite()) return false;
  const double len = pc.norm();
  if (!(len > 1e-9)) return false;
  row.count = 3;
  row.c = (radius / len) * pc - pc;  // C = G − (Q̄ − P), along Q̄ − P
  row.gamma = gamma;
  row.direction = false;
  row.compliant = true;
  row.index[0] = 0;
  row.grad[0] = row.react[0] = 1.0;
  for (int j = 0; j < 2; ++j) {
    row.index[j + 1] = j + 1;
    row.grad[j + 1] = row.react[j + 1] = -weights[j];
  }
  return true;
}

bool radialCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d q[2], const double weights[2], double radius,
                      double w, const double wq[2], double gamma, Eigen::Vector3d& dp, Eigen::Vector3d dq[2]) {
  if (!(gamma >= 0.0 && gamma <= 1.0)) return false;
  ConstraintRow row;
  if (!radialRow(p, q, weights, radius, gamma, row)) return false;
  return pbdCorrections(row, w, wq, dp, dq);
}

// ------------------------------------------------------------------------------------------------ sets

RadialConstraints::RadialConstraints(const RadialAttachment& attachment, int firstAxisParticle, double gamma)
    : att_(attachment), firstAxis_(0), gamma_(gamma) {
  checkUnitInterval("radial stiffness", gamma);
  checkAttachment(att_, "RadialConstraints");
  setFirstAxisParticle(firstAxisParticle);
  axisCount_ = att_.vertexCount() > 0 ? att_.axisIndex.maxCoeff() + 1 : 0;
}

void RadialConstraints::setGamma(double gamma) {
  checkUnitInterval("radial stiffness", gamma);
  gamma_ = gamma;
}

void RadialConstraints::setFirstAxisParticle(int first) {
  if (first < 0) throw ParameterError("radial first axis particle", std::to_string(first), "must be >= 0");
  firstAxis_ = first;
  rowLayoutChanged();
}

int RadialConstraints::rowParticles(int r, int index[kMaxRowParticles]) const {
  index[0] = first_ + r;
  index[1] = firstAxis_ + att_.axisIndex(r, 0);
  index[2] = firstAxis_ + att_.axisIndex(r, 1);
  return index[1] == index[2] ? 2 : 3;
}

void RadialConstraints::beginRows(const Points& p, const Eigen::VectorXd& w) {
  MSK_ASSERT(w.size() == p.rows() && p.rows() >= first_ + att_.vertexCount() && p.rows() >= firstAxis_ + axisCount_,
             "radial constraints: size mismatch");
}

bool RadialConstraints::row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const {
  (void)w;
  const int iv = first_ + r, a = firstAxis_ + att_.axisIndex(r, 0), b = firstAxis_ + att_.axisIndex(r, 1);
  const Vec3 q[2] = {p.row(a).transpose(), p.row(b).transpose()};
  const double c[2] = {att_.weights(r, 0), att_.weights(r, 1)};
  if (!radialRow(p.row(iv).transpose(), q, c, att_.radius[r], gamma_, out)) return false;
  out.index[0] = iv;
  out.index[1] = a;
  out.index[2] = b;
  if (a == b) {  // both weights on one axis vertex
    out.count = 2;
    out.grad[1] = out.react[1] = -(c[0] + c[1]);
  }
  return true;
}

void recenterAxis(const Points& surface, Points& axis, const RadialAttachment& att, double gamma,
                  const Eigen::VectorXd* axisInverseMasses) {
  checkUnitInterval("axis centering stiffness", gamma);
  checkAttachment(att, "recenterAxis");
  const int na = static_cast<int>(axis.rows()), nv = att.vertexCount();
  MSK_ASSERT(surface.rows() == nv, "recenterAxis: surface and attachment differ in size");
  MSK_ASSERT(nv == 0 || att.axisIndex.maxCoeff() < na, "recenterAxis: attachment indexes beyond the axis");
  MSK_ASSERT(!axisInverseMasses || axisInverseMasses->size() == na, "recenterAxis: inverse masses differ in size");
  if (na < 2) return;
  Eigen::VectorXd mass = Eigen::VectorXd::Zero(na);
  Points sum = Points::Zero(na, 3);
  for (int v = 0; v < nv; ++v) {
    for (int k = 0; k < 2; ++k) {
      const int j = att.axisIndex(v, k);
      const double c = att.weights(v, k);
      mass[j] += c;
      sum.row(j) += c * surface.row(v);
    }
  }
  const Points before = axis;  // tangents and offsets from the axis as it was (Jacobi update)
  for (int j = 0; j < na; ++j) {
    if (!(mass[j] > 0) || (axisInverseMasses && !((*axisInverseMasses)[j] > 0))) continue;
    const Vec3 centre = sum.row(j).transpose() / mass[j];
    const Vec3 tangent = (before.row(std::min(j + 1, na - 1)) - before.row(std::max(j - 1, 0))).transpose();
    Vec3 delta = centre - before.row(j).transpose();
    const double len = tangent.norm();
    if (len > 0) delta -= tangent.dot(delta) / (len * len) * tangent;
    if (delta.allFinite()) axis.row(j) += gamma * delta.transpose();
  }
}

AxisCentering::AxisCentering(const RadialAttachment& attachment, int firstAxisParticle, int axisVertexCount,
                             double gamma)
    : att_(attachment), firstAxis_(firstAxisParticle), axisCount_(axisVertexCount), gamma_(gamma) {
  checkUnitInterval("axis centering stiffness", gamma);
  checkAttachment(att_, "AxisCentering");
  if (firstAxisParticle < 0)
    throw ParameterError("axis centering first axis particle", std::to_string(firstAxisParticle), "must be >= 0");
  if (axisVertexCount < 2 || (att_.vertexCount() > 0 && att_.axisIndex.maxCoeff() >= axisVertexCount))
    throw ParameterError("axis centering vertex count", std::to_string(axisVertexCount),
                         "must be >= 2 and cover every attached axis index");
}

void AxisCentering::project(Points& p, const Eigen::VectorXd& w) {
  const int n = att_.vertexCount();
  MSK_ASSERT(w.size() == p.rows() && p.rows() >= first_ + n && p.rows() >= firstAxis_ + axisCount_,
             "axis centering: size mismatch");
  const Points surface = p.middleRows(first_, n);
  Points axis = p.middleRows(firstAxis_, axisCount_);
  const Eigen::VectorXd wAxis = w.segment(firstAxis_, axisCount_);
  recenterAxis(surface, axis, att_, gamma_, &wAxis);
  p.middleRows(firstAxis_, axisCount_) = axis;
}

// ------------------------------------------------------------------------------------------------ axis-first stage

namespace {

/// Smallest rotation taking the direction of `from` onto the direction of `to` (identity if either is zero).
Eigen::Matrix3d smallestRotation(const Vec3& from, const Vec3& to) {
  if (!(from.squaredNorm() > 0) || !(to.squaredNorm() > 0)) return Eigen::Matrix3d::Identity();
  return Eigen::Quaterniond::FromTwoVectors(from, to).toRotationMatrix();
}

}  // namespace

Points axisShapeTargets(const Points& q, const Points& ref) {
  const int n = static_cast<int>(q.rows());
  if (ref.rows() != n) throw Error("axisShapeTargets: axis and reference differ in size");
  if (n < 3) throw Error("axisShapeTargets: an open axis needs at least 3 vertices (got " + std::to_string(n) + ")");
  Points t(n, 3);
  auto row = [](const Points& m, int j) -> Vec3 { return m.row(j).transpose(); };
  for (int j = 1; j + 1 < n; ++j) {
    const Vec3 mid = 0.5 * (row(q, j - 1) + row(q, j + 1)), refMid = 0.5 * (row(ref, j - 1) + row(ref, j + 1));
    const Eigen::Matrix3d r = smallestRotation(row(ref, j + 1) - row(ref, j - 1), row(q, j + 1) - row(q, j - 1));
    t.row(j) = (mid + r * (row(ref, j) - refMid)).transpose();
  }
  // Ends: (end, next, next but one) = (0, 1, 2) and (n−1, n−2, n−3).
  for (auto [e, a, b] : {std::tuple{0, 1, 2}, std::tuple{n - 1, n - 2, n - 3}}) {
    const Eigen::Matrix3d r = smallestRotation(row(ref, b) - row(ref, a), row(q, b) - row(q, a));
    t.row(e) = (2.0 * row(q, a) - row(q, b) + r * (row(ref, e) - 2.0 * row(ref, a) + row(ref, b))).transpose();
  }
  return t;
}

GeneralisedCylinder::GeneralisedCylinder(const Points& refSurface, const Points& refAxis, const RadialAttachment& att)
    : refSurface_(refSurface), refAxis_(refAxis), att_(att) {
  checkAttachment(att_, "GeneralisedCylinder");
  const int na = static_cast<int>(refAxis_.rows()), nv = att_.vertexCount();
  if (na < 3) throw Error("GeneralisedCylinder: the axis needs at least 3 vertices (got " + std::to_string(na) + ")");
  if (refSurface_.rows() != nv)
    throw Error("GeneralisedCylinder: " + std::to_string(refSurface_.rows()) +
                " surface vertices for an attachment of " + std::to_string(nv));
  if (nv > 0 && att_.axisIndex.maxCoeff() >= na) throw Error("GeneralisedCylinder: attachment beyond the axis");
  refOffset_.resize(nv, 3);
  carried_ = Eigen::VectorXd::Zero(na);
  for (int v = 0; v < nv; ++v) {
    const int a = att_.axisIndex(v, 0), b = att_.axisIndex(v, 1);
    refOffset_.row(v) =
        refSurface_.row(v) - (att_.weights(v, 0) * refAxis_.row(a) + att_.weights(v, 1) * refAxis_.row(b));
    carried_[a] += att_.weights(v, 0);
    carried_[b] += att_.weights(v, 1);
  }
}

Points GeneralisedCylinder::tangents(const Points& q) {
  const int n = static_cast<int>(q.rows());
  Points t(n, 3);
  for (int j = 0; j < n; ++j) {
    const Eigen::RowVector3d d = q.row(std::min(j + 1, n - 1)) - q.row(std::max(j - 1, 0));
    const double len = d.norm();
    t.row(j) = len > 0 ? Eigen::RowVector3d(d / len) : Eigen::RowVector3d::Zero();
  }
  return t;
}

Points GeneralisedCylinder::surface(const Points& q) const {
  if (q.rows() != refAxis_.rows()) throw Error("GeneralisedCylinder::surface: axis size differs from the reference");
  const Points tRef = tangents(refAxis_), t = tangents(q);
  const int nv = att_.vertexCount();
  Points p(nv, 3);
  for (int v = 0; v < nv; ++v) {
    const int a = att_.axisIndex(v, 0), b = att_.axisIndex(v, 1);
    const double c0 = att_.weights(v, 0), c1 = att_.weights(v, 1);
    const Vec3 from = (c0 * tRef.row(a) + c1 * tRef.row(b)).transpose();
    const Vec3 to = (c0 * t.row(a) + c1 * t.row(b)).transpose();
    const Vec3 foot = (c0 * q.row(a) + c1 * q.row(b)).transpose();
    p.row(v) = (foot + smallestRotation(from, to) * refOffset_.row(v).transpose()).transpose();
  }
  return p;
}

Points GeneralisedCylinder::axisDrive(const Points& d) const {
  const int nv = att_.vertexCount(), na = axisVertexCount();
  if (d.rows() != nv) throw Error("GeneralisedCylinder::axisDrive: displacements differ in size from the surface");
  Points sum = Points::Zero(na, 3);
  for (int v = 0; v < nv; ++v)
    for (int k = 0; k < 2; ++k) sum.row(att_.axisIndex(v, k)) += att_.weights(v, k) * d.row(v);
  for (int j = 0; j < na; ++j)
    sum.row(j) = carried_[j] > 0 ? Eigen::RowVector3d(sum.row(j) / carried_[j]) : Eigen::RowVector3d::Zero();
  return sum;
}

double GeneralisedCylinder::step(Points& q, const Points& d, const AxisFirstOptions& opts) const {
  checkUnitInterval("axis-first image gain", opts.imageGain);
  checkUnitInterval("axis-first shape memory", opts.shapeMemory);
  if (q.rows() != refAxis_.rows()) throw Error("GeneralisedCylinder::step: axis size differs from the reference");
  const Points before = q;
  q += opts.imageGain * axisDrive(d);
  q += opts.shapeMemory * (axisShapeTargets(q, refAxis_) - q);
  return (q - before).rowwise().norm().maxCoeff();
}

}  // namespace msk
