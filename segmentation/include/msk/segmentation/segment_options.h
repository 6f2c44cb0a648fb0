#pragma once
/// The settings of a segmentation run, grouped by the part of the pipeline they steer, their one validation
/// (checkSegmentOptions(), which the command line calls too) and the presets that fill the "0 = preset" fields
/// (resolveSettings()).
#include <optional>
#include <string>
#include <vector>

#include "msk/core/collision_response.h"
#include "msk/core/medial_axis.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/solver.h"
#include "msk/imaging/grid.h"

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

/// The evolution's schedule and scheme. Fields at 0 (or unset) take the preset's value.
struct EvolutionOptions {
  Quality quality = Quality::Balanced;  ///< preset
  int levels = 0;                       ///< mesh resolution levels, ×4 vertices apart, 0..5 (0 = preset)
  int maxStepsPerLevel = 0;             ///< step cap per level, 0..100000 (0 = preset)
  double toleranceMm = 0;  ///< a level stops when no vertex moves more than this in a step, mm, ≥ 0 (0 = preset)
  std::optional<Scheme> scheme;  ///< evolution scheme (unset = preset)
  int substeps = 0;              ///< substeps per step, 0..1000 (0 = the scheme's)
  int iterations = 0;            ///< projection sweeps per substep, 0..1000 (0 = the scheme's)
  /// Threads of the coloured, Jacobi and CG schemes and of collision detection, 0..1024 (0 = all cores); results do
  /// not depend on it.
  int threads = 1;
  double dt = 1.0;             ///< time step of one step (> 0; it cancels from position-based corrections)
  double damping = 0.5;        ///< share of each velocity's deviation from the rigid motion removed per step, [0, 1]
  double drag = 0.5;           ///< share of the remaining velocity removed per step, [0, 1]
  double xpbdStiffness = 4.0;  ///< XPBD k, mass-relative (XpbdStiffness::MassRelative): k × the force stiffness
  double jacobiOmega = 1.5;    ///< Jacobi relaxation ω ∈ (0, 2)
  /// Evolve only the levels coarser than the finest: the finest level's surface takes the coarser one's displacement
  /// (as on entering it) and is not evolved, nor refined; the clean-up sweeps still run. A quick look at where a start
  /// leads (the atlas's starts are compared on it), not an output: the surfaces are neither unfolded nor separated, no
  /// labels are rasterised; the quality figures are measured. No effect with one level.
  bool coarseOnly = false;
};

/// Each object's shape constraints: its template shape memory and the global shape prior.
struct ShapeOptions {
  double internalStiffness = 1.0;                         ///< γ of the 2-simplex shape memory, [0, 1]
  InternalMode internalMode = InternalMode::ShapeMemory;  ///< shape memory or smoothing
  double priorStart = 0.3;                                ///< global prior weight λ at the start of the run, [0, 1]
  double priorEnd = 0.1;                                  ///< λ at the end of the run (ramped linearly), [0, 1]
  PriorTransform priorTransform = PriorTransform::Similarity;  ///< kind of the global fit
};

/// The image force: where each vertex searches along its normal, at which image scale, and how hard it is pulled.
struct ImageSearchOptions {
  double stiffness = 0.25;  ///< γ of the image targets, [0, 1]
  /// Image scale σ at the finest level, × the smallest voxel spacing, [0, 10]; unset = the preset's (0.5; accurate
  /// 0.25, a lighter blur that moves edges less).
  std::optional<double> sigmaFine;
  double sigmaCoarse = 1.5;  ///< σ at the coarsest level, same units, [0, 10] (levels in between interpolate)
  double rangeFine = 1.5;    ///< search range ± at the finest level, × the largest voxel spacing, (0, 20]
  double rangeCoarse = 3.0;  ///< search range at the coarsest level, same units, [0, 20], plus rangeCoarseExtraMm
  /// Length added to the coarsest level's search range, mm, [0, 1000] (levels in between get their share): a capture
  /// reach beyond the voxel-relative range.
  double rangeCoarseExtraMm = 2.0;
  double farTargetScaleMm = 0;  ///< > 0: a target d mm away pulls with weight 1/(1 + (d/scale)²); ≥ 0
  double edgePenalty = 0.1;     ///< score lost per mm of distance from the vertex (relative to the best edge), [0, 10]
  /// Gradient force at the levels coarser than the finest: each edge found at the level's scale is moved to the finest
  /// scale's edge next to it (edge focusing, searchTargets()). Helps a thin bright shell seen coarsely (CT cortex);
  /// costs solid bone a little.
  bool edgeFocusing = false;
  /// Gradient force: an edge counts only where the intensity crosses the object's edge level (estimateEdgeLevel(), at
  /// each level's scale and the template's position), so edges of other boundaries with the same polarity are ignored.
  bool edgeLevel = false;
  /// One more pass at the finest level once the levels are done: every refining object's converged surface becomes
  /// its reference shape (shape memory, global prior, medial axis) and its force the gradient with the edge level
  /// estimated there, so the image's own edges place its surface. The scene's per-object "refine" wins; objects that
  /// do not refine stay where the levels left them (fixed, still collision partners). Made for bones on CT.
  bool refinePass = false;
  double refineSigma = 0.5;  ///< image scale of the refinement pass, × the smallest spacing, [0, 10]
  /// > 0: a muscle's image target lies at most this many local edge lengths (mean distance to the vertex's three
  /// neighbours) from its vertex in a step, [0, 1000] (0 = no limit). Targets at interfaces a muscle cannot reach
  /// otherwise pull at full length step after step and the surface buckles between them. Bones are not limited.
  double muscleTargetStepEdges = 1.0;
  /// > 0: a vertex that has moved less than this × the smallest voxel spacing (and turned its normal less than
  /// kReuseTurnDegrees) since its last image search keeps that search's target instead of searching again, [0, 1]
  /// (0: every vertex searched every step); unset = the preset's (0.1; accurate 0).
  std::optional<double> reuseTargetVoxels;
};

/// The largest turn of a vertex's normal (degrees) with which it keeps its last image target
/// (ImageSearchOptions::reuseTargetVoxels).
constexpr double kReuseTurnDegrees = 2.0;

/// Contacts between the objects of the scene's collision pairs, and the separation of the output surfaces.
struct CollisionOptions {
  bool enabled = true;  ///< respond to the scene's collision pairs (false: objects ignore each other)
  double gapMm = 0.2;   ///< default clearance g kept between partners, mm, [0, 10] (a pair in the scene may override)
  double proximityMm = 0;  ///< contact search reach beyond the gap, mm, [0, 50] (0 = max(1 mm, ½ the largest spacing))
  double friction = 0;     ///< default friction μ ∈ [0, 1]
  /// Bone particles are this many times heavier than muscle ones (they share less of a contact), [0.001, 1000].
  double boneMassRatio = 5;
  /// How pairs whose scene entry has no "resolution" resolve their contacts (sequential, or global conjugate gradient).
  CollisionResolution resolution = CollisionResolution::Sequential;
  /// Velocity- and acceleration-mode pairs: a vertex more than this far inside its partner (mm, ≥ 0) gets a position
  /// correction in the projection phase (CollisionResponse::positionBeyondMm).
  double positionBeyondMm = 0.0;
  int finalSweeps = 10;       ///< collision-only detect + project sweeps after the last step, 0..1000
  int sideTestEvery = 10;     ///< steps between inside/outside tests of contacts, 0..100000 (0 = first step only)
  int separationSweeps = 32;  ///< most sweeps of the output-surface separation of declared pairs, 0..1000 (0 = none)
};

/// Medial axes of the objects whose model asks for one, and the axis-first coarse stage.
struct AxisOptions {
  double radialStiffness = 0.1;  ///< default γ of the radial constraints, [0, 1]
  double spacingMm = 8.0;        ///< default distance between medial-axis vertices, mm, [0.5, 100]
  double centering = 0.5;        ///< γ of the axis re-centring on its surface per step, [0, 1]
  /// Objects with a medial axis whose model does not set "axis_first" first move as a generalised cylinder of their
  /// axis (GeneralisedCylinder, driven by the surface's image targets) before the coarsest level's full-surface
  /// evolution; the template bent by the stage's axis is their reference shape from then on.
  bool first = false;
  int firstSteps = 40;          ///< step cap of the axis-first stage (it stops earlier on the tolerance), 0..100000
  AxisFirstOptions firstStage;  ///< image gain and axis shape memory of the axis-first stage, each [0, 1]
};

/// 3-simplex volume models of the objects whose model asks for one.
struct VolumeOptions {
  double stiffness = 0.5;  ///< default γ of the 3-simplex internal constraint, [0, 1]
};

/// The templates' triangulation and the output surfaces' quality.
struct SurfaceOptions {
  /// Each muscle's and generic object's template (bones keep theirs unless their model asks; the scene's per-object
  /// "remesh" wins; volumetric objects are not remeshed) is first remeshed isotropically to its own vertex count
  /// (remeshIsotropic()): the long thin triangles of a decimated template make a 2-simplex dual whose vertices fold
  /// under the image forces. The output is on the remeshed triangulation, the same for every run from one template.
  bool remeshTemplates = true;
  /// Local folds an output surface still has are smoothed away (unfoldSurface()): after the evolution, and after the
  /// output separation (then separated again).
  bool unfoldSurfaces = true;
  /// A folder where the meshes derived from templates (remeshed, decimated to the coarser levels) are kept and
  /// reused, bitwise the same (MeshCache); empty: none. It changes no result, only whether they are derived again.
  std::string templateCache;
};

/// Settings of one run.
struct SegmentOptions {
  EvolutionOptions evolution;  ///< schedule and scheme
  ShapeOptions shape;          ///< shape memory and global prior
  ImageSearchOptions image;    ///< image force
  CollisionOptions collision;  ///< contacts and separation
  AxisOptions axis;            ///< medial axes and the axis-first stage
  VolumeOptions volume;        ///< volume models
  SurfaceOptions surface;      ///< template remeshing and output unfolding
};

/// Checks every field of `opts` against its range (as documented on the field); throws ParameterError naming the
/// command-line option of the first one out of range (e.g. "--collision-gap = 20: must be in [0, 10] mm").
void checkSegmentOptions(const SegmentOptions& opts);

/// The settings a run actually used after the preset is applied.
struct ResolvedSettings {
  int levels = 2, maxStepsPerLevel = 60;
  double toleranceMm = 0.02;
  double sigmaFineVoxels = 0.5;    ///< σ at the finest level, × the smallest spacing (the option, or the preset's)
  double reuseTargetVoxels = 0.1;  ///< ImageSearchOptions::reuseTargetVoxels (the option, or the preset's)
  std::vector<double> sigmaMm;     ///< image scale per level, coarse first
  std::vector<double> rangeMm;     ///< search range per level, coarse first
  SolverOptions solver;            ///< the evolution scheme with all its settings (what Solver runs)
};

/// Applies the preset to `opts` for an image grid (scales and ranges are relative to the voxel size).
ResolvedSettings resolveSettings(const SegmentOptions& opts, const Grid& grid);

}  // namespace msk
