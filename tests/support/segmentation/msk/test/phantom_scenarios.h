#pragma once
/// Phantom scenarios, shared by the segmentation tests (which assert on them) and bench/phantom_bench.cpp (which
/// reports their figures): the femur of the bundled phantom and of five other phantoms segmented from the mean
/// template, and the whole thigh scene (femur and three muscle compartments with their collision pairs) on the bundled
/// phantom and on the other five.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "msk/phantom/phantom.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk::test {

/// One phantom of the acceptance scenarios: its seed, voxel size (mm) and grid rotation (degrees about x, y, z).
struct PhantomCase {
  uint32_t seed = 1;
  Eigen::Vector3d spacing = Eigen::Vector3d(1.2, 1.2, 3.0), oblique = Eigen::Vector3d::Zero();
  /// "seed 3 (1.2x1.2x3, oblique 10,-15,20)".
  std::string name() const;
};

/// The five phantoms besides the bundled one (seed 1): seeds 2–6 on anisotropic and oblique grids.
const std::vector<PhantomCase>& otherPhantomCases();

/// The phantom of a case.
Phantom makeCasePhantom(const PhantomCase& c);

/// A femur to segment: the image, the exact labels (femur = 1), the truth surface and the mean template.
struct FemurCase {
  std::string name;
  ImageF image;
  LabelMap labels;
  TriangleMesh truth, templ;
};

/// The femur of the bundled phantom data-samples/thigh-seed1.
FemurCase bundledFemur();
/// The femur of a phantom case.
FemurCase phantomFemur(const PhantomCase& c);

/// A scene of the femur alone (label 1, bone) from `templ`.
Scene femurScene(const TriangleMesh& templ);

/// Whether a scenario also scores the templates against the truth surfaces (the benchmarks' starting figures), or
/// leaves those scores at 0.
enum class TemplateScores { Measure, Skip };

/// A femur run scored against the truth.
struct FemurScore {
  SegmentationMetrics labels;  ///< result labels against the exact labels
  SegmentationMetrics mesh;    ///< result surface against the truth surface
  SegmentationMetrics start;   ///< the template against the truth surface (TemplateScores::Measure)
  ObjectQuality quality;       ///< the run's quality check of the femur
  double seconds = 0;          ///< the segmentation
};

/// Segments the femur from `templ` (the case's template if empty) and scores it.
FemurScore segmentFemur(const FemurCase& c, const SegmentOptions& opts = {}, const TriangleMesh* templ = nullptr,
                        TemplateScores scores = TemplateScores::Measure);

/// The bundled thigh scene: image, exact labels (1 femur, 2 quadriceps, 3 hamstrings, 4 adductors) and scene.json.
struct BundledThigh {
  ImageF image;
  LabelMap labels;
  Scene scene;
};
BundledThigh loadBundledThigh();

/// A run of the bundled thigh scene, with Dice and ASSD (mm) of labels 1–4 against the exact labels.
struct ThighRun {
  SegmentationResult res;
  double dice[4] = {0, 0, 0, 0};
  double assd[4] = {0, 0, 0, 0};
};

/// Segments `scene` (the bundled scene or a variant of it) in the bundled image and scores labels 1–4.
ThighRun segmentThigh(const BundledThigh& thigh, const Scene& scene, const SegmentOptions& opts);

/// A collision response for every pair of the bundled thigh scene: each pair's mode, and the run's resolution.
struct ThighCollisionCase {
  const char* name;
  CollisionMode mode;
  CollisionResolution resolution;
};
/// Velocity mode resolved sequentially, and position mode resolved globally (both with the spring target).
const std::vector<ThighCollisionCase>& thighCollisionCases();

/// One object of the thigh scene on a phantom case.
struct ThighObjectScore {
  std::string name;
  double dice = 0;          ///< labels against the exact labels
  double meshAssd = 0;      ///< result surface against the truth surface, mm
  double templateAssd = 0;  ///< the template against the truth surface, mm (TemplateScores::Measure)
  ObjectQuality quality;    ///< the run's quality check of the object
};

/// The thigh scene of a phantom case (its touching pairs as collision pairs), default settings, scored.
struct ThighSceneScore {
  size_t objectsInScene = 0, collisionPairs = 0;
  std::vector<ThighObjectScore> objects;
  double meanAssd = 0;       ///< mean of the objects' mesh ASSD, mm
  size_t overlapVoxels = 0;  ///< voxels inside two output surfaces
  long overlapVoxelsRepaired = 0;
  double deepestMm = 0;  ///< deepest vertex inside a partner over every pair
  /// Mean distance (mm) from the muscles' truth vertices to their result surface where the fat septum between two
  /// muscles is missing (muscle 1.5 mm outside the truth vertex along its normal), and elsewhere; vertex counts.
  double septaMissingMm = 0, septaOtherMm = 0;
  int septaMissingVertices = 0, septaOtherVertices = 0;
  double seconds = 0;
};
ThighSceneScore segmentPhantomThigh(const PhantomCase& c, TemplateScores scores = TemplateScores::Measure);

}  // namespace msk::test
