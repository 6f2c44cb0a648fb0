#pragma once
/// The segmentation pipeline: template surfaces of a scene evolve as 2-simplex meshes under image targets, shape
/// memory and a global shape prior, coarse to fine (DESIGN-NOTES §6, §7).
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "msk/core/constraints.h"
#include "msk/core/json.h"
#include "msk/core/log.h"
#include "msk/core/medial_axis.h"
#include "msk/core/pbd_solver.h"
#include "msk/core/volume_simplex.h"
#include "msk/core/solver.h"
#include "msk/segmentation/image_forces.h"
#include "msk/segmentation/scene.h"

namespace msk {

/// Speed/accuracy presets (resolveSettings() maps them: levels, steps, tolerance, scheme, substeps × iterations).
enum class Quality { Fast, Balanced, Accurate };

/// Parses "fast" | "balanced" | "accurate"; throws ParameterError otherwise.
Quality parseQuality(const std::string& text);
/// Name of a preset.
const char* qualityName(Quality q);
/// Parses "rigid" | "similarity" | "affine"; throws ParameterError (naming `option`) otherwise.
PriorTransform parsePriorTransform(const std::string& text, const std::string& option = "prior");
/// Name of a prior transform.
const char* priorTransformName(PriorTransform t);
/// Name of a polarity ("auto", "dark-inside", "bright-inside").
const char* polarityName(Polarity p);

/// Settings of one run. Values ≤ 0 in the "0 = preset" fields take the preset's value.
struct SegmentOptions {
  Quality quality = Quality::Balanced;  ///< preset
  int levels = 0;               ///< mesh resolution levels, ×4 vertices apart (0 = preset)
  int maxStepsPerLevel = 0;     ///< step cap per level (0 = preset)
  double toleranceMm = 0;       ///< stop a level when no vertex moves more than this per step (0 = preset)
  double internalStiffness = 1.0;   ///< γ of the 2-simplex shape memory, [0, 1]
  double imageStiffness = 0.25;     ///< γ of the image targets, [0, 1]
  double priorStart = 0.3;          ///< global prior weight λ at the start of the run, [0, 1]
  double priorEnd = 0.1;            ///< λ at the end of the run (ramped linearly), [0, 1]
  PriorTransform priorTransform = PriorTransform::Similarity;  ///< kind of the global fit
  /// Image scale σ at the finest level, in units of the smallest voxel spacing; unset = the preset's (0.5, accurate
  /// 0.25: a lighter blur moves the edges less, measured over six femur phantoms 0.320 → 0.287 mm ASSD).
  std::optional<double> sigmaFine;
  double sigmaCoarse = 1.5;   ///< σ at the coarsest level, same units (levels in between interpolate)
  double rangeFine = 1.5;     ///< search range ± at the finest level, in units of the largest voxel spacing
  double rangeCoarse = 3.0;   ///< search range at the coarsest level, same units, plus rangeCoarseExtraMm
  /// Length added to the coarsest level's search range, mm (levels in between get their share), ≥ 0: a capture reach
  /// beyond the voxel-relative range. A length like the collision gap, so it scales with the image's units.
  double rangeCoarseExtraMm = 2.0;
  double farTargetScaleMm = 0;  ///< > 0: a target d mm away pulls with weight 1/(1 + (d/scale)²) (robust to outliers)
  double edgePenalty = 0.1;   ///< score lost per mm of distance from the vertex (relative to the best edge)
  /// Gradient force at the levels coarser than the finest: relocate each edge found at the level's scale to the
  /// finest scale's edge next to it (edge focusing, see searchTargets()); off by default: it helps a thin bright
  /// shell seen coarsely (CT cortex at 3 mm) but costs the phantom femurs (solid bone) 0.001–0.003 Dice.
  bool edgeFocusing = false;
  /// Gradient force: an edge counts only where the intensity crosses the object's edge level (estimateEdgeLevel(), at
  /// each level's scale and the template's position), so edges of other boundaries with the same polarity are ignored.
  bool edgeLevel = false;
  /// One more pass at the finest level once the levels are done (refinement): every object's converged surface becomes
  /// its reference shape (shape memory, global prior, medial axis), and its force the gradient with the edge level
  /// estimated there. The run's force and template decide where the object is; its image's own edges where its
  /// surface lies. For objects whose profiles are learned elsewhere (mirrored contralateral side) or whose template's
  /// shape differs from the subject's. The scene's per-object "refine" wins; objects that do not refine stay where the
  /// levels left them (fixed, still collision partners). Made for bones on CT, whose edge is the image's strongest;
  /// on a blurry MRI the steepest muscle–fat gradient lies off the labelled boundary and the pass costs muscles.
  bool refinePass = false;
  /// Image scale of the refinement pass, × the smallest spacing (the edges it settles on are the finest it sees;
  /// independent of the run's finest σ, which multi-object scenes raise for their muscles).
  double refineSigma = 0.5;
  /// > 0: a muscle's image target lies at most this many local edge lengths (mean distance to the vertex's three
  /// neighbours) from its vertex in a step (0 = no limit). Targets at interfaces a muscle cannot reach (a partner, a
  /// missing septum) otherwise pull at full length step after step and the surface buckles between them. Bones are
  /// not limited: their edges are strong, and the limit cost the real CT femur 0.01 Dice.
  double muscleTargetStepEdges = 1.0;
  /// Each muscle's and generic object's template (bones keep theirs unless their model asks; the scene's per-object
  /// "remesh" wins; volumetric objects are not remeshed: their surface is the boundary of their tetrahedralisation,
  /// made of well-shaped facets) is first remeshed isotropically to its own vertex count (remeshIsotropic()): the long
  /// thin triangles of a decimated muscle template make a 2-simplex dual whose vertices fold under the image forces,
  /// and the output surface then intersects itself (README, *Surface quality*). The output is on the remeshed
  /// triangulation, the same for every run from the same template.
  bool remeshTemplates = true;
  /// Local folds an output surface still has (faces crossing each other where it was squeezed between partners or
  /// pulled by noise) are smoothed away: after the evolution, and after the output separation (then separated again).
  /// unfoldSurface(); each object reports what it found and moved.
  bool unfoldSurfaces = true;
  InternalMode internalMode = InternalMode::ShapeMemory;       ///< shape memory or smoothing
  bool collisions = true;       ///< respond to the scene's collision pairs (false: objects ignore each other)
  double collisionGapMm = 0.2;  ///< default clearance g kept between partners (a pair in the scene may override)
  double collisionProximityMm = 0;  ///< contact search reach beyond the gap (0 = max(1 mm, ½ the largest spacing))
  double collisionFriction = 0;     ///< default friction μ ∈ [0, 1]
  double boneMassRatio = 5;     ///< bone particles are this many times heavier than muscle ones (share less of a contact)
  /// How pairs whose scene entry has no "resolution" resolve their contacts (sequential, or global conjugate gradient)
  CollisionResolution collisionResolution = CollisionResolution::Sequential;
  /// Velocity- and acceleration-mode pairs: a vertex more than this far inside its partner (mm, ≥ 0) gets a position
  /// correction in the projection phase (CollisionResponse::positionBeyondMm; the seed's robust practice)
  double collisionPositionBeyondMm = 0.0;
  int collisionFinalSweeps = 10;  ///< collision-only detect + project sweeps after the last step (penetration clean-up)
  int collisionSideTestEvery = 10;  ///< steps between inside/outside tests of contacts (winding number; 0 = first step only)
  int separationSweeps = 32;    ///< most sweeps of the output-surface separation of declared pairs (0 = none)
  double radialStiffness = 0.1;   ///< default γ of the radial constraints of objects with a medial axis, [0, 1]
  double axisSpacingMm = 8.0;     ///< default distance between medial-axis vertices, mm
  double axisCentering = 0.5;     ///< γ of the axis re-centring on its surface per step, [0, 1]
  /// Objects with a medial axis whose model does not set "axis_first" run the axis-first coarse stage: before the
  /// coarsest level's full-surface evolution the object moves as a generalised cylinder of its axis
  /// (GeneralisedCylinder, driven by the surface's image targets), and the template bent by the stage's axis is its
  /// reference shape (shape memory, global prior, axis) from then on
  bool axisFirst = false;
  int axisFirstSteps = 40;          ///< step cap of the axis-first stage (it stops earlier on the tolerance), 0..100000
  AxisFirstOptions axisFirstStage;  ///< image gain and axis shape memory of the axis-first stage
  double volumeStiffness = 0.5;   ///< default γ of the 3-simplex internal constraint of volumetric objects, [0, 1]
  PbdOptions pbd;               ///< time step, damping and drag of every scheme (pbd.iterations ≠ 1: see `iterations`)
  std::optional<Scheme> scheme; ///< evolution scheme (unset = preset)
  int substeps = 0;             ///< substeps per step (0 = preset)
  int iterations = 0;           ///< projection sweeps per substep (0 = pbd.iterations if ≠ 1, else preset)
  int threads = 1;              ///< threads of the coloured, Jacobi and CG schemes and of collision detection (0 = all
                                ///< cores); results do not depend on it
  double xpbdStiffness = 4.0;   ///< XPBD k, mass-relative (XpbdStiffness::MassRelative): k × the force stiffness γ m̄ dt⁻²
  double jacobiOmega = 1.5;     ///< Jacobi relaxation ω ∈ (0, 2)
};

/// The collision response one pair used (names of its objects, mode, target, resolution).
struct PairResponse {
  std::string a, b;              ///< object names
  CollisionResponse response;    ///< what was used
};

/// What the axis-first coarse stage did for one object (report.json "parameters" → "axis_first_stage"; the stages'
/// total time is SegmentationResult::secondsPerStage["axis-first"], a part of "evolution").
struct AxisFirstReport {
  std::string object;         ///< object name
  int steps = 0;              ///< steps taken
  bool converged = false;     ///< stopped because no axis vertex moved more than the tolerance (not on the cap)
  double lastMaxMoveMm = 0;   ///< largest axis vertex move in the last step, mm
  double meanAxisMoveMm = 0;  ///< mean distance the axis vertices moved over the stage, mm
  double seconds = 0;         ///< time of the stage, s (image search and the rebuild of the object's constraint sets
                              ///< about the bent template included)
};

/// The settings a run actually used after the preset is applied (written into report.json).
struct ResolvedSettings {
  int levels = 2, maxStepsPerLevel = 60;
  double toleranceMm = 0.02;
  double sigmaFineVoxels = 0.5;  ///< σ at the finest level, × the smallest spacing (the option, or the preset's)
  std::vector<double> sigmaMm;   ///< image scale per level, coarse first
  std::vector<double> rangeMm;   ///< search range per level, coarse first
  SolverOptions solver;          ///< the evolution scheme with all its settings (what Solver runs)
  std::vector<PairResponse> collisionResponses;  ///< per scene pair (scene order), filled by segmentScene()
  std::vector<AxisFirstReport> axisFirst;        ///< per object that ran the axis-first stage, filled by segmentScene()
};

/// What one level of one object did.
struct LevelReport {
  int vertices = 0;         ///< simplex vertices
  int steps = 0;            ///< steps taken
  double lastMaxMoveMm = 0; ///< largest displacement in the last step
  bool converged = false;   ///< stopped on tolerance (not on the step cap)
  double sigmaMm = 0, rangeMm = 0;
  bool refinement = false;  ///< the refinement pass (SegmentOptions::refinePass) rather than a level
};

/// The result for one object.
struct ObjectResult {
  std::string name;
  int label = 0;
  TriangleMesh mesh;  ///< final surface, RAS mm; point data "displacement_mm" and "image_residual_mm"
  Polarity polarity = Polarity::Auto;  ///< the polarity used (estimated if auto)
  std::vector<LevelReport> levels;     ///< coarse first
  double seconds = 0;                  ///< evolution time, shared equally among the objects evolved together
  double volumeMm3 = 0, templateVolumeMm3 = 0;
  double meanImageResidualMm = 0;      ///< mean |target offset| at the end
  std::map<std::string, double> secondsPerFamily;  ///< constraint projection time by family, plus "image-search"
  TetMesh volumeMesh;                  ///< volumetric objects: the final tet mesh (nodes recovered from the 3-simplex)
  double volumeModelMm3 = 0;           ///< its volume, mm³ (0 without a volume model)
  double volumeModelTemplateMm3 = 0;   ///< the volume of the tetrahedralised template, mm³
  int invertedTets = 0;                ///< tets of volumeMesh with volume ≤ 0 (flat slivers of the mesher flip first)
  /// What the volume model's volume constraint decided (volume_preservation.h): "holding" the template's volume,
  /// "following" the image (it demanded another), or "observing" (never settled); empty without a volume model.
  std::string volumeDecision;
  bool remeshed = false;     ///< the template was remeshed (SegmentOptions::remeshTemplates, "remesh")
  int templateVertices = 0;  ///< vertices of the template as given
  /// Pairs of faces of the output surface that cross each other (selfIntersections(); 0 = embedded)
  size_t selfIntersections = 0;
  size_t foldsFound = 0;     ///< crossing face pairs unfoldSurface() found, summed over its calls
  int unfoldedVertices = 0;  ///< vertices it moved, summed over its calls
};

/// The result of a scene.
struct SegmentationResult {
  std::vector<ObjectResult> objects;
  LabelMap labels;               ///< every object rasterised on the image grid with its label (bones win overlaps)
  ResolvedSettings settings;     ///< preset applied
  double seconds = 0;            ///< whole run
  std::map<std::string, double> secondsPerStage;  ///< "features", "evolution", "rasterise"
  int featureScalesBuilt = 0;    ///< distinct image scales computed (each once)
  int collisionSetsBuilt = 0;    ///< directed vertex–surface collision sets built over all levels (0 without pairs)
  int volumeModelsBuilt = 0;     ///< objects given a 3-simplex volume model (0 unless a model asks)
  int medialAxesBuilt = 0;       ///< objects given a medial axis with radial constraints (0 unless a model asks)
  size_t overlapVoxels = 0;      ///< voxels inside more than one object's surface
  /// Per declared pair (scene order): the deepest vertex of either output surface inside the other (winding-number
  /// side, mm, 0 if none), measured on the meshes written out.
  std::vector<double> pairPenetrationMm;
  int separationSweeps = 0;      ///< sweeps the output-surface separation ran
  long separationCorrections = 0;  ///< vertex corrections it applied
  /// Voxel centres left inside both surfaces of a declared pair by the separation (edges crossing between its
  /// samples) that were handed to one of the two (its closest triangle moved inward past the centre)
  long overlapVoxelsRepaired = 0;
};

/// Applies the preset to `opts` for an image grid (scales and ranges are relative to the voxel size).
ResolvedSettings resolveSettings(const SegmentOptions& opts, const Grid& grid);

/// The options and resolved settings as JSON (for report.json).
Json settingsJson(const SegmentOptions& opts, const ResolvedSettings& settings);

/// Segments every object of the scene in `image` (RAS mm). Throws Error/ParameterError on bad input (NaN voxels,
/// parameters out of range) before doing any work.
SegmentationResult segmentScene(const ImageF& image, const Scene& scene, const SegmentOptions& opts,
                                const ProgressFn& progress = {});

}  // namespace msk
