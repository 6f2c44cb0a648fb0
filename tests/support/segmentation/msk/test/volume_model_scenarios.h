#pragma once
/// Volume-model scenarios, shared by tests/segmentation/volume_model_test.cpp (which asserts on them) and
/// bench/volume_model_bench.cpp (which reports their figures): a muscle made volumetric and segmented alone, its
/// template its true surface moved rigidly (the image asks for no change of volume) or also scaled (the image asks for
/// one), measured against the true volume. The muscles: the bundled phantom's, and the left autochthon muscle of
/// totalseg-mr from its own label.
#include <Eigen/Core>
#include <string>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk::test {

/// `mesh` rotated by `angleDeg` about `axis` through its centroid, scaled by `scale` about it, then moved by `offset`.
TriangleMesh movedScaled(const TriangleMesh& mesh, double angleDeg, const Eigen::Vector3d& axis, double scale,
                         const Eigen::Vector3d& offset);

/// The 4×4 map of movedScaled().
Eigen::Matrix4d movedScaledMatrix(const TriangleMesh& mesh, double angleDeg, const Eigen::Vector3d& axis, double scale,
                                  const Eigen::Vector3d& offset);

/// Whether a volume-model run also tetrahedralises the template again for the quality of its tets at rest (the
/// benchmark's figures minDihedralDeg, slivers, invertedSlivers, invertedRestDeg), or leaves those at 0.
enum class RestQuality { Measure, Skip };

/// What one volume-model run measured.
struct VolumeRun {
  int tets = 0, inverted = 0, invertedAtSurface = 0;
  double boundaryOffSurfaceMm = 0;  ///< the furthest a tet boundary node lies from its surface vertex (−1: not matched)
  double minDihedralDeg = 0;        ///< of the tetrahedralised template (RestQuality::Measure)
  int slivers = 0;                  ///< template tets with a dihedral angle under 5° (RestQuality::Measure)
  int invertedSlivers = 0;          ///< inverted tets that were slivers at rest (RestQuality::Measure)
  double invertedRestDeg = 0;       ///< the largest rest min-dihedral angle of an inverted tet (RestQuality::Measure)
  double templateMm3 = 0, modelMm3 = 0, truthMm3 = 0, surfaceMm3 = 0;
  std::string decision;  ///< the volume constraint's decision (ObjectResult::volumeDecision)
  double dice = 0, templateDice = 0, seconds = 0;
  /// Volume change of the model against its template, %.
  double changePercent() const { return 100.0 * (modelMm3 / templateMm3 - 1.0); }
  /// The model's volume against the true object's, %.
  double errorPercent() const { return 100.0 * (modelMm3 / truthMm3 - 1.0); }
  /// The output surface's volume against the true object's, %.
  double surfaceErrorPercent() const { return 100.0 * (surfaceMm3 / truthMm3 - 1.0); }
};

/// Segments `object` (made volumetric) alone in `image` and measures the volume model against label `label` of
/// `labels`, whose object has the volume `truthMm3`.
VolumeRun runVolumeModel(const ImageF& image, SceneObject object, const LabelMap& labels, int label, double truthMm3,
                         const SegmentOptions& opts = {}, RestQuality rest = RestQuality::Measure);

/// A muscle to run as a volume model: its image, labels, scene object (template to be set) and true surface.
struct VolumeCase {
  std::string name;
  ImageF image;
  LabelMap labels;
  SceneObject object;
  TriangleMesh truth;
  bool real = false;  ///< a real scan: the profile force, its profiles learned where the template came from
};

/// A muscle of the bundled phantom ("hamstrings", "quadriceps", "adductors"): its scene object and true surface.
VolumeCase phantomMuscleCase(const std::string& name);

/// The left autochthon muscle of totalseg-mr (label 46) under `sharedData`, its truth the template from its own label,
/// the image cropped around it with 20 mm; the profile force.
VolumeCase realAutochthonCase(const std::string& sharedData);

/// Runs the case's muscle with its true surface moved by (2, −2.5, 1.5) mm and rotated by `angleDeg` about (1, 2, 3),
/// scaled by `scale` (a real case learns its profiles where the template came from: the true place).
VolumeRun runMovedTruth(const VolumeCase& c, double angleDeg, double scale, RestQuality rest = RestQuality::Measure);

/// The volume (mm³) the same muscle reaches as a plain surface model from the same start as runMovedTruth(): where the
/// image forces alone take it, which a volume model that follows the image should reach too.
double surfaceModelMovedTruthMm3(const VolumeCase& c, double angleDeg, double scale);

}  // namespace msk::test
