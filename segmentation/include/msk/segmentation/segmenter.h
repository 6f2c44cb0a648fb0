#pragma once
/// The segmentation pipeline: the template surfaces of a scene evolve as 2-simplex meshes under image targets, shape
/// memory and a global shape prior, coarse to fine, every object in one stacked particle system with contacts between
/// the scene's collision pairs (DESIGN-NOTES §6, §7); then the output surfaces are separated, unfolded and rasterised.
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "msk/core/collision_response.h"
#include "msk/core/log.h"
#include "msk/core/triangle_mesh.h"
#include "msk/core/volume_simplex.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/image_forces.h"
#include "msk/segmentation/mesh_cache.h"
#include "msk/segmentation/quality_check.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segment_options.h"

namespace msk {

/// The collision response one pair used (names of its objects, mode, target, resolution).
struct PairResponse {
  std::string a, b;            ///< object names
  CollisionResponse response;  ///< what was used
};

/// What the axis-first coarse stage did for one object.
struct AxisFirstReport {
  std::string object;         ///< object name
  int steps = 0;              ///< steps taken
  bool converged = false;     ///< stopped because no axis vertex moved more than the tolerance (not on the cap)
  double lastMaxMoveMm = 0;   ///< largest axis vertex move in the last step, mm
  double meanAxisMoveMm = 0;  ///< mean distance the axis vertices moved over the stage, mm
  double seconds = 0;         ///< time of the stage, s (image search and the rebuild of the object's constraint sets
                              ///< about the bent template included)
};

/// What one level of one object did.
struct LevelReport {
  int vertices = 0;                 ///< simplex vertices
  int steps = 0;                    ///< steps taken
  double lastMaxMoveMm = 0;         ///< largest displacement in the last step (of any object moving in the pass)
  bool stoppedOnTolerance = false;  ///< the pass stopped because no vertex moved more than the tolerance in a step
  /// The object's mean net displacement per step over its last steps (10, or 5 to 14 where the pass ends off that
  /// lattice), mm: the steps' back-and-forth between neighbouring image targets cancels in it, a surface still on its
  /// way does not
  double driftMmPerStep = 0;
  double settleToleranceMm = 0;  ///< the tolerance driftMmPerStep is held to, mm
  /// The object settled: the pass stopped on the tolerance, or its drift is below the tolerance
  bool converged = false;
  double sigmaMm = 0;       ///< image scale of the level, mm
  double rangeMm = 0;       ///< search range of the level, mm
  bool refinement = false;  ///< the refinement pass (ImageSearchOptions::refinePass) rather than a level
  /// Collision-only sweeps run after the last step of the run's last pass (0 elsewhere, or without collisions); fewer
  /// than CollisionOptions::finalSweeps where a sweep left nothing to correct
  int cleanUpSweeps = 0;
};

/// The result for one object.
struct ObjectResult {
  std::string name;
  int label = 0;
  TriangleMesh mesh;                   ///< final surface, RAS mm; point data "displacement_mm" and "image_residual_mm"
  Polarity polarity = Polarity::Auto;  ///< the polarity used (estimated if auto)
  /// The image force of the levels: the scene's, except the profile force without a profile source
  /// (hasProfileSource()), which falls back to the gradient force with a warning
  TargetMode force = TargetMode::Gradient;
  std::vector<LevelReport> levels;  ///< coarse first
  /// Time of the object's own work in the evolution: the image search of its vertices, s. (The constraint projection
  /// of objects evolved together is one solve, timed for the run in SegmentationResult::secondsPerFamily.)
  double imageSearchSeconds = 0;
  /// Of the vertices' image searches, the share that kept their last target (ImageSearchOptions::reuseTargetVoxels).
  double imageSearchReusedShare = 0;
  double volumeMm3 = 0, templateVolumeMm3 = 0;
  double meanImageResidualMm = 0;     ///< mean |target offset| at the end
  TetMesh volumeMesh;                 ///< volumetric objects: the final tet mesh (nodes recovered from the 3-simplex)
  double volumeModelMm3 = 0;          ///< its volume, mm³ (0 without a volume model)
  double volumeModelTemplateMm3 = 0;  ///< the volume of the tetrahedralised template, mm³
  int invertedTets = 0;               ///< tets of volumeMesh with volume ≤ 0 (flat slivers of the mesher flip first)
  /// What the volume model's volume constraint decided (volume_preservation.h): "holding" the template's volume,
  /// "following" the image (it demanded another), or "observing" (never settled); empty without a volume model.
  std::string volumeDecision;
  bool remeshed = false;     ///< the template was remeshed (SurfaceOptions::remeshTemplates, "remesh")
  int templateVertices = 0;  ///< vertices of the template as given
  /// Pairs of faces of the output surface that cross each other (selfIntersections(); 0 = embedded)
  size_t selfIntersections = 0;
  size_t foldsFound = 0;     ///< crossing face pairs unfoldSurface() found, summed over its calls
  int unfoldedVertices = 0;  ///< vertices it moved, summed over its calls
  ObjectQuality quality;     ///< figures of the final surface in the image and the status they give
};

/// The result of a scene.
struct SegmentationResult {
  std::vector<ObjectResult> objects;
  LabelMap labels;            ///< every object rasterised on the image grid with its label (bones win overlaps)
  ResolvedSettings settings;  ///< preset applied
  std::vector<PairResponse> collisionResponses;  ///< per scene pair (scene order; empty without collisions)
  std::vector<AxisFirstReport> axisFirst;        ///< per object that ran the axis-first stage
  double seconds = 0;                            ///< whole run
  /// Seconds per stage: "features", "evolution" (with "axis-first" a part of it), "collision-detection",
  /// "separation", "surface-check", "rasterise", "quality-check".
  std::map<std::string, double> secondsPerStage;
  /// Constraint projection time of the run by family (every object's constraints of the family together), s.
  std::map<std::string, double> secondsPerFamily;
  int featureScalesBuilt = 0;   ///< distinct image scales computed (each once)
  int templateCacheHits = 0;    ///< template meshes read from SurfaceOptions::templateCache
  int templateCacheMisses = 0;  ///< template meshes derived and stored there
  int collisionSetsBuilt = 0;   ///< directed vertex–surface collision sets built over all levels (0 without pairs)
  int volumeModelsBuilt = 0;    ///< objects given a 3-simplex volume model (0 unless a model asks)
  int medialAxesBuilt = 0;      ///< objects given a medial axis with radial constraints (0 unless a model asks)
  size_t overlapVoxels = 0;     ///< voxels inside more than one object's surface
  /// Per declared pair (scene order): the deepest vertex of either output surface inside the other (winding-number
  /// side, mm, 0 if none), measured on the meshes written out.
  std::vector<double> pairPenetrationMm;
  int separationSweeps = 0;        ///< sweeps the output-surface separation ran
  long separationCorrections = 0;  ///< vertex corrections it applied
  /// Voxel centres left inside both surfaces of a declared pair by the separation (edges crossing between its
  /// samples) that were handed to one of the two (its closest triangle moved inward past the centre)
  long overlapVoxelsRepaired = 0;
  QualityStatus status = QualityStatus::Ok;  ///< the worst object's quality status
};

/// Why `image` cannot carry any segmentation, or empty: an invalid grid, NaN/Inf voxels, or one value everywhere (no
/// edge for a surface to find).
std::string imageProblem(const ImageF& image);

/// Share of each object's template vertices inside the image's field of view (voxel-centre hull grown by half a
/// voxel), in scene order.
std::vector<double> templateShareInImage(const Grid& grid, const Scene& scene);

/// Least share of an object's template that must lie inside the image: below it the template is not where that
/// structure is in this image (another subject's world coordinates, another region), and the run is refused.
constexpr double kMinTemplateShareInImage = 0.25;

/// Why the scene cannot be segmented in an image on `grid`, or empty: an object whose template lies mostly outside
/// the image (templateShareInImage() < kMinTemplateShareInImage), named with its share.
std::string coverageProblem(const Grid& grid, const Scene& scene);

/// Whether a run remeshes `obj`'s template before evolving it (SurfaceOptions::remeshTemplates, the object's
/// "remesh"; a template already isotropic is used as it is), and the remeshing it gets: isotropic, to the template's
/// own vertex count (read from, or stored in, `cache` where given).
bool remeshesTemplate(const SceneObject& obj, const SegmentOptions& opts);
TriangleMesh remeshedTemplate(const SceneObject& obj, MeshCache* cache = nullptr);

/// The image features a run computes (each image normalised and smoothed at each level's scale), kept from one run to
/// the next: runs of one scene placed several ways in one image (an atlas's starts) compute them once. Keyed by the
/// images' addresses: the images must not change and must outlive the store. Runs must not share it at once.
class FeatureStore {
 public:
  FeatureStore();
  ~FeatureStore();
  FeatureStore(const FeatureStore&) = delete;
  FeatureStore& operator=(const FeatureStore&) = delete;
  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// Segments every object of the scene in `image` (RAS mm). Throws ParameterError for options out of range
/// (checkSegmentOptions()) and Error on bad input (imageProblem(), coverageProblem(), an empty scene) before doing
/// any work. With `features`, the image features come from that store where an earlier run computed them, and the
/// ones this run computes are kept there (the same results either way).
SegmentationResult segmentScene(const ImageF& image, const Scene& scene, const SegmentOptions& opts,
                                const ProgressFn& progress = {}, FeatureStore* features = nullptr);

}  // namespace msk
