#include "msk/segmentation/segment_report.h"

#include <string>

namespace msk {

namespace {

/// The schedule and scheme the run resolved (preset applied).
void addEvolution(Json& j, const SegmentOptions& o, const ResolvedSettings& s) {
  j["quality"] = qualityName(o.evolution.quality);
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
  for (double v : s.sigmaMm) sig.push_back(v);
  for (double v : s.rangeMm) rng.push_back(v);
  j["image_sigma_mm_per_level"] = sig;
  j["search_range_mm_per_level"] = rng;
}

/// Shape memory, global prior and the image force.
void addShapeAndImage(Json& j, const SegmentOptions& o, const ResolvedSettings& s) {
  j["internal_stiffness"] = o.shape.internalStiffness;
  j["internal_mode"] = o.shape.internalMode == InternalMode::ShapeMemory ? "shape-memory" : "smoothing";
  j["image_stiffness"] = o.image.stiffness;
  j["global_prior"] = priorTransformName(o.shape.priorTransform);
  j["global_prior_weight_start"] = o.shape.priorStart;
  j["global_prior_weight_end"] = o.shape.priorEnd;
  j["far_target_scale_mm"] = o.image.farTargetScaleMm;
  j["sigma_fine_voxels"] = s.sigmaFineVoxels;
  j["reuse_target_voxels"] = s.reuseTargetVoxels;
  j["sigma_coarse_voxels"] = o.image.sigmaCoarse;
  j["range_fine_voxels"] = o.image.rangeFine;
  j["range_coarse_voxels"] = o.image.rangeCoarse;
  j["range_coarse_extra_mm"] = o.image.rangeCoarseExtraMm;
  j["edge_penalty_per_mm"] = o.image.edgePenalty;
  j["edge_focusing"] = o.image.edgeFocusing;
  j["edge_level"] = o.image.edgeLevel;
  j["refine_pass"] = o.image.refinePass;
  j["remesh_templates"] = o.surface.remeshTemplates;
  j["unfold_surfaces"] = o.surface.unfoldSurfaces;
  j["refine_sigma_voxels"] = o.image.refineSigma;
  j["muscle_target_step_edges"] = o.image.muscleTargetStepEdges;
}

/// Contacts, with the response each pair used.
void addCollisions(Json& j, const SegmentOptions& o, const SegmentationResult& result) {
  j["collisions"] = o.collision.enabled;
  j["collision_gap_mm"] = o.collision.gapMm;
  j["collision_proximity_mm"] = o.collision.proximityMm;
  j["collision_friction"] = o.collision.friction;
  // Per pair what the run used (segmentScene() fills it); without pairs (or outside a run) the run's default.
  if (result.collisionResponses.empty()) {
    j["collision_mode"] = std::string("position, spring target, ") + collisionResolutionName(o.collision.resolution);
  } else {
    Json modes = Json::array();
    for (const PairResponse& p : result.collisionResponses) {
      Json m;
      m["objects"] = Json::array({p.a, p.b});
      m["mode"] = collisionModeName(p.response.mode);
      m["target"] = collisionTargetName(p.response.target);
      m["resolution"] = collisionResolutionName(p.response.resolution);
      modes.push_back(m);
    }
    j["collision_mode"] = modes;
  }
  j["collision_resolution"] = collisionResolutionName(o.collision.resolution);
  j["collision_position_beyond_mm"] = o.collision.positionBeyondMm;
  j["collision_final_sweeps"] = o.collision.finalSweeps;
  j["separation_sweeps"] = o.collision.separationSweeps;
  j["collision_side_test_every"] = o.collision.sideTestEvery;
}

/// Medial axes (with what the axis-first stage did), volume models and the time step, damping and drag.
void addAxisAndVolume(Json& j, const SegmentOptions& o, const SegmentationResult& result) {
  j["radial_stiffness"] = o.axis.radialStiffness;
  j["axis_spacing_mm"] = o.axis.spacingMm;
  j["axis_centering"] = o.axis.centering;
  j["axis_first"] = o.axis.first;
  j["axis_first_max_steps"] = o.axis.firstSteps;
  j["axis_first_image_gain"] = o.axis.firstStage.imageGain;
  j["axis_first_shape_memory"] = o.axis.firstStage.shapeMemory;
  if (!result.axisFirst.empty()) {
    Json stage = Json::array();
    for (const AxisFirstReport& a : result.axisFirst) {
      Json r;
      r["object"] = a.object;
      r["steps"] = a.steps;
      r["converged"] = a.converged;
      r["last_max_move_mm"] = a.lastMaxMoveMm;
      r["mean_axis_move_mm"] = a.meanAxisMoveMm;
      r["seconds"] = a.seconds;
      stage.push_back(r);
    }
    j["axis_first_stage"] = stage;
  }
  j["volume_stiffness"] = o.volume.stiffness;
  j["bone_mass_ratio"] = o.collision.boneMassRatio;
  j["dt"] = result.settings.solver.dt;
  j["damping"] = result.settings.solver.damping;
  j["drag"] = result.settings.solver.drag;
}

}  // namespace

Json settingsJson(const SegmentOptions& o, const SegmentationResult& result) {
  Json j;
  addEvolution(j, o, result.settings);
  addShapeAndImage(j, o, result.settings);
  addCollisions(j, o, result);
  addAxisAndVolume(j, o, result);
  return j;
}

Json qualityJson(const ObjectQuality& q) {
  Json j;
  j["status"] = qualityStatusName(q.status);
  j["in_image_share"] = q.inImageShare;
  j["edge_share"] = q.edgeShare;
  j["contrast_to_noise"] = q.contrastToNoise;
  j["contrast_judged"] = q.contrastJudged;
  if (std::isfinite(q.profileMatch)) j["profile_match"] = q.profileMatch;
  j["reasons"] = q.reasons;
  return j;
}

Json objectJson(const ObjectResult& o) {
  Json j;
  j["name"] = o.name;
  j["label"] = o.label;
  j["polarity"] = polarityName(o.polarity);
  j["force"] = o.force == TargetMode::Profile ? "profile" : "gradient";
  j["vertices"] = o.mesh.vertexCount();
  j["image_search_s"] = o.imageSearchSeconds;
  j["image_search_reused_share"] = o.imageSearchReusedShare;
  j["volume_mm3"] = o.volumeMm3;
  j["template_volume_mm3"] = o.templateVolumeMm3;
  j["template_vertices"] = o.templateVertices;
  j["template_remeshed"] = o.remeshed;
  j["self_intersections"] = o.selfIntersections;
  j["folds_unfolded"] = o.foldsFound;
  j["vertices_unfolded"] = o.unfoldedVertices;
  if (o.volumeMesh.tetCount() > 0) {
    Json vm;
    vm["inverted_tets"] = o.invertedTets;
    vm["tets"] = o.volumeMesh.tetCount();
    vm["volume_mm3"] = o.volumeModelMm3;
    vm["template_volume_mm3"] = o.volumeModelTemplateMm3;
    if (o.volumeModelTemplateMm3 > 0)
      vm["volume_change_percent"] = 100.0 * (o.volumeModelMm3 / o.volumeModelTemplateMm3 - 1.0);
    vm["volume_decision"] = o.volumeDecision;
    j["volume_model"] = vm;
  }
  j["mean_image_residual_mm"] = o.meanImageResidualMm;
  const auto displacement = o.mesh.pointData.find("displacement_mm");
  if (displacement != o.mesh.pointData.end()) j["mean_displacement_mm"] = displacement->second.mean();
  Json lv = Json::array();
  int totalSteps = 0;
  for (const LevelReport& l : o.levels) {
    Json r;
    r["simplex_vertices"] = l.vertices;
    r["steps"] = l.steps;
    r["converged"] = l.converged;
    r["drift_mm_per_step"] = l.driftMmPerStep;
    r["stopped_on_tolerance"] = l.stoppedOnTolerance;
    r["last_max_move_mm"] = l.lastMaxMoveMm;
    r["sigma_mm"] = l.sigmaMm;
    r["range_mm"] = l.rangeMm;
    r["clean_up_sweeps"] = l.cleanUpSweeps;
    if (l.refinement) r["refinement"] = true;
    lv.push_back(r);
    totalSteps += l.steps;
  }
  j["steps"] = totalSteps;
  j["levels"] = lv;
  j["quality"] = qualityJson(o.quality);
  return j;
}

Json segmentReport(const SegmentationResult& res, const Scene& scene, const SegmentOptions& opts) {
  Json report;
  report["status"] = qualityStatusName(res.status);
  report["parameters"] = settingsJson(opts, res);
  Json timing;
  timing["total_s"] = res.seconds;
  for (const auto& kv : res.secondsPerStage) timing[kv.first + "_s"] = kv.second;
  timing["image_scales_built"] = res.featureScalesBuilt;
  Json fam = Json::object();
  for (const auto& kv : res.secondsPerFamily) fam[kv.first] = kv.second;
  timing["constraint_projection_s"] = fam;
  report["timing"] = timing;
  report["overlap_voxels"] = res.overlapVoxels;
  report["collision_sets_built"] = res.collisionSetsBuilt;
  report["medial_axes_built"] = res.medialAxesBuilt;
  report["volume_models_built"] = res.volumeModelsBuilt;
  if (!opts.surface.templateCache.empty())
    report["template_cache"] = {
        {"folder", opts.surface.templateCache}, {"hits", res.templateCacheHits}, {"misses", res.templateCacheMisses}};
  Json pairs = Json::array();
  for (size_t k = 0; k < scene.collisions.size(); ++k) {
    const CollisionPair& cp = scene.collisions[k];
    Json pj;
    pj["objects"] =
        Json::array({scene.objects[static_cast<size_t>(cp.a)].name, scene.objects[static_cast<size_t>(cp.b)].name});
    pj["gap_mm"] = cp.gapMm >= 0 ? cp.gapMm : opts.collision.gapMm;
    if (cp.proximityMm > 0) pj["proximity_mm"] = cp.proximityMm;
    pj["friction"] = cp.friction >= 0 ? cp.friction : opts.collision.friction;
    pj["declared"] = cp.fromAuto ? "auto" : "by name";
    if (k < res.pairPenetrationMm.size()) pj["max_penetration_mm"] = res.pairPenetrationMm[k];
    pairs.push_back(pj);
  }
  report["collision_pairs"] = pairs;
  report["separation_sweeps_run"] = res.separationSweeps;
  report["separation_corrections"] = res.separationCorrections;
  report["overlap_voxels_repaired"] = res.overlapVoxelsRepaired;
  Json objects = Json::array();
  for (const ObjectResult& o : res.objects) objects.push_back(objectJson(o));
  report["objects"] = objects;
  return report;
}

}  // namespace msk
