#pragma once
/// Real-scan scenarios on ../shared/data (totalseg-ct, totalseg-mr), shared by the segmentation tests (which assert on
/// them) and bench/real_scans_bench.cpp (which reports their figures). Every template is built from the contralateral
/// label, mirrored across the sagittal plane through a midline landmark, and (in the scenes) displaced by 3 mm and
/// scaled by ±3 % (a template is never exactly in place); the profile force learns each object's profiles on the
/// structure its template came from. Scores are taken on the full grid against the reference labels
/// (TotalSegmentator's).
#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk::test {

/// One object of a real scene: the label to find and the label its template is built from (the other side's, or its
/// own for a midline structure).
struct ObjectSpec {
  const char* name;
  int label;
  int templateFrom;
  ObjectKind kind;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  ///< rigid motion applied to the mirrored template (world mm)
  /// false: the template is built from `templateFrom` where it lies, not mirrored (its profiles are still learned on
  /// the mirror image of where it came from, the contralateral structure)
  bool mirror = true;
};

/// How far every scene template is moved (mm); per object its direction and scale are fixed (deterministic runs).
constexpr double kDisplacementMm = 3.0;

/// A scene ready to run: the cropped image, the full reference labels and the scene with its perturbed templates.
struct RealScene {
  ImageF image;        ///< cropped to the templates' box plus the margin
  LabelMap reference;  ///< full grid
  Scene scene;
};

/// Builds the scene: contralateral templates (mirrored across x = midX, `vertices` each), displaced by `displacementMm`
/// along fixed directions and scaled by 1.03 / 0.97 in turn (none if `displacementMm` is 0), every object with the
/// profile force learning its profiles on the contralateral structure (profileSource), and the image cropped around
/// the templates and their sources with `marginMm` (the sources must lie in the image).
RealScene makeRealScene(const ImageF& image, const LabelMap& labels, const std::vector<ObjectSpec>& specs, double midX,
                        const std::vector<std::pair<int, int>>& pairs, int vertices = 3000,
                        double displacementMm = kDisplacementMm, double marginMm = 20);

/// Scores of one object: the template alone and the result, against the reference label (full grid).
struct ObjectScore {
  std::string name;
  int label = 0;
  SegmentationMetrics before, after;
};

/// Scores of a run.
struct SceneScore {
  std::vector<ObjectScore> objects;
  size_t overlapVoxels = 0;
  double maxPenetrationMm = 0;
  double seconds = 0;
  SegmentationResult result;
};

/// Segments the scene and scores every object (each surface rasterised alone on the full grid).
SceneScore runRealScene(const RealScene& rs, const SegmentOptions& opts);

/// Gives each 26-connected component of `label` with at least `minVoxels` voxels its own label firstLabel,
/// firstLabel + 1, ... (largest first); returns how many. Smaller components keep `label`.
int splitComponents(LabelMap& labels, int label, int firstLabel, size_t minVoxels);

/// How well the mirrored contralateral label can match at best: the Dice against label `to` of label `from` mirrored
/// across x = midX, as is and after its best rigid fit onto `to` (point-to-point ICP over the two labels' boundary
/// voxel centres, world mm); the fit's rotation (degrees) and how far it moves the mirrored boundary's centroid (mm).
struct RigidFitScore {
  double mirrorDice = 0, fittedDice = 0, rotationDeg = 0, centroidMoveMm = 0;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  ///< the fit: mirrored label → `to` (world mm)
};
RigidFitScore rigidFitOfMirror(const LabelMap& labels, int from, int to, double midX);

/// Where a result surface sits against its label, by what lies `outMm` outside each vertex along its normal: mean and
/// mean absolute signed distance (mm, + = the surface outside the label) to the nearest label boundary crossing along
/// the normal within ± 9 mm (vertices without one are not counted).
struct BoundaryClassError {
  const char* name;
  int vertices = 0;
  double signedMm = 0, absMm = 0;
};
/// The classes, in order: fat (< −40 HU), bone (a label of `bones` or > 250 HU), partner muscles (a label of
/// `partners`), other soft tissue.
std::vector<BoundaryClassError> errorByOutside(const TriangleMesh& mesh, const LabelMap& labels, int label,
                                               const ImageF& image, const std::vector<int>& partners,
                                               const std::vector<int>& bones, double outMm = 6.0);

/// totalseg-mr: left and right autochthon muscles (46, 47; each from the other, mirrored) and the vertebrae (19) as
/// bones. Label 19 holds several vertebral bodies apart from each other (the discs between them are label 20), so each
/// component of at least 100 voxels is its own bone object (labels 1901, 1902, ...; template from itself, mirrored).
/// Mid-sagittal plane through the vertebrae's centroid; each muscle against every vertebra.
RealScene mrScene(const std::string& data, int vertices = 3000);

/// The MR scene's run: the global prior ends at λ = 0.3.
SceneScore runMrScene(const RealScene& rs);

/// totalseg-ct, right side: femur 76, hip bone 78, gluteus maximus 81 and medius 83, each from the left label,
/// mirrored across the sagittal plane through the sacrum's centroid (25); every pair may touch. `mediusPose`: a rigid
/// motion of the mirrored gluteus medius template before its displacement. `ownLabels`: every template built from the
/// right side's own label instead (the shape the result should have), displaced and scaled the same way, its profiles
/// still learned on the left structure.
RealScene ctScene(const std::string& data, double displacementMm = kDisplacementMm,
                  const Eigen::Matrix4d& mediusPose = Eigen::Matrix4d::Identity(), bool ownLabels = false);

/// The CT scene's run: the two bones take the refinement pass, the global prior ends at λ = 0.2, the finest search
/// reaches ± 1 voxel on an image smoothed at σ = 1 voxel; `edgeLevel` adds the edge level (gradient force).
SceneScore runCtScene(RealScene& rs, bool edgeLevel = false);

/// The CT scene with every template from the right side's own label; `gradient`: every object on the gradient force
/// (no profiles) with the edge level, else the profiles learned on the left side.
SceneScore runCtSceneFromOwnLabels(const std::string& data, bool gradient);

/// x (RAS mm) of the mid-sagittal plane of totalseg-ct: the sacrum's centroid (label 25), a midline landmark.
double ctMidSagittalX(const LabelMap& labels);

/// A bone of the right side from the left side's label, mirrored across x = midX, with the profile force learning its
/// profiles on the left structure ("profiles_from": {"mirror_x": midX}).
SceneObject mirroredBone(const LabelMap& labels, const char* name, int label, int from, double midX);

/// The CT femur's options: the global prior ends at λ = 0.2, the finest search reaches ± 1 voxel, and (if `refine`)
/// the refinement pass finishes the bone on the CT's own edges.
SegmentOptions ctFemurOptions(bool refine = true);

/// The right femur of totalseg-ct alone (template not displaced), with and without the refinement pass.
struct CtFemurRuns {
  double midX = 0;
  SegmentationMetrics before, after, withoutPass;
  QualityStatus status = QualityStatus::Ok;  ///< the run's quality status (with the refinement pass)
  double seconds = 0;
};
CtFemurRuns runCtFemur(const std::string& data);

/// The right femur with the right hip bone as its collision partner.
struct CtFemurWithHip {
  SegmentationMetrics femurBefore, femur, hipBefore, hip;
  size_t overlapVoxels = 0;
  QualityStatus status = QualityStatus::Ok;  ///< the run's quality status
  double penetrationMm = 0;
  double seconds = 0;
};
CtFemurWithHip runCtFemurWithHip(const std::string& data);

}  // namespace msk::test
