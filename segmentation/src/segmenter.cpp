#include "msk/segmentation/segmenter.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <tuple>

#include "msk/core/error.h"
#include "msk/core/medial_axis.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/surface_separation.h"
#include "msk/core/tet_untangle.h"
#include "msk/core/volume_preservation.h"
#include "msk/core/volume_simplex.h"
#include "msk/imaging/rasterize.h"
#include "msk/imaging/surface_extraction.h"
#include "msk/segmentation/overlap_repair.h"
#include "msk/segmentation/surface_quality.h"
#include "msk/segmentation/tetrahedralize.h"

namespace msk {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Image features per scale, built on first use only.
class FeatureCache {
 public:
  explicit FeatureCache(const ImageF& image) : image_(image) {}
  const ImageFeatures& at(double sigmaMm) {
    const long key = std::lround(sigmaMm * 1000.0);
    auto it = cache_.find(key);
    if (it == cache_.end()) {
      const auto t0 = Clock::now();
      it = cache_.emplace(key, computeImageFeatures(image_, sigmaMm)).first;
      seconds_ += since(t0);
    }
    return it->second;
  }
  int built() const { return static_cast<int>(cache_.size()); }
  double seconds() const { return seconds_; }

 private:
  const ImageF& image_;
  std::map<long, ImageFeatures> cache_;
  double seconds_ = 0;
};

/// Weights in [0, 1] from search scores: strong edges (≥ half the median positive score) get full weight.
Eigen::VectorXd scoreWeights(const Eigen::VectorXd& scores) {
  std::vector<double> pos;
  for (int i = 0; i < scores.size(); ++i)
    if (scores[i] > 0) pos.push_back(scores[i]);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(scores.size());
  if (pos.empty()) return w;
  std::nth_element(pos.begin(), pos.begin() + pos.size() / 2, pos.end());
  const double ref = 0.5 * pos[pos.size() / 2];
  for (int i = 0; i < scores.size(); ++i) w[i] = ref > 0 ? std::min(1.0, scores[i] / ref) : 0.0;
  return w;
}

/// Moves each target toward its vertex until it is at most `edges` local edge lengths (the vertex's mean distance to
/// its three neighbours) away: a limit on the image step, so that no vertex moves more than about γ × `edges` mesh
/// spacings per step. Targets a muscle cannot reach (at a partner, or where a septum is missing) otherwise pull at
/// full length step after step, and the surface buckles between them: on the thigh phantoms 350–1000 folded dual
/// edges per muscle without the limit, 35–55 % fewer with 1 edge, with equal or better Dice. Limiting only a vertex's
/// step relative to its neighbours' mean step was tried and does not help: the absolute step matters.
void limitTargetStep(const SimplexMesh& mesh, double edges, Points& targets) {
  const Points& p = mesh.positions;
  for (int v = 0; v < mesh.vertexCount(); ++v) {
    double edge = 0;
    for (int c = 0; c < 3; ++c) edge += (p.row(mesh.neighbors(v, c)) - p.row(v)).norm();
    const double cap = edges * edge / 3.0;
    const Eigen::RowVector3d d = targets.row(v) - p.row(v);
    const double len = d.norm();
    if (len > cap) targets.row(v) = p.row(v) + (cap / len) * d;
  }
}

struct LevelMeshes {
  TriangleMesh triangles;  ///< template at this level
  SimplexMesh simplex;     ///< its dual
};

}  // namespace

Quality parseQuality(const std::string& t) {
  if (t == "fast") return Quality::Fast;
  if (t == "balanced") return Quality::Balanced;
  if (t == "accurate") return Quality::Accurate;
  throw ParameterError("quality", t, "must be fast, balanced or accurate");
}

const char* qualityName(Quality q) {
  switch (q) {
    case Quality::Fast: return "fast";
    case Quality::Balanced: return "balanced";
    case Quality::Accurate: return "accurate";
  }
  return "?";
}

PriorTransform parsePriorTransform(const std::string& t, const std::string& option) {
  if (t == "rigid") return PriorTransform::Rigid;
  if (t == "similarity") return PriorTransform::Similarity;
  if (t == "affine") return PriorTransform::Affine;
  throw ParameterError(option, t, "must be rigid, similarity or affine");
}

const char* priorTransformName(PriorTransform t) {
  switch (t) {
    case PriorTransform::Rigid: return "rigid";
    case PriorTransform::Similarity: return "similarity";
    case PriorTransform::Affine: return "affine";
  }
  return "?";
}

const char* polarityName(Polarity p) {
  switch (p) {
    case Polarity::Auto: return "auto";
    case Polarity::DarkInside: return "dark-inside";
    case Polarity::BrightInside: return "bright-inside";
  }
  return "?";
}

ResolvedSettings resolveSettings(const SegmentOptions& o, const Grid& grid) {
  ResolvedSettings s;
  const double minSp = grid.spacing.minCoeff(), maxSp = grid.spacing.maxCoeff();
  // The presets (measured with `mskseg bench tradeoff`, see README): levels, step cap per level, tolerance in units
  // of the smallest spacing, scheme, substeps × iterations.
  int levels = 2, steps = 50, substeps = 1, iterations = 1;
  double tolFactor = 0.02;
  Scheme scheme = Scheme::GaussSeidel;
  switch (o.quality) {
    case Quality::Fast:  // one level: no coarse search, one image scale (capture range ± 1.5 voxels only)
      levels = 1; steps = 15; tolFactor = 0.04; scheme = Scheme::Xpbd; substeps = 2; iterations = 2;
      break;
    case Quality::Balanced:
      levels = 2; steps = 50; tolFactor = 0.02; scheme = Scheme::GaussSeidel; substeps = 1; iterations = 1;
      break;
    case Quality::Accurate:  // a tight tolerance and a lighter finest blur (sigmaFineVoxels): the least surface distance
      levels = 3; steps = 200; tolFactor = 0.004; scheme = Scheme::Xpbd; substeps = 2; iterations = 2;
      break;
  }
  s.levels = o.levels > 0 ? o.levels : levels;
  s.maxStepsPerLevel = o.maxStepsPerLevel > 0 ? o.maxStepsPerLevel : steps;
  s.toleranceMm = o.toleranceMm > 0 ? o.toleranceMm : tolFactor * minSp;
  if (o.scheme && *o.scheme != scheme) {
    // Another scheme than the preset's: the substeps × iterations it needs on the same schedule (measured on the
    // femur phantoms: explicit Euler needs ≥ 4 substeps, Jacobi two sweeps to keep pace with Gauss–Seidel).
    scheme = *o.scheme;
    substeps = scheme == Scheme::Xpbd ? 2 : scheme == Scheme::Explicit ? 4 : 1;
    iterations = scheme == Scheme::Xpbd || scheme == Scheme::Jacobi ? 2 : 1;
  }
  s.solver = SolverOptions::fromPbd(o.pbd);
  s.solver.scheme = scheme;
  s.solver.substeps = o.substeps > 0 ? o.substeps : substeps;
  s.solver.iterations = o.iterations > 0 ? o.iterations : o.pbd.iterations != 1 ? o.pbd.iterations : iterations;
  s.solver.threads = o.threads;
  s.solver.stiffness = o.xpbdStiffness;
  s.solver.xpbdStiffness = XpbdStiffness::MassRelative;
  s.solver.omega = o.jacobiOmega;
  s.sigmaFineVoxels = o.sigmaFine ? *o.sigmaFine : o.quality == Quality::Accurate ? 0.25 : 0.5;
  // Coarse levels see a smoother image over a longer range; the finest level a light blur over a short range.
  for (int l = 0; l < s.levels; ++l) {
    const double f = s.levels == 1 ? 0.0 : 1.0 - static_cast<double>(l) / (s.levels - 1);  // 1 coarse → 0 fine
    s.sigmaMm.push_back(minSp * (s.sigmaFineVoxels + (o.sigmaCoarse - s.sigmaFineVoxels) * f));
    s.rangeMm.push_back(maxSp * (o.rangeFine + (o.rangeCoarse - o.rangeFine) * f) + o.rangeCoarseExtraMm * f);
  }
  return s;
}

Json settingsJson(const SegmentOptions& o, const ResolvedSettings& s) {
  Json j;
  j["quality"] = qualityName(o.quality);
  j["scheme"] = schemeName(s.solver.scheme);
  j["substeps"] = s.solver.substeps;
  j["iterations"] = s.solver.iterations;
  j["threads"] = s.solver.threads;
  if (s.solver.scheme == Scheme::Xpbd) {
    j["xpbd_stiffness"] = s.solver.stiffness;
    j["xpbd_stiffness_unit"] = "mass-relative";
  }
  if (s.solver.scheme == Scheme::Jacobi) j["jacobi_omega"] = s.solver.omega;
  if (s.solver.scheme == Scheme::Explicit || s.solver.scheme == Scheme::Implicit) {
    j["force_damping_ratio"] = s.solver.forceDamping;
    j["anisotropy"] = s.solver.anisotropy;
  }
  if (s.solver.scheme == Scheme::Implicit) {
    j["cg_iterations"] = s.solver.cgIterations;
    j["cg_tolerance"] = s.solver.cgTolerance;
  }
  j["levels"] = s.levels;
  j["max_steps_per_level"] = s.maxStepsPerLevel;
  j["tolerance_mm"] = s.toleranceMm;
  Json sig = Json::array(), rng = Json::array();
  for (double v : s.sigmaMm) sig.push(v);
  for (double v : s.rangeMm) rng.push(v);
  j["image_sigma_mm_per_level"] = sig;
  j["search_range_mm_per_level"] = rng;
  j["internal_stiffness"] = o.internalStiffness;
  j["internal_mode"] = o.internalMode == InternalMode::ShapeMemory ? "shape-memory" : "smoothing";
  j["image_stiffness"] = o.imageStiffness;
  j["global_prior"] = priorTransformName(o.priorTransform);
  j["global_prior_weight_start"] = o.priorStart;
  j["global_prior_weight_end"] = o.priorEnd;
  j["far_target_scale_mm"] = o.farTargetScaleMm;
  j["sigma_fine_voxels"] = s.sigmaFineVoxels;
  j["sigma_coarse_voxels"] = o.sigmaCoarse;
  j["range_fine_voxels"] = o.rangeFine;
  j["range_coarse_voxels"] = o.rangeCoarse;
  j["range_coarse_extra_mm"] = o.rangeCoarseExtraMm;
  j["edge_penalty_per_mm"] = o.edgePenalty;
  j["edge_focusing"] = o.edgeFocusing;
  j["edge_level"] = o.edgeLevel;
  j["refine_pass"] = o.refinePass;
  j["remesh_templates"] = o.remeshTemplates;
  j["unfold_surfaces"] = o.unfoldSurfaces;
  j["refine_sigma_voxels"] = o.refineSigma;
  j["muscle_target_step_edges"] = o.muscleTargetStepEdges;
  j["collisions"] = o.collisions;
  j["collision_gap_mm"] = o.collisionGapMm;
  j["collision_proximity_mm"] = o.collisionProximityMm;
  j["collision_friction"] = o.collisionFriction;
  // Per pair what the run used (segmentScene() fills it); without pairs (or outside a run) the run's default.
  if (s.collisionResponses.empty()) {
    j["collision_mode"] = std::string("position, spring target, ") + collisionResolutionName(o.collisionResolution);
  } else {
    Json modes = Json::array();
    for (const PairResponse& p : s.collisionResponses) {
      Json m;
      m["objects"] = Json(Json::Array{p.a, p.b});
      m["mode"] = collisionModeName(p.response.mode);
      m["target"] = collisionTargetName(p.response.target);
      m["resolution"] = collisionResolutionName(p.response.resolution);
      modes.push(m);
    }
    j["collision_mode"] = modes;
  }
  j["collision_resolution"] = collisionResolutionName(o.collisionResolution);
  j["collision_position_beyond_mm"] = o.collisionPositionBeyondMm;
  j["collision_final_sweeps"] = o.collisionFinalSweeps;
  j["separation_sweeps"] = o.separationSweeps;
  j["collision_side_test_every"] = o.collisionSideTestEvery;
  j["radial_stiffness"] = o.radialStiffness;
  j["axis_spacing_mm"] = o.axisSpacingMm;
  j["axis_centering"] = o.axisCentering;
  j["axis_first"] = o.axisFirst;
  j["axis_first_max_steps"] = o.axisFirstSteps;
  j["axis_first_image_gain"] = o.axisFirstStage.imageGain;
  j["axis_first_shape_memory"] = o.axisFirstStage.shapeMemory;
  if (!s.axisFirst.empty()) {
    Json stage = Json::array();
    for (const AxisFirstReport& a : s.axisFirst) {
      Json r;
      r["object"] = a.object;
      r["steps"] = a.steps;
      r["converged"] = a.converged;
      r["last_max_move_mm"] = a.lastMaxMoveMm;
      r["mean_axis_move_mm"] = a.meanAxisMoveMm;
      r["seconds"] = a.seconds;
      stage.push(r);
    }
    j["axis_first_stage"] = stage;
  }
  j["volume_stiffness"] = o.volumeStiffness;
  j["bone_mass_ratio"] = o.boneMassRatio;
  j["pbd_dt"] = o.pbd.dt;
  j["pbd_damping"] = o.pbd.damping;
  j["pbd_drag"] = o.pbd.drag;
  return j;
}

namespace {

/// One object's evolving state across levels.
struct ObjectState {
  const SceneObject* obj = nullptr;
  ObjectResult out;
  std::vector<LevelMeshes> lv;  ///< index 0 finest
  TargetSearchOptions search;
  Polarity polarity = Polarity::Auto;
  SimplexMesh current;
  Eigen::VectorXd residual;
  double searchSeconds = 0;
  int first = 0;  ///< first particle in the stacked system at the current level
  // Per-level constraint sets.
  std::unique_ptr<SimplexInternalConstraints> internal;
  std::unique_ptr<TargetConstraints> targets;
  std::unique_ptr<ShapeMatchingConstraint> prior;
  LearnedProfiles profiles;
  // Medial axis (objects whose model asks for one): its particles follow every object's surface in the stacked system.
  MedialAxis axis;                 ///< at the current level, template position
  RadialAttachment attachment;     ///< surface vertices of this level → axis segments, reference radii
  Points axisStart;                ///< axis particles at the start of the level (template axis moved with the surface)
  int axisFirst = 0;               ///< first axis particle in the stacked system
  std::unique_ptr<RadialConstraints> radial;
  std::unique_ptr<AxisCentering> centering;
  // 3-simplex volume model (objects whose model asks for one), at the finest level: its tet vertices are the particles
  // right before the surface's, whose simplex vertices are the model's ghosts (the finest template is the boundary of
  // the tetrahedralised template), so the surface and the volume share those particles.
  std::optional<VolumeSimplexMesh> volume;
  std::unique_ptr<VolumeSimplexConstraints> volumeSet;
  std::unique_ptr<VolumePreservation> volumeHold;  ///< holds the template's volume unless the image demands another
  int volFirst = 0;        ///< first tet particle in the stacked system
  Points volStart, volFinal;  ///< tet particles at the start and the end of the finest level
  Eigen::VectorXd volRestVolumes;  ///< volumes of the volume model's rest tets, mm³ (finishObject())
  Eigen::VectorXi volSurfaceNode;  ///< tet node of each vertex of the output surface (finishObject())
  /// Tet particles at level l (0 unless the object is volumetric and l is the finest level).
  int tetCount(int l) const { return volume && l == 0 ? volume->tetCount() : 0; }
  /// The constraint sets of this object at the current level, in projection order (image, internal, prior, radial).
  std::vector<ConstraintSet*> sets() const {
    std::vector<ConstraintSet*> out;
    for (ConstraintSet* c : {static_cast<ConstraintSet*>(targets.get()), static_cast<ConstraintSet*>(internal.get()),
                             static_cast<ConstraintSet*>(prior.get()), static_cast<ConstraintSet*>(radial.get()),
                             static_cast<ConstraintSet*>(centering.get()), static_cast<ConstraintSet*>(volumeSet.get()),
                             static_cast<ConstraintSet*>(volumeHold.get())})
      if (c) out.push_back(c);
    return out;
  }
  /// Whether the object's model has a medial axis.
  bool hasAxis() const { return obj && obj->model.medialAxis; }
  // Axis-first stage (objects that run it): the coarsest template's axis and where the stage left it.
  Points stageAxisRef, stageAxis;  ///< empty without the stage
  /// Template points (any level's surface or axis) swept by the axis-first stage (GeneralisedCylinder about the
  /// coarsest template axis); unchanged without the stage.
  Points bentByStage(const Points& templ) const {
    if (stageAxis.rows() == 0) return templ;
    return GeneralisedCylinder(templ, stageAxisRef, attachToAxis(templ, stageAxisRef)).surface(stageAxis);
  }
  /// Whether the object runs the axis-first coarse stage (its model's "axis_first", else the run's default).
  bool runsAxisFirst(const SegmentOptions& o) const { return hasAxis() && obj->model.axisFirst.value_or(o.axisFirst); }
  /// Whether the object takes part in the refinement pass (its model's "refine", else the run's).
  bool refines(const SegmentOptions& o) const { return obj->model.refine.value_or(o.refinePass); }
  Points axisEnd;  ///< axis particles where the last pass left them (a refinement pass's fixed objects keep them)
  /// Number of axis particles at the current level (0 without an axis).
  int axisCount() const { return hasAxis() ? axis.curve.vertexCount() : 0; }
};

/// Builds the resolution levels, polarity and search settings of one object.
void prepareObject(ObjectState& st, const SegmentOptions& opts, const ResolvedSettings& rs, FeatureCache& features) {
  const SceneObject& obj = *st.obj;
  st.out.name = obj.name;
  st.out.label = obj.label;
  st.out.templateVolumeMm3 = enclosedVolume(obj.templ);
  st.out.templateVertices = obj.templ.vertexCount();
  // Unless its model says: bones keep their template's triangulation (a bone template made by decimation puts its
  // vertices where the surface bends, condyles and head, which a uniform remesh spreads out: phantom femurs 0.01–0.06
  // mm more ASSD; they showed no fold without it), muscles and generic objects take the run's. A volumetric object's
  // surface is its tetrahedralisation's boundary, which the mesher makes of well-shaped facets anyway.
  st.out.remeshed =
      obj.model.remesh.value_or(opts.remeshTemplates && obj.kind != ObjectKind::Bone) && !obj.model.volumetric;
  const TriangleMesh templ = st.out.remeshed ? remeshIsotropic(obj.templ, obj.templ.vertexCount()) : obj.templ;
  // Resolution levels of the template: index 0 finest; each coarser level has about a quarter of the vertices.
  st.lv.resize(static_cast<size_t>(rs.levels));
  st.lv[0].triangles = templ;
  TetMesh tets;
  if (obj.model.volumetric) {
    // Tetrahedra about as large as the template's triangles; the finest surface becomes the tet mesh's boundary.
    const double edge = meanEdgeLength(templ);
    TetOptions to;
    to.facetSizeMm = edge;
    to.cellSizeMm = 1.5 * edge;
    to.facetDistanceMm = 0.1 * edge;
    // ODT smoothing, sliver perturbation and exudation: fewer badly shaped tets to fold at the surface.
    to.odt = to.perturb = to.exude = true;
    // Every tet gets a node off the surface, so finishObject() can untangle any tet the surface folds.
    to.interiorNodes = true;
    tets = tetrahedralize(templ, to);
    st.volume = volumeSimplexFromTets(tets);
    st.lv[0].triangles = tetBoundary(tets);
  }
  for (int l = 1; l < rs.levels; ++l) {
    const int target = std::max(150, st.lv[l - 1].triangles.vertexCount() / 4);
    st.lv[l].triangles = target < st.lv[l - 1].triangles.vertexCount() ? decimateMesh(st.lv[l - 1].triangles, target)
                                                                       : st.lv[l - 1].triangles;
  }
  for (auto& l : st.lv) l.simplex = simplexFromTriangles(l.triangles);
  if (st.volume) {
    // The surface's simplex vertices must be the model's ghosts, in the same order and place.
    const Points& ghosts = st.volume->boundary.positions;
    if (ghosts.rows() != st.lv[0].simplex.vertexCount() ||
        (ghosts - st.lv[0].simplex.positions).cwiseAbs().maxCoeff() > 1e-6 * (1.0 + ghosts.cwiseAbs().maxCoeff()))
      throw Error(obj.name + ": the volume model's boundary does not match its surface model");
  }
  st.search.mode = obj.hasForce ? obj.force : obj.model.imageForce;
  st.search.distancePenalty = opts.edgePenalty;
  // Polarity: the object's setting, else estimated once on the coarsest scale at the template position, on the template
  // as given (a vote over its vertices: remeshed, the same surface votes with other weights, and a borderline case such
  // as the phantom femur's thin cortex over bright marrow would flip).
  st.polarity = obj.hasPolarity ? obj.polarity : Polarity::Auto;
  if (st.polarity == Polarity::Auto) {
    const SimplexMesh given = st.out.remeshed ? simplexFromTriangles(obj.templ) : st.lv[0].simplex;
    st.polarity = estimatePolarity(features.at(rs.sigmaMm[0]), given.positions, simplexVertexNormals(given));
  }
  st.out.polarity = st.polarity;
  st.current = st.lv[static_cast<size_t>(rs.levels - 1)].simplex;
}

/// Moves an object to level `l` (carrying the coarser level's displacement) and builds its constraint sets. The
/// refinement pass (`refine`, level 0 again) keeps the surface where it is and takes it as the reference shape, with
/// the gradient force and the edge level estimated there.
void enterLevel(ObjectState& st, int l, int coarsest, const SegmentOptions& opts, const ImageFeatures& feat,
                const Grid& grid, bool refine = false) {
  const LevelMeshes& ref = st.lv[static_cast<size_t>(l)];
  if (l != coarsest && !refine) {
    // Carry the displacement of the coarser level's surface over to this level's template.
    const LevelMeshes& coarse = st.lv[static_cast<size_t>(l + 1)];
    const TriangleMesh moved = trianglesFromSimplex(st.current);
    const Eigen::MatrixXd disp = moved.vertices - coarse.triangles.vertices;
    SurfaceTransfer transfer(coarse.triangles, ref.triangles.vertices);
    TriangleMesh start = ref.triangles;
    start.vertices += transfer.apply(disp);
    st.current = simplexFromTriangles(start);
  }
  st.search.mode = refine ? TargetMode::Gradient : st.obj->hasForce ? st.obj->force : st.obj->model.imageForce;
  st.search.edgeLevel = std::numeric_limits<double>::quiet_NaN();
  if (st.search.mode == TargetMode::Gradient && (opts.edgeLevel || refine)) {
    const SimplexMesh& at = refine ? st.current : ref.simplex;
    st.search.edgeLevel = estimateEdgeLevel(feat, at.positions, simplexVertexNormals(at));
  }
  if (st.search.mode == TargetMode::Profile) {
    // Learned where the template came from (e.g. the mirrored contralateral structure) when the scene says so.
    Points positions = ref.simplex.positions, normals = simplexVertexNormals(ref.simplex);
    toProfileSource(*st.obj, positions, normals);
    st.profiles = learnProfiles(feat, positions, normals, st.search, grid);
  }
  // Only what the object's model asks for is built.
  const ObjectModel& model = st.obj->model;
  // After the axis-first stage, the template swept by the stage's axis is the object's reference shape (shape memory,
  // global prior, axis and radii): the straight template's similarity prior would otherwise pull the bend back out.
  const SimplexMesh* shape = &ref.simplex;
  SimplexMesh bentShape;
  if (refine) {
    bentShape = st.current;
    shape = &bentShape;
  } else if (st.stageAxis.rows() > 0) {
    bentShape = ref.simplex;
    bentShape.positions = st.bentByStage(ref.simplex.positions);
    shape = &bentShape;
  }
  st.internal.reset();
  if (model.shapeMemory)
    st.internal = std::make_unique<SimplexInternalConstraints>(
        *shape, model.internalStiffness >= 0 ? model.internalStiffness : opts.internalStiffness,
        opts.internalMode == InternalMode::Smoothing ? InternalMode::Smoothing : *model.shapeMemory);
  st.targets = std::make_unique<TargetConstraints>(opts.imageStiffness);
  st.prior.reset();
  if (model.globalPrior)
    st.prior = std::make_unique<ShapeMatchingConstraint>(shape->positions,
                                                         model.priorTransform.value_or(opts.priorTransform), opts.priorStart);
  st.radial.reset();
  st.centering.reset();
  if (model.medialAxis) {
    // The axis of this level's template, its surface vertices attached with their template radii; the axis starts
    // where the best similarity fit of the template onto the current surface puts it.
    MedialAxisOptions mo;
    mo.spacingMm = model.axisSpacingMm > 0 ? model.axisSpacingMm : opts.axisSpacingMm;
    st.axis = buildMedialAxis(refine ? trianglesFromSimplex(st.current) : ref.triangles, mo);
    if (shape != &ref.simplex && !refine) st.axis.curve.positions = st.bentByStage(st.axis.curve.positions);
    st.attachment = attachToAxis(shape->positions, st.axis.curve.positions);
    const Eigen::Matrix4d fit = fitTransform(shape->positions, st.current.positions,
                                             Eigen::VectorXd::Ones(ref.simplex.vertexCount()), PriorTransform::Similarity);
    st.axisStart = ((st.axis.curve.positions * fit.topLeftCorner<3, 3>().transpose()).rowwise() +
                    fit.topRightCorner<3, 1>().transpose());
  }
  st.volumeSet.reset();
  st.volumeHold.reset();
  if (st.volume && l == 0) {
    // Tet vertices start where the best affine fit of the template surface onto the current one puts them.
    // The refinement pass starts them where the finest level left them.
    if (refine) {
      st.volStart = st.volFinal;
    } else {
      const int nt = st.volume->tetCount();
      const Eigen::Matrix4d fit = fitTransform(ref.simplex.positions, st.current.positions,
                                               Eigen::VectorXd::Ones(ref.simplex.vertexCount()), PriorTransform::Affine);
      st.volStart = (st.volume->simplex.positions.topRows(nt) * fit.topLeftCorner<3, 3>().transpose()).rowwise() +
                    fit.topRightCorner<3, 1>().transpose();
    }
    const double gamma = model.volumeStiffness >= 0 ? model.volumeStiffness : opts.volumeStiffness;
    st.volumeSet = std::make_unique<VolumeSimplexConstraints>(*st.volume, gamma, VolumeBoundary::SurfaceDriven);
    // The template's volume, held unless the image demands another (volume_preservation.h).
    st.volumeHold = std::make_unique<VolumePreservation>(ref.simplex);
  }
  for (ConstraintSet* c : st.sets()) c->setFirstParticle(st.first);
  if (st.volumeSet) st.volumeSet->setFirstParticle(st.volFirst);  // tets first, then the ghosts = the surface
}

/// Detects the contacts of every collision set at positions `p`. The sets only read the positions and their shared
/// partner surfaces (updated before), and each writes its own contacts, so they run on `threads` threads (0 = all
/// cores) with the same result as one.
void detectAll(std::vector<std::unique_ptr<CollisionConstraints>>& sets, const Points& p, bool sideTest, int threads) {
  const size_t n = sets.size();
  const size_t workers = std::min(n, static_cast<size_t>(threads > 0 ? threads : std::max(1u, std::thread::hardware_concurrency())));
  if (workers <= 1) {
    for (auto& c : sets) c->detect(p, sideTest);
    return;
  }
  std::atomic<size_t> next{0};
  std::exception_ptr failure;
  std::mutex failureMutex;
  auto work = [&]() {
    for (size_t k = next++; k < n; k = next++) {
      try {
        sets[k]->detect(p, sideTest);
      } catch (...) {
        std::lock_guard<std::mutex> lock(failureMutex);
        if (!failure) failure = std::current_exception();
      }
    }
  };
  std::vector<std::thread> pool;
  for (size_t t = 1; t < workers; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
}

/// Builds the radial constraints and the axis re-centring of an object with a medial axis, once its axis particles
/// have their place in the stacked system (st.axisFirst).
void buildAxisSets(ObjectState& st, const SegmentOptions& opts) {
  const ObjectModel& model = st.obj->model;
  const double gamma = model.radialStiffness >= 0 ? model.radialStiffness : opts.radialStiffness;
  st.radial = std::make_unique<RadialConstraints>(st.attachment, st.axisFirst, gamma);
  st.centering = std::make_unique<AxisCentering>(st.attachment, st.axisFirst, st.axis.curve.vertexCount(), opts.axisCentering);
  st.radial->setFirstParticle(st.first);
  st.centering->setFirstParticle(st.first);
}

/// One object's image targets at `mesh` (its current surface): the search (timed into st.searchSeconds), score weights
/// with the optional far-target down-weighting, and a muscle's per-step limit.
struct ImageTargets {
  Points targets;
  Eigen::VectorXd weights, residual;
};
ImageTargets imageTargets(ObjectState& st, const SimplexMesh& mesh, const SegmentOptions& opts,
                          const ImageFeatures& feat, const Grid& grid, const ImageFeatures* focus) {
  const auto ts = Clock::now();
  const TargetSearchResult found =
      searchTargets(feat, mesh.positions, simplexVertexNormals(mesh), mesh.neighbors, st.search, st.polarity, grid,
                    st.search.mode == TargetMode::Profile ? &st.profiles : nullptr, focus);
  st.searchSeconds += since(ts);
  ImageTargets out{found.targets, scoreWeights(found.scores), found.residual};
  if (opts.farTargetScaleMm > 0)  // robust (Cauchy) down-weighting of far targets: outliers pull less
    for (int i = 0; i < out.weights.size(); ++i)
      out.weights[i] /= 1.0 + std::pow(found.offsets[i] / opts.farTargetScaleMm, 2);
  if (opts.muscleTargetStepEdges > 0 && st.obj->kind == ObjectKind::Muscle)
    limitTargetStep(mesh, opts.muscleTargetStepEdges, out.targets);
  return out;
}

/// The axis-first coarse stage (DESIGN-NOTES §4, "evolve the axis first") of an object with a medial axis at level
/// `l`, after enterLevel() and before the full-surface evolution: the object moves as a generalised cylinder of its
/// axis (GeneralisedCylinder: the surface keeps its template radii about the axis, the axis is driven by the
/// attachment-weighted mean of its surface vertices' image-target displacements — searched, score-weighted and
/// step-limited as in the full evolution — and keeps its shape), until no axis vertex moves more than the tolerance or
/// the step cap. The surface and axis particles then start from there, and the stage's axis is kept (stageAxis) so
/// that enterLevel() bends every level's reference shape with it; the caller rebuilds the level's sets. Objects do not
/// see each other in this stage: collisions act from the full evolution on.
AxisFirstReport runAxisFirst(ObjectState& st, int l, const SegmentOptions& opts, const ResolvedSettings& rs,
                             const ImageFeatures& feat, const Grid& grid) {
  AxisFirstReport rep;
  rep.object = st.obj->name;
  const GeneralisedCylinder cylinder(st.lv[static_cast<size_t>(l)].simplex.positions, st.axis.curve.positions,
                                     st.attachment);
  Points axis = st.axisStart;
  SimplexMesh mesh = st.current;
  for (int s = 0; s < opts.axisFirstSteps; ++s) {
    mesh.positions = cylinder.surface(axis);
    const ImageTargets found = imageTargets(st, mesh, opts, feat, grid, nullptr);
    const Points displacement =
        found.weights.cwiseMin(1.0).cwiseMax(0.0).asDiagonal() * (found.targets - mesh.positions);
    rep.lastMaxMoveMm = cylinder.step(axis, displacement, opts.axisFirstStage);
    ++rep.steps;
    if (rep.lastMaxMoveMm < rs.toleranceMm) {
      rep.converged = true;
      break;
    }
  }
  st.current.positions = cylinder.surface(axis);
  rep.meanAxisMoveMm = (axis - st.axisStart).rowwise().norm().mean();
  st.axisStart = axis;
  st.stageAxisRef = st.axis.curve.positions;
  st.stageAxis = axis;
  return rep;
}

/// Puts the boundary nodes of `out.volumeMesh` on the vertices of `out.mesh` (the written surface), then untangles:
/// tets the recovery or the surface left flat or inverted get their interior nodes moved to raise their volumes
/// relative to rest (tet_untangle.h), and where the surface leaves them no room, nearby boundary nodes by a tenth of
/// an edge at most; then the interior nodes of badly shaped tets are moved to better their shape (the worst tets left
/// have a thin boundary face, which no interior node can fix). Counts the volume and the inverted tets.
/// `restVolumes` are the volumes of the model's rest tets and `surfaceNode` the tet node of each surface vertex
/// (ObjectState).
void settleVolumeMesh(ObjectResult& out, const Eigen::VectorXd& restVolumes, const Eigen::VectorXi& surfaceNode) {
  MSK_ASSERT(surfaceNode.size() == out.mesh.vertexCount(), "volume model: tet boundary does not match the surface");
  for (Eigen::Index v = 0; v < surfaceNode.size(); ++v) out.volumeMesh.nodes.row(surfaceNode[v]) = out.mesh.vertices.row(v);
  untangleTetMesh(out.volumeMesh, restVolumes.cwiseMax(1e-3 * std::fabs(restVolumes.mean())),
                  0.1 * meanEdgeLength(out.mesh));
  improveWorstTetShapes(out.volumeMesh, 0.3);
  out.volumeModelMm3 = totalVolume(out.volumeMesh);
  out.invertedTets = static_cast<int>((tetVolumes(out.volumeMesh).array() <= 0).count());
  out.volumeModelTemplateMm3 = restVolumes.sum();
}

/// Final surface on the template's triangulation (as given, or remeshed), with per-vertex displacement and image
/// residual; local folds left by the evolution unfolded (`unfold`, unfoldSurface()).
void finishObject(ObjectState& st, bool unfold) {
  st.current.pointData.clear();
  st.current.pointData["image_residual_mm"] = st.residual.size() == st.current.vertexCount()
                                                  ? st.residual
                                                  : Eigen::VectorXd::Zero(st.current.vertexCount());
  ObjectResult& out = st.out;
  out.mesh = trianglesFromSimplex(st.current);
  if (unfold) {
    const UnfoldReport u = unfoldSurface(out.mesh);
    out.foldsFound = u.before;
    out.unfoldedVertices = u.verticesMoved;
    out.selfIntersections = u.after;
  }
  out.mesh.pointData["displacement_mm"] = (out.mesh.vertices - st.lv[0].triangles.vertices).rowwise().norm();
  if (st.volume) {
    Points all(st.volume->vertexCount(), 3);
    all.topRows(st.volume->tetCount()) = st.volFinal;
    all.bottomRows(st.volume->ghostCount()) = st.current.positions;
    all = relaxVolumeSimplexTets(*st.volume, all);  // the tets' equilibrium with the final surface (no lag)
    // Boundary nodes on the evolved surface's vertices (the tet boundary is the surface's triangulation, prepareObject),
    // interior nodes by least squares from the simplex vertices.
    const TetMesh rest = tetsFromVolumeSimplex(*st.volume, st.volume->simplex.positions);
    tetBoundary(rest, &st.volSurfaceNode);
    st.volRestVolumes = tetVolumes(rest);
    MSK_ASSERT(st.volSurfaceNode.size() == out.mesh.vertexCount(), "volume model: tet boundary does not match the surface");
    out.volumeMesh = tetsFromVolumeSimplex(*st.volume, all, st.volSurfaceNode, out.mesh.vertices);
    settleVolumeMesh(out, st.volRestVolumes, st.volSurfaceNode);
    if (st.volumeHold)
      out.volumeDecision = st.volumeHold->decision() == VolumeDecision::Holding     ? "holding"
                           : st.volumeHold->decision() == VolumeDecision::Following ? "following"
                                                                                     : "observing";
  }
  out.meanImageResidualMm = out.mesh.pointData["image_residual_mm"].mean();
  out.volumeMm3 = enclosedVolume(out.mesh);
  out.secondsPerFamily["image-search"] += st.searchSeconds;
  const std::string problem = closedMeshProblem(out.mesh);
  if (!problem.empty()) throw Error(st.obj->name + ": the evolved surface is invalid: " + problem);
}

}  // namespace

SegmentationResult segmentScene(const ImageF& image, const Scene& scene, const SegmentOptions& opts,
                                const ProgressFn& progress) {
  const auto t0 = Clock::now();
  checkUnitInterval("internal stiffness", opts.internalStiffness);
  checkUnitInterval("image stiffness", opts.imageStiffness);
  checkUnitInterval("global prior start", opts.priorStart);
  checkUnitInterval("global prior end", opts.priorEnd);
  checkUnitInterval("collision friction", opts.collisionFriction);
  checkUnitInterval("radial stiffness", opts.radialStiffness);
  checkUnitInterval("volume stiffness", opts.volumeStiffness);
  checkUnitInterval("axis centring", opts.axisCentering);
  checkUnitInterval("axis-first image gain", opts.axisFirstStage.imageGain);
  checkUnitInterval("axis-first shape memory", opts.axisFirstStage.shapeMemory);
  if (opts.axisFirstSteps < 0 || opts.axisFirstSteps > 100000)
    throw ParameterError("axis-first steps", std::to_string(opts.axisFirstSteps), "must be 0..100000");
  if (!(opts.axisSpacingMm >= 0.5 && opts.axisSpacingMm <= 100))
    throw ParameterError("axis spacing", std::to_string(opts.axisSpacingMm), "must be in [0.5, 100] mm");
  if (!(opts.muscleTargetStepEdges >= 0))
    throw ParameterError("muscle target step", std::to_string(opts.muscleTargetStepEdges), "must be >= 0 edge lengths");
  if (!(opts.collisionGapMm >= 0 && opts.collisionGapMm <= 10))
    throw ParameterError("collision gap", std::to_string(opts.collisionGapMm), "must be in [0, 10] mm");
  if (!(opts.collisionProximityMm >= 0 && opts.collisionProximityMm <= 50))
    throw ParameterError("collision proximity", std::to_string(opts.collisionProximityMm), "must be in [0, 50] mm (0 = auto)");
  if (!(opts.boneMassRatio >= 1e-3 && opts.boneMassRatio <= 1e3))
    throw ParameterError("bone mass ratio", std::to_string(opts.boneMassRatio), "must be in [0.001, 1000]");
  if (!(opts.collisionPositionBeyondMm >= 0))
    throw ParameterError("collision position threshold", std::to_string(opts.collisionPositionBeyondMm), "must be >= 0 mm");
  if (opts.collisionFinalSweeps < 0 || opts.collisionFinalSweeps > 1000)
    throw ParameterError("collision sweeps", std::to_string(opts.collisionFinalSweeps), "must be 0..1000");
  if (opts.collisionSideTestEvery < 0 || opts.collisionSideTestEvery > 100000)
    throw ParameterError("collision side test interval", std::to_string(opts.collisionSideTestEvery), "must be 0..100000");
  if (opts.separationSweeps < 0 || opts.separationSweeps > 1000)
    throw ParameterError("separation sweeps", std::to_string(opts.separationSweeps), "must be 0..1000");
  if (opts.levels < 0 || opts.levels > 5) throw ParameterError("levels", std::to_string(opts.levels), "must be 0..5");
  if (opts.maxStepsPerLevel < 0 || opts.maxStepsPerLevel > 100000)
    throw ParameterError("max steps", std::to_string(opts.maxStepsPerLevel), "must be 0..100000");
  if (!(opts.toleranceMm >= 0) || !std::isfinite(opts.toleranceMm))
    throw ParameterError("tolerance", std::to_string(opts.toleranceMm), "must be ≥ 0 mm");
  if (opts.threads < 0 || opts.threads > 1024) throw ParameterError("threads", std::to_string(opts.threads), "must be 0..1024");
  validateSolverOptions(resolveSettings(opts, Grid{}).solver);  // throws on bad scheme settings
  for (auto [name, v, hi] : {std::tuple{"sigma fine", opts.sigmaFine.value_or(0.5), 10.0}, std::tuple{"sigma coarse", opts.sigmaCoarse, 10.0},
                             std::tuple{"refine sigma", opts.refineSigma, 10.0},
                             std::tuple{"range fine", opts.rangeFine, 20.0}, std::tuple{"range coarse", opts.rangeCoarse, 20.0},
                             std::tuple{"range coarse extra mm", opts.rangeCoarseExtraMm, 1000.0},
                             std::tuple{"edge penalty", opts.edgePenalty, 10.0}})
    if (!(v >= 0 && v <= hi)) throw ParameterError(name, std::to_string(v), "must be in [0, " + std::to_string(hi) + "]");
  if (!(opts.rangeFine > 0)) throw ParameterError("range fine", std::to_string(opts.rangeFine), "must be positive");
  const std::string gridProblem = image.grid.problem();
  if (!gridProblem.empty()) throw Error("image: " + gridProblem);
  for (float v : image.data)
    if (!std::isfinite(v)) throw Error("image has NaN/Inf voxels");
  if (scene.objects.empty()) throw Error("scene has no objects");

  SegmentationResult res;
  res.settings = resolveSettings(opts, image.grid);
  // The response of each pair (Table 4.23: mode and target from the scene; resolution from the scene or the run).
  auto pairResponse = [&](const CollisionPair& p) {
    return CollisionResponse{p.mode, p.target, p.resolution.value_or(opts.collisionResolution),
                             opts.collisionPositionBeyondMm};
  };
  if (opts.collisions)
    for (const CollisionPair& p : scene.collisions)
      res.settings.collisionResponses.push_back({scene.objects[static_cast<size_t>(p.a)].name,
                                                 scene.objects[static_cast<size_t>(p.b)].name, pairResponse(p)});
  const ResolvedSettings& rs = res.settings;
  FeatureCache features(image);
  const auto te = Clock::now();
  std::vector<ObjectState> objs(scene.objects.size());
  for (size_t i = 0; i < objs.size(); ++i) {
    objs[i].obj = &scene.objects[i];
    prepareObject(objs[i], opts, rs, features);
  }
  // All objects evolve together, level by level, stacked in one particle system (the ground for collision
  // corrections between declared pairs, which must move both partners and conserve momentum).
  const int coarsest = rs.levels - 1;
  const double proximity =
      opts.collisionProximityMm > 0 ? opts.collisionProximityMm : std::max(1.0, 0.5 * image.grid.spacing.maxCoeff());
  double collisionDetectSeconds = 0;
  const int detectionThreads = opts.threads;
  // Contact parameters of a pair: the scene's values where it sets them, else the run's.
  auto pairGap = [&](const CollisionPair& p) { return p.gapMm >= 0 ? p.gapMm : opts.collisionGapMm; };
  auto pairProximity = [&](const CollisionPair& p) { return p.proximityMm > 0 ? p.proximityMm : proximity; };
  auto pairFriction = [&](const CollisionPair& p) { return p.friction >= 0 ? p.friction : opts.collisionFriction; };
  // Passes: the levels, coarsest first, then the refinement pass at the finest level again if an object refines. In
  // that pass the objects that do not refine stay where they are: their particles are fixed, their sets not built.
  const bool anyRefines = std::any_of(objs.begin(), objs.end(), [&](const ObjectState& st) { return st.refines(opts); });
  const int passes = rs.levels + (anyRefines ? 1 : 0);
  const int totalSteps = passes * rs.maxStepsPerLevel;
  const int rampSteps = rs.levels * rs.maxStepsPerLevel;  // the prior's ramp spans the levels; refinement is at its end
  int stepsDone = 0;
  for (int pass = 0; pass < passes; ++pass) {
    const bool refine = pass == rs.levels;
    const int l = refine ? 0 : coarsest - pass;
    const int order = coarsest - l;  // 0 for the coarsest level
    auto fixed = [&](const ObjectState& st) { return refine && !st.refines(opts); };
    const double sigmaMm = refine ? opts.refineSigma * image.grid.spacing.minCoeff() : rs.sigmaMm[order];
    const ImageFeatures& feat = features.at(sigmaMm);
    const ImageFeatures* focus = opts.edgeFocusing && order + 1 < rs.levels ? &features.at(rs.sigmaMm.back()) : nullptr;
    int n = 0;
    for (auto& st : objs) {
      st.volFirst = n;  // a volume model's tet particles come right before its surface's
      n += st.tetCount(l);
      st.first = n;
      st.search.rangeMm = rs.rangeMm[order];
      if (!fixed(st)) enterLevel(st, l, coarsest, opts, feat, image.grid, refine);
      n += st.current.vertexCount();
    }
    // Medial-axis particles follow all the surfaces.
    for (auto& st : objs)
      if (st.hasAxis()) {
        st.axisFirst = n;
        n += st.axisCount();
        if (!fixed(st)) buildAxisSets(st, opts);
        if (pass == 0) ++res.medialAxesBuilt;
      }
    // The axis-first coarse stage, for the objects that ask for it, before the coarsest level's full evolution.
    if (pass == 0)
      for (auto& st : objs)
        if (st.runsAxisFirst(opts)) {
          const auto ta = Clock::now();
          res.settings.axisFirst.push_back(runAxisFirst(st, l, opts, rs, feat, image.grid));
          // The level's sets again, now about the template the stage bent (same particle counts and places).
          enterLevel(st, l, coarsest, opts, feat, image.grid);
          buildAxisSets(st, opts);
          res.settings.axisFirst.back().seconds = since(ta);
          res.secondsPerStage["axis-first"] += res.settings.axisFirst.back().seconds;
        }
    if (pass == 0)
      for (const auto& st : objs) res.volumeModelsBuilt += st.volume ? 1 : 0;
    Points x(n, 3);
    for (const auto& st : objs) {
      x.middleRows(st.first, st.current.vertexCount()) = st.current.positions;
      if (st.hasAxis()) x.middleRows(st.axisFirst, st.axisCount()) = fixed(st) ? st.axisEnd : st.axisStart;
      if (st.volumeSet) x.middleRows(st.volFirst, st.tetCount(l)) = fixed(st) ? st.volFinal : st.volStart;
    }
    std::vector<ConstraintSet*> sets;
    for (auto& st : objs)
      if (!fixed(st))
        for (ConstraintSet* c : st.sets()) sets.push_back(c);
    // Bones are heavier, so a contact moves the muscle more than the bone (masses only matter for shared corrections:
    // image targets and shape memory do not depend on a uniform mass scale). An axis carries the mass of its surface.
    Eigen::VectorXd invMass = Eigen::VectorXd::Ones(n);
    for (const auto& st : objs) {
      if (st.obj->kind == ObjectKind::Bone) {
        invMass.segment(st.first, st.current.vertexCount()).setConstant(1.0 / opts.boneMassRatio);
        invMass.segment(st.volFirst, st.tetCount(l)).setConstant(1.0 / opts.boneMassRatio);
      }
      if (st.hasAxis())
        invMass.segment(st.axisFirst, st.axisCount()) =
            axisInverseMass(st.attachment, st.axisCount(), invMass.segment(st.first, st.current.vertexCount()));
      if (fixed(st)) {
        invMass.segment(st.volFirst, st.tetCount(l)).setZero();
        invMass.segment(st.first, st.current.vertexCount()).setZero();
        if (st.hasAxis()) invMass.segment(st.axisFirst, st.axisCount()).setZero();
      }
    }
    // Collision sets, only for declared pairs: each direction is A's vertices against B's surface (fan triangles of
    // B's simplex faces, whose corners are B's particles). Projected last in a step, so contacts have the last word.
    // Each partner surface is set up once per level and its grid rebuilt once per step, shared by the sets against it.
    std::vector<std::unique_ptr<CollisionConstraints>> collide;  // pair k: [2k] = first against second, [2k+1] back
    std::map<size_t, std::shared_ptr<CollisionSurface>> surfaces;
    // Pairs resolved globally: their sets are solved together, one system per mode (the sets alone do nothing).
    std::map<CollisionMode, std::unique_ptr<GlobalCollisionResolution>> global;
    if (opts.collisions && !scene.collisions.empty()) {
      // Each surface must reach the largest gap + proximity of the pairs it is a partner in.
      std::map<size_t, double> reach;
      for (const CollisionPair& pair : scene.collisions)
        for (int o : {pair.a, pair.b})
          reach[static_cast<size_t>(o)] = std::max(reach[static_cast<size_t>(o)], pairGap(pair) + pairProximity(pair));
      auto surfaceOf = [&](size_t i) {
        auto it = surfaces.find(i);
        if (it == surfaces.end()) {
          Triangles t = simplexFanTriangles(objs[i].current);
          t.array() += objs[i].first;
          it = surfaces.emplace(i, std::make_shared<CollisionSurface>(t, reach.at(i))).first;
        }
        return it->second;
      };
      for (const CollisionPair& pair : scene.collisions)
        for (auto [u, v] : {std::pair<size_t, size_t>(pair.a, pair.b), std::pair<size_t, size_t>(pair.b, pair.a)}) {
          const CollisionResponse response = pairResponse(pair);
          collide.push_back(std::make_unique<CollisionConstraints>(objs[u].first, objs[u].current.vertexCount(),
                                                                   surfaceOf(v), pairGap(pair), pairProximity(pair),
                                                                   pairFriction(pair), response));
          if (response.resolution == CollisionResolution::Global) {
            auto& g = global[response.mode];
            if (!g) g = std::make_unique<GlobalCollisionResolution>(response.mode);
            g->add(collide.back().get());
          }
        }
      res.collisionSetsBuilt += static_cast<int>(collide.size());
    }
    auto updateSurfaces = [&](const Points& p) {
      for (auto& kv : surfaces) kv.second->update(p);
    };
    for (auto& c : collide)
      if (c->response().resolution == CollisionResolution::Sequential) sets.push_back(c.get());
    for (auto& kv : global) sets.push_back(kv.second.get());
    Solver solver(rs.solver);
    solver.prepare(x, invMass);
    LevelReport rep;
    rep.sigmaMm = sigmaMm;
    rep.rangeMm = rs.rangeMm[order];
    rep.refinement = refine;
    for (int s = 0; s < rs.maxStepsPerLevel; ++s) {
      const double runFraction = std::min(1.0, static_cast<double>(stepsDone) / std::max(1, rampSteps - 1));
      for (auto& st : objs) {
        if (fixed(st)) continue;
        if (st.prior) st.prior->setLambda(opts.priorStart + (opts.priorEnd - opts.priorStart) * runFraction);
        st.current.positions = solver.positions().middleRows(st.first, st.current.vertexCount());
        const ImageTargets found = imageTargets(st, st.current, opts, feat, image.grid, focus);
        st.targets->setTargets(found.targets, found.weights);
        st.residual = found.residual;
      }
      {
        const auto tc = Clock::now();
        updateSurfaces(solver.positions());
        // The side test (winding number) on the first step of a level and every few steps after it, so that a vertex
        // that got through a partner is found and pushed back out the right way.
        const bool sideTest = s == 0 || (opts.collisionSideTestEvery > 0 && s % opts.collisionSideTestEvery == 0);
        detectAll(collide, solver.positions(), sideTest, detectionThreads);
        collisionDetectSeconds += since(tc);
      }
      rep.lastMaxMoveMm = solver.step(sets);
      ++rep.steps;
      ++stepsDone;
      if (progress)
        progress(std::min(1.0, static_cast<double>(stepsDone) / totalSteps),
                 refine ? std::string("refinement") : "level " + std::to_string(order + 1) + "/" + std::to_string(rs.levels));
      if (rep.lastMaxMoveMm < rs.toleranceMm) {
        rep.converged = true;
        break;
      }
    }
    stepsDone = (pass + 1) * rs.maxStepsPerLevel;
    if (pass + 1 == passes && !collide.empty()) {
      // Clean-up: collision-only sweeps on the final positions, so no vertex is left inside a partner. They are
      // position corrections with each pair's target whatever its mode (the seed's robust practice: position first),
      // sequential pairs one set after the other, then the global pairs solved together.
      const auto tc = Clock::now();
      Points p = solver.positions();
      for (int sweep = 0; sweep < opts.collisionFinalSweeps; ++sweep) {
        for (size_t k = 0; k < collide.size(); ++k) {
          if (collide[k]->response().resolution != CollisionResolution::Sequential) continue;
          // Positions change with every projection here: the partner's grid is rebuilt before each detection.
          const CollisionPair& pair = scene.collisions[k / 2];
          surfaces.at(static_cast<size_t>(k % 2 == 0 ? pair.b : pair.a))->update(p);
          collide[k]->detect(p, sweep == 0);
          collide[k]->projectPositions(p, solver.inverseMass());
        }
        if (global.empty()) continue;
        updateSurfaces(p);
        for (auto& c : collide)
          if (c->response().resolution == CollisionResolution::Global) c->detect(p, sweep == 0);
        for (auto& kv : global) kv.second->projectPositions(p, solver.inverseMass());
      }
      solver.reset(p, solver.inverseMass());
      collisionDetectSeconds += since(tc);
    }
    for (auto& st : objs) {
      if (fixed(st)) continue;
      st.current.positions = solver.positions().middleRows(st.first, st.current.vertexCount());
      if (st.hasAxis()) st.axisEnd = solver.positions().middleRows(st.axisFirst, st.axisCount());
      if (st.volumeSet) st.volFinal = solver.positions().middleRows(st.volFirst, st.tetCount(l));
      // A run that has blown up (size changed by more than ×5) stops with a clear message instead of writing it out.
      const Points& refP = st.lv[static_cast<size_t>(l)].simplex.positions;
      const double refDiag = (refP.colwise().maxCoeff() - refP.colwise().minCoeff()).norm();
      const double curDiag = (st.current.positions.colwise().maxCoeff() - st.current.positions.colwise().minCoeff()).norm();
      if (!(curDiag < 5.0 * refDiag && curDiag > 0.2 * refDiag))
        throw Error(st.obj->name + ": evolution diverged at level " + std::to_string(order + 1) + " (size ×" +
                    std::to_string(curDiag / refDiag) + " of the template); lower the stiffness or check the image");
      for (const auto& kv : solver.secondsPerFamily()) st.out.secondsPerFamily[kv.first] += kv.second;
      LevelReport r = rep;
      r.vertices = st.current.vertexCount();
      st.out.levels.push_back(r);
    }
  }
  for (auto& st : objs) {
    finishObject(st, opts.unfoldSurfaces);
    st.out.seconds = since(te) / static_cast<double>(objs.size());
    res.objects.push_back(std::move(st.out));
  }
  res.secondsPerStage["evolution"] = since(te) - features.seconds();
  std::vector<std::vector<size_t>> inside;  // each object's voxels (insideVoxels()), once its output surface is final
  if (opts.collisions && !scene.collisions.empty()) {
    // The output surfaces (the dual triangle meshes, not the simplex surfaces the contacts acted on) are separated
    // last, so that what is written out and rasterised has no vertex inside a partner; then penetration is measured
    // on them.
    const auto ts = Clock::now();
    std::vector<TriangleMesh*> surfaces;
    std::vector<double> inverseMass;
    for (size_t i = 0; i < res.objects.size(); ++i) {
      surfaces.push_back(&res.objects[i].mesh);
      inverseMass.push_back(scene.objects[i].kind == ObjectKind::Bone ? 1.0 / opts.boneMassRatio : 1.0);
    }
    std::vector<SeparationPair> pairs;
    for (const CollisionPair& pair : scene.collisions)
      pairs.push_back({pair.a, pair.b, pairGap(pair)});
    SeparationOptions so;
    so.maxSweeps = opts.separationSweeps;
    so.threads = opts.threads;
    so.reachMm = std::max(3.0, 2.0 * proximity);
    for (const CollisionPair& p : scene.collisions) so.reachMm = std::max(so.reachMm, pairGap(p) + pairProximity(p));
    const SeparationReport sep = separateSurfaces(surfaces, inverseMass, pairs, so);
    res.separationSweeps = sep.sweeps;
    res.separationCorrections = sep.corrections;
    // The separation moves vertices one by one and can fold a surface squeezed between partners: unfolded, then
    // separated again (twice at most).
    for (int again = 0; again < 2 && opts.unfoldSurfaces; ++again) {
      int moved = 0;
      for (ObjectResult& o : res.objects) {
        const UnfoldReport u = unfoldSurface(o.mesh);
        o.foldsFound += u.before;
        o.unfoldedVertices += u.verticesMoved;
        moved += u.verticesMoved;
      }
      if (moved == 0) break;
      const SeparationReport more = separateSurfaces(surfaces, inverseMass, pairs, so);
      res.separationSweeps += more.sweeps;
      res.separationCorrections += more.corrections;
    }
    const auto tr = Clock::now();
    for (const ObjectResult& o : res.objects) inside.push_back(insideVoxels(o.mesh, image.grid));
    res.secondsPerStage["rasterise"] = since(tr);
    // Voxel centres still inside both surfaces of a pair (edges crossing between the separation's samples) go to one.
    double margin = 0;
    std::vector<std::pair<int, int>> repairPairs;
    for (const CollisionPair& p : scene.collisions) {
      margin = std::max(margin, 0.5 * pairGap(p));
      repairPairs.emplace_back(p.a, p.b);
    }
    res.overlapVoxelsRepaired = repairOverlapVoxels(surfaces, repairPairs, image.grid, margin, inside).handedOver;
    for (size_t i = 0; i < res.objects.size(); ++i) {
      ObjectResult& o = res.objects[i];
      o.mesh.pointData["displacement_mm"] = (o.mesh.vertices - objs[i].lv[0].triangles.vertices).rowwise().norm();
      o.volumeMm3 = enclosedVolume(o.mesh);
      if (objs[i].volume) settleVolumeMesh(o, objs[i].volRestVolumes, objs[i].volSurfaceNode);  // the separated surface
    }
    for (const SeparationPair& p : pairs)
      res.pairPenetrationMm.push_back(std::max(penetrationDepth(*surfaces[static_cast<size_t>(p.a)], *surfaces[static_cast<size_t>(p.b)]),
                                               penetrationDepth(*surfaces[static_cast<size_t>(p.b)], *surfaces[static_cast<size_t>(p.a)])));
    res.secondsPerStage["separation"] = since(ts);
  }
  if (res.collisionSetsBuilt > 0) res.secondsPerStage["collision-detection"] = collisionDetectSeconds;
  // What is written out: does any surface cross itself? (The unfolding in finishObject() counted it already unless the
  // separation has moved the surfaces since.)
  if (!opts.unfoldSurfaces || !inside.empty()) {
    const auto tq = Clock::now();
    for (ObjectResult& o : res.objects) o.selfIntersections = selfIntersections(o.mesh);
    res.secondsPerStage["surface-check"] = since(tq);
  }
  res.secondsPerStage["features"] = features.seconds();
  res.featureScalesBuilt = features.built();

  const auto tr = Clock::now();
  // Voxels claimed by more than one object are counted; in the label map they go to bones (muscles and generic
  // objects are written first).
  res.labels = LabelMap(image.grid, 0);
  std::vector<uint8_t> claims(image.grid.voxelCount(), 0);
  for (ObjectKind pass : {ObjectKind::Generic, ObjectKind::Muscle, ObjectKind::Bone})
    for (size_t i = 0; i < res.objects.size(); ++i) {
      if (scene.objects[i].kind != pass) continue;
      std::vector<size_t> computed;  // only without the separation's lists
      if (inside.empty()) computed = insideVoxels(res.objects[i].mesh, image.grid);
      for (size_t v : inside.empty() ? computed : inside[i]) {
        claims[v] = static_cast<uint8_t>(std::min(255, claims[v] + 1));
        res.labels.data[v] = res.objects[i].label;
      }
    }
  for (uint8_t c : claims) res.overlapVoxels += c > 1;
  res.secondsPerStage["rasterise"] += since(tr);
  res.seconds = since(t0);
  if (progress) progress(1.0, "done");
  return res;
}

}  // namespace msk
