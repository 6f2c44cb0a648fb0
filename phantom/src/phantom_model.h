#pragma once
// Private to the phantoms (phantom.cpp, multi_phantom.cpp): a limb's anatomy (one bone, a ring of muscle compartments
// separated by septa, fat, skin) as implicit functions of position (RAS mm, +x lateral).
// Every structure is a signed-distance-like function, negative inside, Lipschitz constant close to 1,
// so |f| is (nearly) a lower bound on the distance to its surface.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <random>
#include <vector>

namespace msk::phantom {

/// Deterministic random numbers: mt19937 with our own uniform and Box–Muller normal conversions,
/// so sequences do not depend on the standard library's distribution implementations.
class Random {
 public:
  /// Seeds the engine.
  explicit Random(uint32_t seed) : gen_(seed) {}
  /// Uniform in the open interval (0, 1).
  double uniform() { return (static_cast<double>(gen_()) + 0.5) / 4294967296.0; }
  /// Uniform in (a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// Standard normal (Box–Muller, both values of a pair used in turn).
  double normal();
  /// (uniform(a0, b0), uniform(a1, b1)), the second drawn first: every compiler then makes the same anatomy for a
  /// seed (the order of a call's arguments is unspecified), the one the bundled samples were made with.
  Eigen::Vector2d uniform2(double a0, double b0, double a1, double b1) {
    const double y = uniform(a1, b1);
    return {uniform(a0, b0), y};
  }
  /// Three standard normals, the last drawn first (as uniform2()).
  Eigen::Vector3d normal3() {
    const double z = normal(), y = normal();
    return {normal(), y, z};
  }

 private:
  std::mt19937 gen_;
  bool hasSpare_ = false;
  double spare_ = 0;
};

/// Largest number of muscle compartments of a limb (there are as many septa as compartments).
constexpr int kMaxMuscles = 8;

/// A thin curved fat sheet inside one muscle: the part of a sphere's surface inside an ellipsoidal patch.
struct Streak {
  int muscle = 0;                                    ///< compartment index 0..Anatomy::muscles-1
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< patch centre (on the sheet)
  Eigen::Vector3d sphereCentre = Eigen::Vector3d::Zero();
  double sphereRadius = 60;                      ///< sheet curvature radius, mm
  double halfThickness = 0.5;                    ///< mm
  double patchRadiusXY = 10, patchRadiusZ = 30;  ///< patch ellipsoid semi-axes, mm
};

/// Parameters of one limb segment. Anatomy{} is the mean thigh of the thigh phantom (templates); drawAnatomy()
/// perturbs it.
struct Anatomy {
  // Femur: capsule around a bent centreline c(z) = base + tilt·z + bow·(1 − (z/bowHalfLength)²).
  Eigen::Vector2d femurBase{5, 3};               ///< centreline xy at z = 0, mm
  Eigen::Vector2d femurTilt{0.04, 0.0};          ///< dxy/dz (shaft slightly lateral superiorly)
  Eigen::Vector2d femurBow{0.0, 3.0};            ///< anterior bow at z = 0, mm
  double bowHalfLength = 90;                     ///< mm
  double femurBottom = -72, femurTop = 74;       ///< z of the capsule's end-cap centres, mm
  double shaftRadius = 13.0;                     ///< outer cortical radius of the shaft, mm
  double radiusWave = 0.6, radiusWavePhase = 0;  ///< R += wave·sin(2πz/160 mm + phase)
  double flare = 4.5, flareLength = 40.0;  ///< distal metaphysis: extra radius at femurBottom, fading over flareLength
  double marrowRatio = 0.55, marrowRatioFlare = 0.72;  ///< marrow radius / outer radius in shaft and metaphysis
  double gap = 1.0;                                    ///< periosteal fat between bone and muscles, mm
  // Muscle envelope: fusiform ellipsoid-like, centre e(z) = c(z) + offset·(1 − u²), u = (z − centreZ)/halfLength.
  Eigen::Vector2d envelopeOffset{-5, -3};               ///< envelope centre minus femur axis at the middle, mm
  double envelopeCentreZ = 0, envelopeHalfLength = 74;  ///< mm
  double envelopeRadiusX = 48, envelopeRadiusY = 42;    ///< cross-section semi-axes at the middle, mm
  double envelopeTaper = 0.10;                          ///< radii × (1 + taper·u): wider proximally
  double envelopeWave = 0.04, envelopeWavePhase = 0;    ///< radii × (1 + wave·sin(1.5πu + phase))
  // Septa: half-planes radiating from the femur axis, angle from +x (lateral) towards +y (anterior). The thigh's are
  // 0 lateral (quadriceps|hamstrings), 1 medial (quadriceps|adductors), 2 posterior (adductors|hamstrings).
  int muscles = 3;                                                ///< compartments (= septa), at most kMaxMuscles
  std::array<double, kMaxMuscles> septumAngleDeg{-40, 150, 245};  ///< at u = 0
  /// Compartment m spans counter-clockwise from septum muscleFirstSeptum[m] to septum muscleLastSeptum[m]
  /// (thigh: 0 quadriceps, 1 hamstrings, 2 adductors).
  std::array<int, kMaxMuscles> muscleFirstSeptum{0, 2, 1};
  std::array<int, kMaxMuscles> muscleLastSeptum{1, 0, 2};  ///< see muscleFirstSeptum
  double twistDeg = 10;                                    ///< common rotation added at u = +1 (subtracted at u = −1)
  double septumHalfThickness = 0.7;                        ///< mm
  std::array<std::array<double, 2>, kMaxMuscles>
      septumMissing{};      ///< z interval [lo, hi] without septum (none if lo ≥ hi)
  double septumRamp = 5.0;  ///< mm over which a septum fades in and out
  // Subcutaneous fat and skin: elliptic cylinder around the envelope.
  double fatX = 10, fatY = 10;  ///< minimum fat thickness along x and y, mm
  double skinThickness = 1.5;   ///< mm
  std::vector<Streak> streaks;  ///< intramuscular fat
};

/// Draws a seeded anatomy: the mean Anatomy{} perturbed by perturbAnatomy().
Anatomy drawAnatomy(uint32_t seed);

/// Perturbs an anatomy in place with uniform offsets (positions, bend, radii, septa, twist), one missing stretch per
/// septum and two fat streaks per muscle, drawing from `rng`.
void perturbAnatomy(Anatomy& a, Random& rng);

/// Everything that depends on z only, evaluated once per z.
struct Slice {
  double z = 0;
  Eigen::Vector2d axis;                                ///< femur centreline c(z)
  Eigen::Vector2d capAxis;                             ///< c(clamp(z)) for the capsule
  double capDz = 0;                                    ///< z − clamp(z, bottom, top)
  double radius = 0, marrowRadius = 0;                 ///< at clamp(z)
  Eigen::Vector2d envCentre;                           ///< envelope centre
  double envA = 1, envB = 1, envU = 0, envScale = 1;   ///< semi-axes, normalised z, min(a, b)
  std::array<Eigen::Vector2d, kMaxMuscles> septumDir;  ///< unit directions of the septa
  std::array<double, kMaxMuscles> septumHalf{};        ///< half-thicknesses (0 where missing)
  Eigen::Vector2d skinCentre;                          ///< skin cylinder axis
};

/// What a point is made of.
struct PointClass {
  int32_t label = 0;   ///< object label (0, bone 1, muscles 2..muscles+1)
  int32_t tissue = 0;  ///< PhantomTissue value
  double bound = 0;    ///< lower bound (up to the Lipschitz factor) on the distance to the nearest tissue boundary, mm
};

/// Evaluates an Anatomy: implicit functions, labels, tissue classes, bounding boxes.
class Model {
 public:
  /// Derives the skin size and sector widths. Throws ParameterError if a.muscles is not in [2, kMaxMuscles].
  explicit Model(const Anatomy& a);
  /// The anatomy.
  const Anatomy& anatomy() const { return a_; }
  /// z-dependent quantities.
  Slice slice(double z) const;
  /// Outer femur surface (negative inside).
  double femur(const Slice& s, const Eigen::Vector3d& p) const;
  /// Marrow cavity.
  double marrow(const Slice& s, const Eigen::Vector3d& p) const;
  /// Muscle envelope.
  double envelope(const Slice& s, const Eigen::Vector3d& p) const;
  /// Angular sector of compartment m, thinned by half the septa.
  double sector(const Slice& s, int m, const Eigen::Vector3d& p) const;
  /// Muscle compartment m (envelope ∩ outside bone+gap ∩ sector); label m + 2.
  double muscle(const Slice& s, int m, const Eigen::Vector3d& p) const;
  /// Object function: object 0 = bone, 1..muscles = muscle object−1.
  double object(int object, const Slice& s, const Eigen::Vector3d& p) const {
    return object == 0 ? femur(s, p) : muscle(s, object - 1, p);
  }
  /// Skin outer and inner (fat) boundaries.
  double skinOuter(const Slice& s, const Eigen::Vector3d& p) const;
  double skinInner(const Slice& s, const Eigen::Vector3d& p) const;
  /// Label, tissue and boundary-distance bound at p (computes its own slice).
  PointClass classify(const Eigen::Vector3d& p) const;
  /// World bounding box {min, max} of an object (same numbering as object()), without margin.
  std::array<Eigen::Vector3d, 2> objectBounds(int object) const;
  /// Lipschitz safety factor of all functions (|f| / factor ≤ distance).
  static constexpr double kLipschitz = 1.35;
  /// Skin semi-axes (outer surface).
  double skinRadiusX() const { return skinX_ + a_.skinThickness; }
  double skinRadiusY() const { return skinY_ + a_.skinThickness; }

 private:
  Eigen::Vector2d femurAxis(double z) const;
  double femurRadius(double z) const;
  double flareFraction(double z) const;
  Anatomy a_;
  double skinX_ = 0, skinY_ = 0;  // fat boundary semi-axes (skin inner surface)
  std::array<bool, kMaxMuscles> convex_{};
};

}  // namespace msk::phantom
