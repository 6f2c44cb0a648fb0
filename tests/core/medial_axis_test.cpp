#include "msk/core/medial_axis.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "msk/core/error.h"
#include "msk/test/shapes.h"

namespace {

using Vec3 = Eigen::Vector3d;

/// A tilted elongated ellipsoid: semi-axis `half` mm along `axis` through `center`, radius `radius` mm across.
struct Tube {
  msk::TriangleMesh mesh;
  Vec3 center, axis;
  double half, radius;
};

Tube makeTube(double half = 40.0, double radius = 10.0, int subdivisions = 4) {
  Tube t;
  t.center = Vec3(12.0, -30.0, 55.0);
  t.axis = Vec3(0.6, -0.3, 0.74).normalized();
  t.half = half;
  t.radius = radius;
  t.mesh = msk::makeIcosphere(1.0, subdivisions);
  const Eigen::Matrix3d rot = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitX(), t.axis).toRotationMatrix();
  Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
  a.topLeftCorner<3, 3>() = rot * Eigen::Vector3d(half, radius, radius).asDiagonal();
  a.topRightCorner<3, 1>() = t.center;
  msk::transformMesh(t.mesh, a);
  return t;
}

double distanceToLine(const Vec3& p, const Vec3& c, const Vec3& d) {
  const Vec3 r = p - c;
  return (r - r.dot(d) * d).norm();
}

using msk::test::uniformVector;

}  // namespace

// An open curve is stored with its ends wrapped, the only k = 1 table simplexMeshProblem() accepts.
TEST(MedialAxis, OpenCurveMeshIsAValidOneSimplex) {
  msk::Points q(4, 3);
  q << 0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0;
  const msk::SimplexMesh m = msk::openCurveMesh(q);
  EXPECT_EQ(m.k, 1);
  EXPECT_EQ(msk::simplexMeshProblem(m), "");
  EXPECT_EQ(m.neighbors(0, 0), 3);
  EXPECT_EQ(m.neighbors(0, 1), 1);
  EXPECT_EQ(m.neighbors(3, 0), 2);
  EXPECT_EQ(m.neighbors(3, 1), 0);
  EXPECT_THROW(msk::openCurveMesh(q.topRows(2)), msk::Error);
}

// (a) The sliced axis of a tilted elongated ellipsoid lies on its true axis (within 0.5 mm), ordered along it.
TEST(MedialAxis, EllipsoidAxisLiesOnTrueAxis) {
  const Tube t = makeTube();
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  ASSERT_EQ(msk::simplexMeshProblem(ax.curve), "");
  EXPECT_EQ(ax.curve.k, 1);
  EXPECT_EQ(ax.curve.vertexCount(), 16);  // 80 mm / 5 mm
  EXPECT_NEAR(ax.lengthMm, 2 * t.half, 1e-6);
  EXPECT_GT(std::fabs(ax.direction.dot(t.axis)), 1.0 - 1e-6);
  EXPECT_LT((ax.center - t.center).norm(), 1e-6);
  double worst = 0, prev = -std::numeric_limits<double>::infinity();
  for (int j = 0; j < ax.curve.vertexCount(); ++j) {
    const Vec3 q = ax.curve.positions.row(j);
    worst = std::max(worst, distanceToLine(q, t.center, t.axis));
    const double s = (q - ax.center).dot(ax.direction);
    EXPECT_GT(s, prev);
    prev = s;
  }
  RecordProperty("axis_error_mm", std::to_string(worst));
  EXPECT_LT(worst, 0.5);

  msk::MedialAxisOptions opts;
  opts.slices = 7;
  EXPECT_EQ(msk::buildMedialAxis(t.mesh, opts).curve.vertexCount(), 7);
  opts.slices = 0;
  opts.spacingMm = 100.0;
  EXPECT_EQ(msk::buildMedialAxis(t.mesh, opts).curve.vertexCount(), 3);  // at least 3
}

// Many slabs on a coarse mesh leave some empty: they are interpolated, and the axis still follows the true one.
TEST(MedialAxis, EmptySlabsAreInterpolated) {
  const Tube t = makeTube(40.0, 10.0, 1);
  msk::MedialAxisOptions opts;
  opts.slices = 40;
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh, opts);
  ASSERT_EQ(ax.curve.vertexCount(), 40);
  EXPECT_TRUE(ax.curve.positions.allFinite());
  for (int j = 0; j < 40; ++j) EXPECT_LT(distanceToLine(ax.curve.positions.row(j), t.center, t.axis), 2.0);
}

// Attachment: weights (1 − t, t) on one segment, r̃ = |Q̄ − P|, and mid-tube radii close to the true ones.
TEST(MedialAxis, AttachmentRecordsProjectionAndRadius) {
  const Tube t = makeTube();
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ax.curve.positions);
  ASSERT_EQ(att.vertexCount(), t.mesh.vertexCount());
  int mid = 0;
  for (int v = 0; v < att.vertexCount(); ++v) {
    EXPECT_EQ(att.axisIndex(v, 1), att.axisIndex(v, 0) + 1);
    EXPECT_GE(att.weights(v, 1), 0.0);
    EXPECT_LE(att.weights(v, 1), 1.0);
    EXPECT_NEAR(att.weights(v, 0) + att.weights(v, 1), 1.0, 1e-12);
    const Vec3 qbar = att.weights(v, 0) * ax.curve.positions.row(att.axisIndex(v, 0)).transpose() +
                      att.weights(v, 1) * ax.curve.positions.row(att.axisIndex(v, 1)).transpose();
    const Vec3 p = t.mesh.vertices.row(v);
    EXPECT_NEAR(att.radius[v], (qbar - p).norm(), 1e-9);
    const double s = (p - t.center).dot(t.axis);
    if (std::fabs(s) < 0.5 * t.half) {  // ellipsoid radius there: r·sqrt(1 − (s/h)²)
      ++mid;
      EXPECT_NEAR(att.radius[v], distanceToLine(p, t.center, t.axis), 0.5);
    }
  }
  EXPECT_GT(mid, 100);
  EXPECT_THROW(msk::attachToAxis(t.mesh.vertices, ax.curve.positions.topRows(1)), msk::Error);
}

// Axis masses carry the surface's mass: Σ M_j = Σ M_v; a fixed surface vertex fixes the axis vertices it touches.
TEST(MedialAxis, AxisInverseMassCarriesSurfaceMass) {
  const Tube t = makeTube();
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ax.curve.positions);
  const int nv = t.mesh.vertexCount(), na = ax.curve.vertexCount();
  Eigen::VectorXd ws = Eigen::VectorXd::Constant(nv, 0.5);
  const Eigen::VectorXd wa = msk::axisInverseMass(att, na, ws);
  ASSERT_EQ(wa.size(), na);
  ASSERT_TRUE((wa.array() > 0).all());
  EXPECT_NEAR(wa.cwiseInverse().sum(), 2.0 * nv, 1e-6 * nv);
  ws[0] = 0;
  const Eigen::VectorXd wf = msk::axisInverseMass(att, na, ws);
  for (int k = 0; k < 2; ++k) {
    if (att.weights(0, k) > 0) {
      EXPECT_EQ(wf[att.axisIndex(0, k)], 0.0);
    }
  }
  EXPECT_THROW(msk::axisInverseMass(att, na, Eigen::VectorXd::Ones(nv - 1)), msk::Error);
}

// (b) The kernel conserves linear momentum and changes Q̄ − P by exactly γC.
TEST(RadialKernel, ConservesLinearMomentum) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> um(0.2, 5.0), ut(0.0, 1.0), ur(1.0, 20.0);
  double worst = 0;
  for (int c = 0; c < 500; ++c) {
    const Vec3 q[2] = {uniformVector(rng, 30.0), uniformVector(rng, 30.0)};
    const double tt = ut(rng), weights[2] = {1.0 - tt, tt};
    const Vec3 p = weights[0] * q[0] + weights[1] * q[1] + uniformVector(rng, 15.0);
    const double r = ur(rng), gamma = ut(rng);
    const double w = 1.0 / um(rng), wq[2] = {1.0 / um(rng), 1.0 / um(rng)};
    Vec3 dp, dq[2];
    ASSERT_TRUE(msk::radialCorrection(p, q, weights, r, w, wq, gamma, dp, dq));
    const Vec3 momentum = dp / w + dq[0] / wq[0] + dq[1] / wq[1];
    const double scale = dp.norm() / w + dq[0].norm() / wq[0] + dq[1].norm() / wq[1];
    ASSERT_GT(scale, 0);
    worst = std::max(worst, momentum.norm() / scale);
    // Q̄ − P moves by γC with C = G − (Q̄ − P).
    const Vec3 pc = weights[0] * q[0] + weights[1] * q[1] - p;
    const Vec3 cvec = r * pc.normalized() - pc;
    const Vec3 pcNew = weights[0] * (q[0] + dq[0]) + weights[1] * (q[1] + dq[1]) - (p + dp);
    EXPECT_LT((pcNew - pc - gamma * cvec).norm(), 1e-9 * (1.0 + pc.norm()));
  }
  EXPECT_LT(worst, 1e-9);
}

// (b) With the axis fixed, one full-stiffness projection lands P at the reference radius.
TEST(RadialKernel, FullStiffnessWithFixedAxisReachesReferenceRadius) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ut(0.0, 1.0), ur(0.5, 20.0), um(0.2, 5.0);
  double worst = 0;
  for (int c = 0; c < 500; ++c) {
    const Vec3 q[2] = {uniformVector(rng, 30.0), uniformVector(rng, 30.0)};
    const double tt = ut(rng), weights[2] = {1.0 - tt, tt}, wq[2] = {0.0, 0.0};
    const Vec3 p = weights[0] * q[0] + weights[1] * q[1] + uniformVector(rng, 15.0);
    const double r = ur(rng);
    Vec3 dp, dq[2];
    ASSERT_TRUE(msk::radialCorrection(p, q, weights, r, 1.0 / um(rng), wq, 1.0, dp, dq));
    EXPECT_EQ(dq[0].norm(), 0.0);
    EXPECT_EQ(dq[1].norm(), 0.0);
    const Vec3 qbar = weights[0] * q[0] + weights[1] * q[1];
    worst = std::max(worst, std::fabs((qbar - (p + dp)).norm() - r));
  }
  EXPECT_LT(worst, 1e-9);
}

// Degenerate input: P on the axis, every particle fixed, non-finite values, γ out of range.
TEST(RadialKernel, RejectsDegenerateInput) {
  const Vec3 q[2] = {Vec3(0, 0, 0), Vec3(10, 0, 0)};
  const double weights[2] = {0.5, 0.5}, wq[2] = {1.0, 1.0}, fixed[2] = {0.0, 0.0};
  Vec3 dp(7, 7, 7), dq[2] = {Vec3(7, 7, 7), Vec3(7, 7, 7)};
  EXPECT_FALSE(msk::radialCorrection(Vec3(5, 0, 0), q, weights, 3.0, 1.0, wq, 1.0, dp, dq));
  EXPECT_FALSE(msk::radialCorrection(Vec3(5, 2, 0), q, weights, 3.0, 0.0, fixed, 1.0, dp, dq));
  EXPECT_FALSE(msk::radialCorrection(Vec3(5, NAN, 0), q, weights, 3.0, 1.0, wq, 1.0, dp, dq));
  EXPECT_FALSE(msk::radialCorrection(Vec3(5, 2, 0), q, weights, NAN, 1.0, wq, 1.0, dp, dq));
  EXPECT_FALSE(msk::radialCorrection(Vec3(5, 2, 0), q, weights, -1.0, 1.0, wq, 1.0, dp, dq));
  EXPECT_FALSE(msk::radialCorrection(Vec3(5, 2, 0), q, weights, 3.0, 1.0, wq, 1.5, dp, dq));
  EXPECT_EQ(dp, Vec3(7, 7, 7));  // outputs untouched
  EXPECT_EQ(dq[0], Vec3(7, 7, 7));
  EXPECT_TRUE(msk::radialCorrection(Vec3(5, 2, 0), q, weights, 3.0, 1.0, wq, 1.0, dp, dq));
}

// (c) A tube squeezed radially to 0.7 recovers its radius under repeated projection with a free axis.
TEST(RadialConstraints, SqueezedTubeRecoversRadius) {
  const Tube t = makeTube(45.0, 10.0, 4);
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ax.curve.positions);
  const int nv = t.mesh.vertexCount(), na = ax.curve.vertexCount();

  // Stacked system: surface particles first, then the axis.
  msk::Points p(nv + na, 3);
  for (int v = 0; v < nv; ++v) {
    const Vec3 x = t.mesh.vertices.row(v);
    const Vec3 r = x - t.center;
    const Vec3 along = r.dot(t.axis) * t.axis;
    p.row(v) = (t.center + along + 0.7 * (r - along)).transpose();
  }
  p.bottomRows(na) = ax.curve.positions;
  // Unit-mass surface; each axis vertex weighs what it carries (a unit-mass axis is thrown off-centre).
  Eigen::VectorXd w = Eigen::VectorXd::Ones(nv + na);
  w.tail(na) = msk::axisInverseMass(att, na, Eigen::VectorXd::Ones(nv));
  ASSERT_TRUE((w.tail(na).array() > 0).all());
  const Eigen::VectorXd mass = w.cwiseInverse();
  const Vec3 momentumBefore = (mass.asDiagonal() * p).colwise().sum().transpose();

  msk::RadialConstraints radial(att, nv, 1.0);
  EXPECT_EQ(radial.name(), "radial");
  radial.setFirstParticle(0);
  for (int it = 0; it < 20; ++it) radial.project(p, w);
  EXPECT_EQ(radial.skipped(), 0);
  // Linear momentum is conserved: the centre of mass does not move.
  EXPECT_LT((((mass.asDiagonal() * p).colwise().sum().transpose() - momentumBefore) / mass.sum()).norm(), 1e-9);

  // Radius of the mid-tube (|s| < half/2) about the true axis, relative to the original.
  double now = 0, orig = 0, axisDrift = 0;
  for (int v = 0; v < nv; ++v) {
    const Vec3 x0 = t.mesh.vertices.row(v);
    if (std::fabs((x0 - t.center).dot(t.axis)) > 0.5 * t.half) continue;
    orig += distanceToLine(x0, t.center, t.axis);
    now += distanceToLine(p.row(v).transpose(), t.center, t.axis);
  }
  for (int j = 0; j < na; ++j) axisDrift = std::max(axisDrift, (p.row(nv + j) - ax.curve.positions.row(j)).norm());
  const double ratio = now / orig;
  EXPECT_NEAR(ratio, 1.0, 0.03);
  EXPECT_LT(axisDrift, 0.5);

  // Every constraint is (nearly) satisfied.
  double worst = 0;
  for (int v = 0; v < nv; ++v) {
    const Vec3 qbar = att.weights(v, 0) * p.row(nv + att.axisIndex(v, 0)).transpose() +
                      att.weights(v, 1) * p.row(nv + att.axisIndex(v, 1)).transpose();
    worst = std::max(worst, std::fabs((qbar - p.row(v).transpose()).norm() - att.radius[v]) / att.radius[v]);
  }
  EXPECT_LT(worst, 0.01);
}

// Re-centring: a surface shifted across the axis drags the axis along, across only (no sliding along the axis).
TEST(RadialConstraints, AxisFollowsShiftedSurface) {
  const Tube t = makeTube();
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ax.curve.positions);
  const Vec3 across = t.axis.unitOrthogonal() * 3.0;
  const msk::Points shifted = t.mesh.vertices.rowwise() + across.transpose();
  msk::Points axis = ax.curve.positions;
  msk::recenterAxis(shifted, axis, att, 1.0);
  for (int j = 0; j < axis.rows(); ++j) {
    const Vec3 moved = (axis.row(j) - ax.curve.positions.row(j)).transpose();
    EXPECT_NEAR(moved.dot(across.normalized()), 3.0, 0.3) << "axis vertex " << j;
    EXPECT_LT(std::fabs(moved.dot(t.axis)), 0.3) << "axis vertex " << j;
  }

  // The same as a constraint set on stacked arrays; a fixed axis vertex stays.
  const int nv = t.mesh.vertexCount(), na = static_cast<int>(axis.rows());
  msk::Points p(nv + na, 3);
  p.topRows(nv) = shifted;
  p.bottomRows(na) = ax.curve.positions;
  Eigen::VectorXd w = Eigen::VectorXd::Ones(nv + na);
  w[nv] = 0;
  msk::AxisCentering centering(att, nv, na, 1.0);
  EXPECT_EQ(centering.name(), "axis-centering");
  centering.project(p, w);
  EXPECT_EQ((p.row(nv) - ax.curve.positions.row(0)).norm(), 0.0);
  EXPECT_LT((p.row(nv + 1) - axis.row(1)).norm(), 1e-12);
}

// (d) Bad parameters throw ParameterError.
TEST(RadialConstraints, BadParametersThrow) {
  const Tube t = makeTube(40.0, 10.0, 2);
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ax.curve.positions);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double g : {-0.1, 1.1, nan}) {
    EXPECT_THROW(msk::RadialConstraints(att, 0, g), msk::ParameterError) << g;
    EXPECT_THROW(msk::AxisCentering(att, 0, ax.curve.vertexCount(), g), msk::ParameterError) << g;
    msk::Points axis = ax.curve.positions;
    EXPECT_THROW(msk::recenterAxis(t.mesh.vertices, axis, att, g), msk::ParameterError) << g;
  }
  msk::RadialConstraints ok(att, 0, 0.5);
  EXPECT_THROW(ok.setGamma(nan), msk::ParameterError);
  EXPECT_THROW(ok.setGamma(-1.0), msk::ParameterError);
  EXPECT_THROW(ok.setFirstAxisParticle(-1), msk::ParameterError);
  EXPECT_DOUBLE_EQ(ok.gamma(), 0.5);
  EXPECT_THROW(msk::RadialConstraints(att, -3, 0.5), msk::ParameterError);

  msk::MedialAxisOptions opts;
  for (double s : {0.0, -5.0, nan, std::numeric_limits<double>::infinity()}) {
    opts.spacingMm = s;
    EXPECT_THROW(msk::buildMedialAxis(t.mesh, opts), msk::ParameterError) << s;
  }
  opts = msk::MedialAxisOptions();
  for (int n : {-1, 1, 2}) {
    opts.slices = n;
    EXPECT_THROW(msk::buildMedialAxis(t.mesh, opts), msk::ParameterError) << n;
  }
  msk::TriangleMesh open = t.mesh;
  open.faces.conservativeResize(open.faceCount() - 1, 3);
  EXPECT_THROW(msk::buildMedialAxis(open), msk::Error);
}

// ------------------------------------------------------------------------------------------------ axis-first stage

namespace {

/// A straight axis of `n` vertices along the tube's true axis, over ±0.9 of its half length.
msk::Points straightAxis(const Tube& t, int n) {
  msk::Points q(n, 3);
  for (int j = 0; j < n; ++j) q.row(j) = (t.center + (-0.9 + 1.8 * j / (n - 1)) * t.half * t.axis).transpose();
  return q;
}

}  // namespace

// The reference axis sweeps the reference surface; a translated axis the translated surface; an axis turned about a
// line across it (no twist) the turned surface.
TEST(GeneralisedCylinder, ReferenceAndRigidAxesSweepTheMovedSurface) {
  const Tube t = makeTube();
  const msk::Points ref = straightAxis(t, 9);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ref);
  const msk::GeneralisedCylinder gc(t.mesh.vertices, ref, att);
  EXPECT_EQ(gc.axisVertexCount(), 9);
  EXPECT_LT((gc.surface(ref) - t.mesh.vertices).cwiseAbs().maxCoeff(), 1e-9);

  const Vec3 shift(2.0, -3.0, 1.5);
  EXPECT_LT((gc.surface(ref.rowwise() + shift.transpose()) - (t.mesh.vertices.rowwise() + shift.transpose()))
                .cwiseAbs()
                .maxCoeff(),
            1e-9);

  const Eigen::Matrix3d rot = Eigen::AngleAxisd(0.3, t.axis.unitOrthogonal()).toRotationMatrix();
  auto turned = [&](const msk::Points& p) {
    return msk::Points(((p.rowwise() - t.center.transpose()) * rot.transpose()).rowwise() + t.center.transpose());
  };
  EXPECT_LT((gc.surface(turned(ref)) - turned(t.mesh.vertices)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_THROW(gc.surface(ref.topRows(5)), msk::Error);
  EXPECT_THROW(msk::GeneralisedCylinder(t.mesh.vertices.topRows(10), ref, att), msk::Error);
  EXPECT_THROW(
      msk::GeneralisedCylinder(t.mesh.vertices, ref.topRows(2), msk::attachToAxis(t.mesh.vertices, ref.topRows(2))),
      msk::Error);
}

// Bending the axis keeps every surface vertex at its reference radius from its attachment point (the radial
// constraints taken as stiff), and moves the middle of the surface with the middle of the axis.
TEST(GeneralisedCylinder, BentAxisKeepsTheReferenceRadii) {
  const Tube t = makeTube();
  const msk::Points ref = straightAxis(t, 11);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ref);
  const msk::GeneralisedCylinder gc(t.mesh.vertices, ref, att);
  const Vec3 across = t.axis.unitOrthogonal();
  msk::Points bent = ref;
  for (int j = 0; j < bent.rows(); ++j) {
    const double u = (j - 5) / 5.0;  // −1 … 1
    bent.row(j) += (6.0 * u * u) * across.transpose();
  }
  const msk::Points p = gc.surface(bent);
  double worst = 0;
  for (int v = 0; v < p.rows(); ++v) {
    const Vec3 foot = att.weights(v, 0) * bent.row(att.axisIndex(v, 0)).transpose() +
                      att.weights(v, 1) * bent.row(att.axisIndex(v, 1)).transpose();
    worst = std::max(worst, std::fabs((p.row(v).transpose() - foot).norm() - att.radius[v]));
  }
  EXPECT_LT(worst, 1e-9);
  // The surface's centroid across the tube follows the axis's: the bend is 6u² mm, its mean over the vertices > 1 mm.
  const double moved = Eigen::RowVector3d((p - t.mesh.vertices).colwise().mean()).dot(across.transpose());
  EXPECT_GT(moved, 1.0);
  EXPECT_LT(moved, 6.0);
}

// The drive of a uniform surface displacement is that displacement at every axis vertex; a step with full image gain
// moves the axis by it (a translation is a fixed point of the axis shape memory), and a gain of ½ by half of it.
TEST(GeneralisedCylinder, UniformDisplacementTranslatesTheAxis) {
  const Tube t = makeTube();
  const msk::MedialAxis ax = msk::buildMedialAxis(t.mesh);
  const msk::RadialAttachment att = msk::attachToAxis(t.mesh.vertices, ax.curve.positions);
  const msk::GeneralisedCylinder gc(t.mesh.vertices, ax.curve.positions, att);
  const Vec3 d(1.0, 2.0, -0.5);
  const msk::Points disp = Eigen::VectorXd::Ones(t.mesh.vertexCount()) * d.transpose();
  const msk::Points drive = gc.axisDrive(disp);
  for (int j = 0; j < drive.rows(); ++j) EXPECT_LT((drive.row(j).transpose() - d).norm(), 1e-12) << j;
  for (double gain : {1.0, 0.5}) {
    msk::Points q = ax.curve.positions;
    msk::AxisFirstOptions o;
    o.imageGain = gain;
    const double move = gc.step(q, disp, o);
    EXPECT_NEAR(move, gain * d.norm(), 1e-9);
    EXPECT_LT(((q - ax.curve.positions).rowwise() - gain * d.transpose()).cwiseAbs().maxCoeff(), 1e-9);
  }
  msk::Points q = ax.curve.positions;
  msk::AxisFirstOptions bad;
  bad.shapeMemory = 1.5;
  EXPECT_THROW(gc.step(q, disp, bad), msk::ParameterError);
  bad = msk::AxisFirstOptions();
  bad.imageGain = -0.1;
  EXPECT_THROW(gc.step(q, disp, bad), msk::ParameterError);
  EXPECT_THROW(gc.axisDrive(disp.topRows(3)), msk::Error);
}

// Axis shape memory: a planar curved reference, translated and turned in its plane, is a fixed point; a kink put into
// it is pulled back (the targets of the kinked vertex lie closer to the reference shape).
TEST(GeneralisedCylinder, AxisShapeMemoryRestoresAKink) {
  const int n = 9;
  msk::Points ref(n, 3);
  for (int j = 0; j < n; ++j) {
    const double a = 0.1 * (j - 4);
    ref.row(j) = Eigen::RowVector3d(60.0 * std::sin(a), 60.0 * (1.0 - std::cos(a)), 5.0);  // arc of radius 60 mm
  }
  const Eigen::Matrix3d rot = Eigen::AngleAxisd(0.4, Vec3::UnitZ()).toRotationMatrix();
  const msk::Points moved = (ref * rot.transpose()).rowwise() + Eigen::RowVector3d(3, -2, 7);
  EXPECT_LT((msk::axisShapeTargets(moved, moved) - moved).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((msk::axisShapeTargets(moved, ref) - moved).cwiseAbs().maxCoeff(), 1e-9);
  msk::Points kinked = ref;
  kinked.row(4) += Eigen::RowVector3d(0, 3.0, 0);
  kinked.row(0) += Eigen::RowVector3d(0, -2.0, 1.0);
  const msk::Points target = msk::axisShapeTargets(kinked, ref);
  EXPECT_LT((target.row(4) - ref.row(4)).norm(), 0.5 * (kinked.row(4) - ref.row(4)).norm());
  EXPECT_LT((target.row(0) - ref.row(0)).norm(), 0.5 * (kinked.row(0) - ref.row(0)).norm());
  EXPECT_THROW(msk::axisShapeTargets(ref.topRows(2), ref.topRows(2)), msk::Error);
  EXPECT_THROW(msk::axisShapeTargets(ref, ref.topRows(5)), msk::Error);
}
