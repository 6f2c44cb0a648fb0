#pragma once
// The stages of segmentScene() (private to msk_segmentation): each object's state across levels and the functions
// that build, evolve and finish it. segmenter.cpp strings them together.
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "msk/core/collision_constraint.h"
#include "msk/core/medial_axis.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/solver.h"
#include "msk/core/target_constraint.h"
#include "msk/core/volume_preservation.h"
#include "msk/core/volume_simplex.h"
#include "msk/segmentation/mesh_cache.h"
#include "msk/segmentation/segmenter.h"

namespace msk::detail {

using Clock = std::chrono::steady_clock;
/// Seconds since `t0`.
inline double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Image features per scale, built on first use only.
class FeatureCache {
 public:
  explicit FeatureCache(const ImageF& image) : image_(image) {}
  /// The features at scale σ (mm), computed the first time this scale is asked for.
  const ImageFeatures& at(double sigmaMm);
  /// Computes the scales `sigmasMm` not computed yet, each on one of `threads` threads (0 = all cores).
  void prepare(const std::vector<double>& sigmasMm, int threads);
  /// Distinct scales computed.
  int built() const { return static_cast<int>(cache_.size()); }
  /// Time spent computing them, s.
  double seconds() const { return seconds_; }

 private:
  /// The normalised image every scale is smoothed from, made on first use.
  const ImageF& normalised();
  const ImageF& image_;
  std::optional<ImageF> normalised_;
  std::map<long, ImageFeatures> cache_;
  double seconds_ = 0;
};

/// The contact parameters of one scene pair: the scene's values where it sets them, else the run's.
struct PairContact {
  double gapMm = 0, proximityMm = 0, friction = 0;
  CollisionResponse response;  ///< mode and target from the scene; resolution from the scene or the run
};

/// The contact search reach beyond the gap of pairs that do not set their own: the run's, or max(1 mm, ½ the largest
/// spacing).
double defaultProximityMm(const SegmentOptions& opts, const Grid& grid);

/// pairContacts()[k] for scene.collisions[k].
std::vector<PairContact> pairContacts(const Scene& scene, const SegmentOptions& opts, const Grid& grid);

/// One resolution level of an object's template: the triangles and their 2-simplex dual.
struct LevelMeshes {
  TriangleMesh triangles;  ///< template at this level
  SimplexMesh simplex;     ///< its dual
};

/// One object's evolving state across levels: its template levels, its current surface, its place in the stacked
/// system and the constraint sets it gets at the current level (only those its model asks for).
struct ObjectState {
  const SceneObject* obj = nullptr;
  ObjectResult out;
  std::vector<LevelMeshes> lv;  ///< index 0 finest
  TargetSearchOptions search;
  TargetMode force = TargetMode::Gradient;  ///< the image force of the levels (the scene's, unless it cannot be used)
  Polarity polarity = Polarity::Auto;
  SimplexMesh current;
  Eigen::VectorXd residual;
  double driftMmPerStep = 0;  ///< mean net displacement per step of the surface over the last steps of the pass, mm
  std::vector<std::string> warnings;  ///< prepareObject()'s warnings, printed in object order once all are prepared
  double searchSeconds = 0;
  int first = 0;  ///< first particle in the stacked system at the current level
  // Per-level constraint sets.
  std::unique_ptr<SimplexInternalConstraints> internal;
  std::unique_ptr<TargetConstraints> targets;
  std::unique_ptr<ShapeMatchingConstraint> prior;
  LearnedProfiles profiles;
  /// The image search's targets kept between the steps of a level (cleared as each level or pass begins).
  SearchReuse reuse;
  /// Features of the image the object learns its profiles on when that is not the segmented one (obj->profileImage).
  FeatureCache* profileFeatures = nullptr;
  /// Features of each subject of obj->profileSubjects (an atlas of several), in their order.
  std::vector<FeatureCache*> subjectFeatures;
  // Medial axis (objects whose model asks for one): its particles follow every object's surface in the stacked system.
  MedialAxis axis;              ///< at the current level, template position
  RadialAttachment attachment;  ///< surface vertices of this level → axis segments, reference radii
  Points axisStart;             ///< axis particles at the start of the level (template axis moved with the surface)
  int axisFirst = 0;            ///< first axis particle in the stacked system
  std::unique_ptr<RadialConstraints> radial;
  std::unique_ptr<AxisCentering> centering;
  // 3-simplex volume model (objects whose model asks for one), at the finest level: its tet vertices are the particles
  // right before the surface's, whose simplex vertices are the model's ghosts (the finest template is the boundary of
  // the tetrahedralised template), so the surface and the volume share those particles.
  std::optional<VolumeSimplexMesh> volume;
  std::unique_ptr<VolumeSimplexConstraints> volumeSet;
  std::unique_ptr<VolumePreservation> volumeHold;  ///< holds the template's volume unless the image demands another
  int volFirst = 0;                                ///< first tet particle in the stacked system
  Points volStart, volFinal;                       ///< tet particles at the start and the end of the finest level
  Eigen::VectorXd volRestVolumes;                  ///< volumes of the volume model's rest tets, mm³ (finishObject())
  Eigen::VectorXi volSurfaceNode;                  ///< tet node of each vertex of the output surface (finishObject())
  // Axis-first stage (objects that run it): the coarsest template's axis and where the stage left it.
  Points stageAxisRef, stageAxis;  ///< empty without the stage
  Points axisEnd;  ///< axis particles where the last pass left them (a refinement pass's fixed objects keep them)

  /// Tet particles at level l (0 unless the object is volumetric and l is the finest level).
  int tetCount(int l) const { return volume && l == 0 ? volume->tetCount() : 0; }
  /// The constraint sets of this object at the current level, in projection order (image, internal, prior, radial,
  /// axis centring, volume).
  std::vector<ConstraintSet*> sets() const;
  /// Whether the object's model has a medial axis.
  bool hasAxis() const { return obj && obj->model.medialAxis; }
  /// Number of axis particles at the current level (0 without an axis).
  int axisCount() const { return hasAxis() ? axis.curve.vertexCount() : 0; }
  /// Template points (any level's surface or axis) swept by the axis-first stage (GeneralisedCylinder about the
  /// coarsest template axis); unchanged without the stage.
  Points bentByStage(const Points& templ) const;
  /// Whether the object runs the axis-first coarse stage (its model's "axis_first", else the run's default).
  bool runsAxisFirst(const SegmentOptions& o) const { return hasAxis() && obj->model.axisFirst.value_or(o.axis.first); }
  /// Whether the object takes part in the refinement pass (its model's "refine", else the run's).
  bool refines(const SegmentOptions& o) const { return obj->model.refine.value_or(o.image.refinePass); }
};

// ---- object_model.cpp: the templates' levels and the constraint sets of a level

/// Builds the resolution levels (remeshed and tetrahedralised where asked), polarity and search settings of one object.
/// Safe to run for several objects at once when `features` and the objects' profile caches hold the coarsest scale
/// rs.sigmaMm[0] already (it only reads them then); its warnings go to st.warnings.
void prepareObject(ObjectState& st, const SegmentOptions& opts, const ResolvedSettings& rs, FeatureCache& features,
                   MeshCache* templateCache);

/// Moves an object to level `l` (carrying the coarser level's displacement) and builds its constraint sets. The
/// refinement pass (`refine`, level 0 again) keeps the surface where it is and takes it as the reference shape, with
/// the gradient force and the edge level estimated there.
void enterLevel(ObjectState& st, int l, int coarsest, const SegmentOptions& opts, const ImageFeatures& feat,
                const Grid& grid, bool refine = false);

/// Builds the radial constraints and the axis re-centring of an object with a medial axis, once its axis particles
/// have their place in the stacked system (st.axisFirst).
void buildAxisSets(ObjectState& st, const SegmentOptions& opts);

// ---- image_targets.cpp: an object's image targets

/// One object's image targets at a surface: targets, weights in [0, 1] and residuals (target offsets, mm).
struct ImageTargets {
  Points targets;
  Eigen::VectorXd weights, residual;
};

/// The image targets of `mesh` (the object's current surface): the search (timed into st.searchSeconds), score weights
/// with the optional far-target down-weighting, and a muscle's per-step limit. `reuseMoveMm` > 0: a vertex that moved
/// less than that since its last search in st.reuse keeps that search's target (SearchReuse).
ImageTargets imageTargets(ObjectState& st, const SimplexMesh& mesh, const SegmentOptions& opts,
                          const ImageFeatures& feat, const Grid& grid, const ImageFeatures* focus,
                          double reuseMoveMm = 0);

// ---- axis_first_stage.cpp

/// The axis-first coarse stage (DESIGN-NOTES §4, "evolve the axis first") of an object with a medial axis at level
/// `l`, after enterLevel() and before the full-surface evolution: the object moves as a generalised cylinder of its
/// axis until no axis vertex moves more than the tolerance or the step cap. The surface and axis particles then start
/// from there, and the stage's axis is kept (stageAxis) so that enterLevel() bends every level's reference shape with
/// it; the caller rebuilds the level's sets. Objects do not see each other in this stage.
AxisFirstReport runAxisFirst(ObjectState& st, int l, const SegmentOptions& opts, const ResolvedSettings& rs,
                             const ImageFeatures& feat, const Grid& grid);

// ---- level_system.cpp: every object's particles of one pass in one system

/// What one pass of the evolution works on: the stacked particle system of every object (tets, surface; then every
/// medial axis), the constraint sets of the objects that move, and the collision sets of the declared pairs.
class LevelSystem {
 public:
  /// Lays the objects out at level `l` and enters it for each object not `fixed` (enterLevel(), buildAxisSets()).
  /// `fixed[i]`: object i keeps its place (its particles are fixed, its sets not built).
  LevelSystem(std::vector<ObjectState>& objs, int l, int coarsest, bool refine, const std::vector<char>& fixed,
              const SegmentOptions& opts, const ResolvedSettings& rs, const ImageFeatures& feat, const Grid& grid);
  /// Stacks the start positions, the inverse masses and the sets (after any axis-first stage), and builds the
  /// collision sets of the scene's pairs when collisions are on. Returns the number of collision sets built.
  int assemble(const Scene& scene, const std::vector<PairContact>& contacts, const SegmentOptions& opts);
  /// Particles in the system.
  int particles() const { return n_; }
  /// Start positions (#particles × 3).
  const Points& positions() const { return x_; }
  /// Inverse masses (0 = fixed).
  const Eigen::VectorXd& inverseMass() const { return invMass_; }
  /// Every set the solver steps, in order: the objects' sets, sequential collision sets, global resolutions.
  const std::vector<ConstraintSet*>& sets() const { return sets_; }
  /// Whether any collision set was built.
  bool hasContacts() const { return !collide_.empty(); }
  /// Rebuilds the partner surfaces at `p` and detects every set's contacts (on `threads` threads, 0 = all cores; the
  /// result does not depend on it), with the inside test when `sideTest`.
  void detectContacts(const Points& p, bool sideTest, int threads);
  /// Collision-only sweeps on `p` after the last step (position corrections with each pair's target whatever its mode):
  /// sequential pairs one set after the other (each set's detection on `threads` threads, 0 = all cores, the result
  /// the same for any number), then the global pairs solved together; it stops early once a sweep corrects nothing
  /// (sequential pairs alone: or moves no coordinate by more than a picometre).
  /// Returns the sweeps run.
  int cleanUpContacts(Points& p, const Eigen::VectorXd& w, int sweeps, const Scene& scene, int threads);

 private:
  std::vector<ObjectState>& objs_;
  std::vector<char> fixed_;
  int l_ = 0, n_ = 0;
  Points x_;
  Eigen::VectorXd invMass_;
  std::vector<ConstraintSet*> sets_;
  std::vector<std::unique_ptr<CollisionConstraints>> collide_;  // pair k: [2k] = first against second, [2k+1] back
  std::map<size_t, std::shared_ptr<CollisionSurface>> surfaces_;
  std::map<CollisionMode, std::unique_ptr<GlobalCollisionResolution>> global_;
};

// ---- step_loop.cpp

/// The step loop of one pass: each step the moving objects' image targets (and the prior's ramped weight λ), the
/// contacts, then one solver step; stops when no vertex moved more than the tolerance or on the step cap. `stepsDone`
/// counts steps over the run (the prior's ramp spans `rampSteps`, progress `totalSteps`). Adds the contact detection
/// time to `detectSeconds`.
LevelReport runSteps(std::vector<ObjectState>& objs, const std::vector<char>& fixed, LevelSystem& system,
                     Solver& solver, const SegmentOptions& opts, const ResolvedSettings& rs, const ImageFeatures& feat,
                     const ImageFeatures* focus, const Grid& grid, int& stepsDone, int rampSteps, int totalSteps,
                     const std::string& stage, const ProgressFn& progress, double& detectSeconds);

/// Takes each moving object's surface, axis and tets back from the solver after a pass, refuses a run that has blown
/// up (size ×5 or ÷5 of its template level), and records the pass's report for it.
void collectPass(std::vector<ObjectState>& objs, const std::vector<char>& fixed, const Solver& solver, int l, int order,
                 const LevelReport& report);

// ---- object_output.cpp: one object's result

/// The final surface on the template's triangulation (as given, or remeshed), with per-vertex displacement and image
/// residual, local folds unfolded (`unfold`), and the volume model's tet mesh.
void finishObject(ObjectState& st, bool unfold);

/// Puts the boundary nodes of `out.volumeMesh` on the vertices of `out.mesh` (the written surface), then untangles
/// the tets and improves the worst ones (tet_untangle.h); counts the volume and the inverted tets.
void settleVolumeMesh(ObjectResult& out, const Eigen::VectorXd& restVolumes, const Eigen::VectorXi& surfaceNode);

// ---- output_surfaces.cpp: the surfaces written out

/// Separates the output surfaces of the declared pairs (then unfolds what the separation folded and separates again),
/// hands voxel centres still inside both surfaces of a pair to one of them, and measures each pair's penetration.
/// Fills the separation and penetration figures of `res`; returns each object's voxels (insideVoxels()).
/// `crossingsCounted`: whether each object's selfIntersections is that of its surface as returned (the last unfolding
/// moved nothing and nothing moved the surfaces after it).
std::vector<std::vector<size_t>> separateOutputs(SegmentationResult& res, const std::vector<ObjectState>& objs,
                                                 const Scene& scene, const std::vector<PairContact>& contacts,
                                                 const SegmentOptions& opts, const Grid& grid, bool& crossingsCounted);

/// The label map: every object's voxels (`inside`, or computed if empty) with its label; voxels claimed by more than
/// one object are counted and go to bones (muscles and generic objects are written first).
void rasteriseLabels(SegmentationResult& res, const Scene& scene, const std::vector<std::vector<size_t>>& inside,
                     const Grid& grid);

}  // namespace msk::detail
