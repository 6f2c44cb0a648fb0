#include "phantom_model.h"

#include <algorithm>
#include <cmath>

#include "msk/core/error.h"
#include "msk/phantom/phantom.h"

namespace msk::phantom {

namespace {

constexpr double kDeg = M_PI / 180.0;

double smoothstep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a[0] * b[1] - a[1] * b[0]; }

// Angular width (degrees, in [0, 360)) of compartment m: from its first septum counter-clockwise to its last.
double sectorWidthDeg(const Anatomy& a, int m) {
  double w = a.septumAngleDeg[static_cast<size_t>(a.muscleLastSeptum[static_cast<size_t>(m)])] -
             a.septumAngleDeg[static_cast<size_t>(a.muscleFirstSeptum[static_cast<size_t>(m)])];
  return std::fmod(std::fmod(w, 360.0) + 360.0, 360.0);
}

}  // namespace

double Random::normal() {
  if (hasSpare_) {
    hasSpare_ = false;
    return spare_;
  }
  const double u1 = uniform(), u2 = uniform();
  const double r = std::sqrt(-2.0 * std::log(u1)), t = 2.0 * M_PI * u2;
  spare_ = r * std::sin(t);
  hasSpare_ = true;
  return r * std::cos(t);
}

Model::Model(const Anatomy& a) : a_(a) {
  if (a_.muscles < 2 || a_.muscles > kMaxMuscles)
    throw ParameterError("muscles", std::to_string(a_.muscles), "must be in [2, " + std::to_string(kMaxMuscles) + "]");
  for (int m = 0; m < a_.muscles; ++m) {
    const size_t mm = static_cast<size_t>(m);
    for (int septum : {a_.muscleFirstSeptum[mm], a_.muscleLastSeptum[mm]})
      if (septum < 0 || septum >= a_.muscles)
        throw ParameterError("muscleFirstSeptum/muscleLastSeptum", std::to_string(septum),
                             "must be a septum index in [0, muscles)");
    convex_[mm] = sectorWidthDeg(a_, m) <= 180.0;
  }
  // Skin: the smallest elliptic cylinder (about the straight part of the axis) that keeps at least fatX/fatY of
  // fat around the envelope at every z.
  double needX = 0, needY = 0;
  for (double z = a_.envelopeCentreZ - a_.envelopeHalfLength; z <= a_.envelopeCentreZ + a_.envelopeHalfLength;
       z += 0.5) {
    const Slice s = slice(z);
    const double k = std::sqrt(std::max(0.0, 1.0 - s.envU * s.envU));
    needX = std::max(needX, std::fabs(s.envCentre[0] - s.skinCentre[0]) + s.envA * k);
    needY = std::max(needY, std::fabs(s.envCentre[1] - s.skinCentre[1]) + s.envB * k);
  }
  skinX_ = needX + a_.fatX;
  skinY_ = needY + a_.fatY;
}

Eigen::Vector2d Model::femurAxis(double z) const {
  const double t = z / a_.bowHalfLength;
  return a_.femurBase + a_.femurTilt * z + a_.femurBow * (1.0 - t * t);
}

double Model::flareFraction(double z) const { return smoothstep(1.0 - (z - a_.femurBottom) / a_.flareLength); }

double Model::femurRadius(double z) const {
  return a_.shaftRadius + a_.radiusWave * std::sin(2 * M_PI * z / 160.0 + a_.radiusWavePhase) +
         a_.flare * flareFraction(z);
}

Slice Model::slice(double z) const {
  Slice s;
  s.z = z;
  s.axis = femurAxis(z);
  const double zc = std::clamp(z, a_.femurBottom, a_.femurTop);
  s.capAxis = femurAxis(zc);
  s.capDz = z - zc;
  s.radius = femurRadius(zc);
  const double f = flareFraction(zc);
  s.marrowRadius = s.radius * (a_.marrowRatio + (a_.marrowRatioFlare - a_.marrowRatio) * f);

  const double u = (z - a_.envelopeCentreZ) / a_.envelopeHalfLength;
  s.envU = u;
  const double scale = 1.0 + a_.envelopeTaper * std::clamp(u, -1.5, 1.5) +
                       a_.envelopeWave * std::sin(1.5 * M_PI * u + a_.envelopeWavePhase);
  s.envA = a_.envelopeRadiusX * scale;
  s.envB = a_.envelopeRadiusY * scale;
  s.envScale = std::min(s.envA, s.envB);
  s.envCentre = s.axis + a_.envelopeOffset * std::max(0.0, 1.0 - u * u);

  const double twist = a_.twistDeg * std::clamp(u, -1.5, 1.5);
  for (size_t i = 0; i < static_cast<size_t>(a_.muscles); ++i) {
    const double th = (a_.septumAngleDeg[i] + twist) * kDeg;
    s.septumDir[i] = Eigen::Vector2d(std::cos(th), std::sin(th));
    const double lo = a_.septumMissing[i][0], hi = a_.septumMissing[i][1];
    double missing = 0;
    if (hi > lo) missing = smoothstep((z - lo) / a_.septumRamp + 0.5) * smoothstep((hi - z) / a_.septumRamp + 0.5);
    s.septumHalf[i] = a_.septumHalfThickness * (1.0 - missing);
  }
  s.skinCentre = a_.femurBase + a_.femurTilt * z + 0.7 * a_.femurBow + a_.envelopeOffset;
  return s;
}

double Model::femur(const Slice& s, const Eigen::Vector3d& p) const {
  const Eigen::Vector2d q = p.head<2>() - s.capAxis;
  return std::sqrt(q.squaredNorm() + s.capDz * s.capDz) - s.radius;
}

double Model::marrow(const Slice& s, const Eigen::Vector3d& p) const {
  const Eigen::Vector2d q = p.head<2>() - s.capAxis;
  return std::sqrt(q.squaredNorm() + s.capDz * s.capDz) - s.marrowRadius;
}

double Model::envelope(const Slice& s, const Eigen::Vector3d& p) const {
  const double x = (p[0] - s.envCentre[0]) / s.envA, y = (p[1] - s.envCentre[1]) / s.envB;
  return (std::sqrt(x * x + y * y + s.envU * s.envU) - 1.0) * s.envScale;
}

double Model::sector(const Slice& s, int m, const Eigen::Vector3d& p) const {
  const size_t mm = static_cast<size_t>(m);
  const size_t a = static_cast<size_t>(a_.muscleFirstSeptum[mm]), b = static_cast<size_t>(a_.muscleLastSeptum[mm]);
  const Eigen::Vector2d q = p.head<2>() - s.axis;
  const double fa = s.septumHalf[a] - cross2(s.septumDir[a], q);  // < 0 on the counter-clockwise side of septum a
  const double fb = s.septumHalf[b] - cross2(q, s.septumDir[b]);  // < 0 on the clockwise side of septum b
  return convex_[mm] ? std::max(fa, fb) : std::min(fa, fb);
}

double Model::muscle(const Slice& s, int m, const Eigen::Vector3d& p) const {
  return std::max({envelope(s, p), a_.gap - femur(s, p), sector(s, m, p)});
}

double Model::skinInner(const Slice& s, const Eigen::Vector3d& p) const {
  const double x = (p[0] - s.skinCentre[0]) / skinX_, y = (p[1] - s.skinCentre[1]) / skinY_;
  return (std::sqrt(x * x + y * y) - 1.0) * std::min(skinX_, skinY_);
}

double Model::skinOuter(const Slice& s, const Eigen::Vector3d& p) const {
  const double ax = skinX_ + a_.skinThickness, ay = skinY_ + a_.skinThickness;
  const double x = (p[0] - s.skinCentre[0]) / ax, y = (p[1] - s.skinCentre[1]) / ay;
  return (std::sqrt(x * x + y * y) - 1.0) * std::min(ax, ay);
}

PointClass Model::classify(const Eigen::Vector3d& p) const {
  const Slice s = slice(p[2]);
  PointClass c;
  const double fem = femur(s, p);
  if (fem < 0) {
    const double mar = marrow(s, p);
    c.label = 1;
    c.tissue = static_cast<int32_t>(mar < 0 ? PhantomTissue::Marrow : PhantomTissue::Cortex);
    c.bound = std::min(-fem, std::fabs(mar));
    return c;
  }
  const double so = skinOuter(s, p);
  if (so > 0) {
    c.tissue = static_cast<int32_t>(PhantomTissue::Air);
    c.bound = std::min(so, fem);
    return c;
  }
  const double si = skinInner(s, p);
  if (si > 0) {
    c.tissue = static_cast<int32_t>(PhantomTissue::Skin);
    c.bound = std::min({-so, si, fem});
    return c;
  }
  const double env = envelope(s, p);
  c.bound = std::min(-si, fem);
  c.tissue = static_cast<int32_t>(PhantomTissue::Fat);
  if (env - a_.gap > c.bound) {  // far outside the envelope: subcutaneous fat
    c.bound = std::min(c.bound, env);
    return c;
  }
  const double boneGap = a_.gap - fem;
  for (int m = 0; m < a_.muscles; ++m) {
    const double f = std::max({env, boneGap, sector(s, m, p)});
    c.bound = std::min(c.bound, std::fabs(f));
    if (f < 0) {
      c.label = m + 2;
      c.tissue = static_cast<int32_t>(PhantomTissue::Muscle);
    }
  }
  if (c.label >= 2) {
    for (const Streak& st : a_.streaks) {
      if (st.muscle != c.label - 2) continue;
      const Eigen::Vector3d d = p - st.centre;
      const double patch = (std::sqrt((d[0] * d[0] + d[1] * d[1]) / (st.patchRadiusXY * st.patchRadiusXY) +
                                      d[2] * d[2] / (st.patchRadiusZ * st.patchRadiusZ)) -
                            1.0) *
                           st.patchRadiusXY;
      if (patch > c.bound) continue;
      const double sheet = std::fabs((p - st.sphereCentre).norm() - st.sphereRadius) - st.halfThickness;
      const double f = std::max(patch, sheet);
      c.bound = std::min(c.bound, std::fabs(f));
      if (f < 0) c.tissue = static_cast<int32_t>(PhantomTissue::IntramuscularFat);
    }
  }
  return c;
}

std::array<Eigen::Vector3d, 2> Model::objectBounds(int object) const {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = Eigen::Vector3d::Constant(-INFINITY);
  if (object == 0) {
    const double rb = femurRadius(a_.femurBottom), rt = femurRadius(a_.femurTop);
    for (double z = a_.femurBottom - rb; z <= a_.femurTop + rt + 0.25; z += 0.5) {
      const Slice s = slice(std::min(z, a_.femurTop + rt));
      const double r = std::max(s.radius, 0.0);
      lo.head<2>() = lo.head<2>().cwiseMin(s.capAxis - Eigen::Vector2d::Constant(r));
      hi.head<2>() = hi.head<2>().cwiseMax(s.capAxis + Eigen::Vector2d::Constant(r));
    }
    lo[2] = a_.femurBottom - rb;
    hi[2] = a_.femurTop + rt;
    return {lo, hi};
  }
  const double z0 = a_.envelopeCentreZ - a_.envelopeHalfLength, z1 = a_.envelopeCentreZ + a_.envelopeHalfLength;
  for (double z = z0; z <= z1 + 0.25; z += 0.5) {
    const Slice s = slice(std::min(z, z1));
    const double k = std::sqrt(std::max(0.0, 1.0 - s.envU * s.envU));
    const Eigen::Vector2d r(s.envA * k, s.envB * k);
    lo.head<2>() = lo.head<2>().cwiseMin(s.envCentre - r);
    hi.head<2>() = hi.head<2>().cwiseMax(s.envCentre + r);
  }
  lo[2] = z0;
  hi[2] = z1;
  return {lo, hi};
}

Anatomy drawAnatomy(uint32_t seed) {
  Random rng(seed);
  Anatomy a;
  perturbAnatomy(a, rng);
  return a;
}

void perturbAnatomy(Anatomy& a, Random& rng) {
  a.femurBase += rng.uniform2(-4, 4, -4, 4);
  a.femurTilt += rng.uniform2(-0.02, 0.02, -0.02, 0.02);
  a.femurBow += rng.uniform2(-1.5, 1.5, -2, 2);
  a.femurBottom += rng.uniform(-3, 3);
  a.femurTop += rng.uniform(-3, 3);
  a.shaftRadius += rng.uniform(-0.8, 0.8);
  a.radiusWavePhase = rng.uniform(0, 2 * M_PI);
  a.flare += rng.uniform(-1, 1);
  a.flareLength += rng.uniform(-5, 5);
  a.envelopeOffset += rng.uniform2(-2, 2, -2, 2);
  a.envelopeCentreZ += rng.uniform(-3, 3);
  a.envelopeHalfLength += rng.uniform(-3, 3);
  a.envelopeRadiusX += rng.uniform(-2, 2);
  a.envelopeRadiusY += rng.uniform(-2, 2);
  a.envelopeTaper += rng.uniform(-0.03, 0.03);
  a.envelopeWavePhase = rng.uniform(0, 2 * M_PI);
  for (int i = 0; i < a.muscles; ++i) a.septumAngleDeg[static_cast<size_t>(i)] += rng.uniform(-10, 10);
  a.twistDeg += rng.uniform(-8, 8);
  // Each septum is missing over one stretch of 20–40 % of the muscles' length.
  const double len = 2 * a.envelopeHalfLength;
  for (int i = 0; i < a.muscles; ++i) {
    auto& gap = a.septumMissing[static_cast<size_t>(i)];
    const double l = rng.uniform(0.2, 0.4) * len;
    const double lo =
        rng.uniform(a.envelopeCentreZ - 0.8 * a.envelopeHalfLength, a.envelopeCentreZ + 0.8 * a.envelopeHalfLength - l);
    gap = {lo, lo + l};
  }
  a.fatX += rng.uniform(-2, 2);
  a.fatY += rng.uniform(-2, 2);

  // Intramuscular fat: two sheets per compartment, roughly parallel to the envelope.
  const Model model(a);
  for (int m = 0; m < a.muscles; ++m) {
    const double th0 = a.septumAngleDeg[static_cast<size_t>(a.muscleFirstSeptum[static_cast<size_t>(m)])];
    const double w = sectorWidthDeg(a, m);
    for (int k = 0; k < 2; ++k) {
      Streak st;
      st.muscle = m;
      const double z = a.envelopeCentreZ + rng.uniform(-0.5, 0.5) * a.envelopeHalfLength;
      const Slice s = model.slice(z);
      const double th = (th0 + a.twistDeg * s.envU + (0.25 + 0.5 * rng.uniform()) * w) * kDeg;
      const Eigen::Vector2d dir(std::cos(th), std::sin(th));
      // Envelope radius along the ray from the femur axis (bisection on the envelope function).
      double rin = s.radius + a.gap, rout = 3 * a.envelopeRadiusX;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (rin + rout);
        const Eigen::Vector2d xy = s.axis + mid * dir;
        (model.envelope(s, Eigen::Vector3d(xy[0], xy[1], z)) < 0 ? rin : rout) = mid;
      }
      const double r0 = s.radius + a.gap;
      const double r = r0 + rng.uniform(0.3, 0.7) * std::max(0.0, rin - r0);
      const Eigen::Vector2d xy = s.axis + r * dir;
      st.centre = Eigen::Vector3d(xy[0], xy[1], z);
      const double tilt = rng.uniform(-35, 35) * kDeg;
      Eigen::Vector3d n(std::cos(th + tilt), std::sin(th + tilt), rng.uniform(-0.3, 0.3));
      n.normalize();
      st.sphereRadius = rng.uniform(40, 90);
      st.sphereCentre = st.centre + (rng.uniform() < 0.5 ? 1.0 : -1.0) * st.sphereRadius * n;
      st.patchRadiusXY = rng.uniform(8, 14);
      st.patchRadiusZ = rng.uniform(20, 40);
      a.streaks.push_back(st);
    }
  }
}

}  // namespace msk::phantom
