// mskseg segment: the scene's templates evolved into the image; meshes, label map, report and QC pictures.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <tuple>

#include "args.h"
#include "commands.h"
#include "msk/core/json.h"
#include "msk/core/log.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/tet_mesh_io.h"
#include "msk/segmentation/qc_pictures.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace fs = std::filesystem;

namespace msk::cli {
namespace {

Json vec3(const Eigen::Vector3d& v) { return Json(Json::Array{v[0], v[1], v[2]}); }

}  // namespace

const std::set<std::string>& segmentValuedOptions() {
  static const std::set<std::string> names = {
      "image", "scene", "out", "quality", "levels", "steps", "tolerance", "internal-stiffness", "image-stiffness",
      "prior", "prior-start", "prior-end", "sigma-fine", "sigma-coarse", "refine-sigma", "range-fine", "range-coarse",
      "range-coarse-extra", "edge-penalty", "far-target", "muscle-target-step", "mesh-space", "collision-gap",
      "collision-proximity", "friction", "collision-resolution", "separation-sweeps", "scheme", "substeps",
      "iterations", "threads"};
  return names;
}

const std::set<std::string>& segmentFlags() {
  static const std::set<std::string> names = {"help",       "no-qc",  "no-collisions", "edge-focusing",
                                              "edge-level", "refine", "axis-first",    "keep-template-mesh"};
  return names;
}

SegmentOptions segmentOptionsFrom(const Args& args) {
  SegmentOptions opts;
  opts.quality = parseQuality(args.str("quality", "balanced"));
  const long levels = args.integer("levels", 0), steps = args.integer("steps", 0);
  if (levels < 0 || levels > 5) throw ParameterError("--levels", std::to_string(levels), "must be 1..5");
  if (steps < 0 || steps > 100000) throw ParameterError("--steps", std::to_string(steps), "must be 1..100000");
  opts.levels = static_cast<int>(levels);
  opts.maxStepsPerLevel = static_cast<int>(steps);
  if (args.has("scheme")) {
    try {
      opts.scheme = parseScheme(args.str("scheme"));
    } catch (const ParameterError&) {
      throw ParameterError("--scheme", args.str("scheme"),
                           "must be gauss-seidel, coloured-gauss-seidel, jacobi, xpbd, explicit or implicit");
    }
  }
  for (auto [name, field, lo] : {std::tuple{"substeps", &opts.substeps, 1L}, std::tuple{"iterations", &opts.iterations, 1L},
                                 std::tuple{"threads", &opts.threads, 0L}}) {
    if (!args.has(name)) continue;
    const long v = args.integer(name, 0);
    if (v < lo || v > 1000)
      throw ParameterError(std::string("--") + name, args.str(name), "must be " + std::to_string(lo) + "..1000");
    *field = static_cast<int>(v);
  }
  opts.toleranceMm = args.num("tolerance", 0);
  if (opts.toleranceMm < 0) throw ParameterError("--tolerance", args.str("tolerance"), "must be ≥ 0 mm");
  opts.internalStiffness = args.num("internal-stiffness", opts.internalStiffness);
  opts.imageStiffness = args.num("image-stiffness", opts.imageStiffness);
  opts.priorStart = args.num("prior-start", opts.priorStart);
  opts.priorEnd = args.num("prior-end", opts.priorEnd);
  if (args.has("sigma-fine")) opts.sigmaFine = args.num("sigma-fine", 0.5);
  opts.sigmaCoarse = args.num("sigma-coarse", opts.sigmaCoarse);
  opts.refineSigma = args.num("refine-sigma", opts.refineSigma);
  opts.rangeFine = args.num("range-fine", opts.rangeFine);
  opts.rangeCoarse = args.num("range-coarse", opts.rangeCoarse);
  opts.rangeCoarseExtraMm = args.num("range-coarse-extra", opts.rangeCoarseExtraMm);
  opts.edgePenalty = args.num("edge-penalty", opts.edgePenalty);
  opts.farTargetScaleMm = args.num("far-target", opts.farTargetScaleMm);
  if (!(opts.farTargetScaleMm >= 0)) throw ParameterError("--far-target", args.str("far-target"), "must be >= 0 mm");
  opts.muscleTargetStepEdges = args.num("muscle-target-step", opts.muscleTargetStepEdges);
  if (!(opts.muscleTargetStepEdges >= 0 && opts.muscleTargetStepEdges <= 1000))
    throw ParameterError("--muscle-target-step", args.str("muscle-target-step"), "must be in [0, 1000]");
  opts.collisions = !args.has("no-collisions");
  opts.edgeFocusing = args.has("edge-focusing");
  opts.edgeLevel = args.has("edge-level");
  opts.refinePass = args.has("refine");
  opts.axisFirst = args.has("axis-first");
  opts.remeshTemplates = !args.has("keep-template-mesh");
  opts.collisionGapMm = args.num("collision-gap", opts.collisionGapMm);
  opts.collisionProximityMm = args.num("collision-proximity", opts.collisionProximityMm);
  opts.collisionFriction = args.num("friction", opts.collisionFriction);
  if (args.has("collision-resolution")) {
    const std::string r = args.str("collision-resolution");
    if (r == "sequential") {
      opts.collisionResolution = CollisionResolution::Sequential;
    } else if (r == "global") {
      opts.collisionResolution = CollisionResolution::Global;
    } else {
      throw ParameterError("--collision-resolution", r, "must be sequential or global");
    }
  }
  const double sweeps = args.num("separation-sweeps", opts.separationSweeps);
  if (!(sweeps >= 0 && sweeps <= 1000) || sweeps != std::floor(sweeps))
    throw ParameterError("--separation-sweeps", args.str("separation-sweeps"), "must be a whole number in 0..1000");
  opts.separationSweeps = static_cast<int>(sweeps);
  if (!(opts.collisionGapMm >= 0 && opts.collisionGapMm <= 10))
    throw ParameterError("--collision-gap", args.str("collision-gap"), "must be in [0, 10] mm");
  if (!(opts.collisionProximityMm >= 0 && opts.collisionProximityMm <= 50))
    throw ParameterError("--collision-proximity", args.str("collision-proximity"), "must be in [0, 50] mm");
  if (!(opts.collisionFriction >= 0 && opts.collisionFriction <= 1))
    throw ParameterError("--friction", args.str("friction"), "must be in [0, 1]");
  opts.priorTransform = parsePriorTransform(args.str("prior", "similarity"), "--prior");
  for (auto [name, v] : {std::pair{"--internal-stiffness", opts.internalStiffness},
                         std::pair{"--image-stiffness", opts.imageStiffness},
                         std::pair{"--prior-start", opts.priorStart}, std::pair{"--prior-end", opts.priorEnd}})
    if (!(v >= 0 && v <= 1)) throw ParameterError(name, std::to_string(v), "must be in [0, 1]");
  return opts;
}

int cmdSegment(const std::vector<std::string>& argv) {
  Args args(argv, segmentValuedOptions(), segmentFlags());
  if (args.has("help")) {
    std::cout
        << "usage: mskseg segment --image IMG --scene SCENE.json --out DIR [--quality fast|balanced|accurate]\n"
           "                      [--levels N] [--steps N] [--tolerance MM] [--internal-stiffness G]\n"
           "                      [--image-stiffness G] [--prior rigid|similarity|affine] [--prior-start L]\n"
           "                      [--prior-end L] [--mesh-space lps|ras] [advanced options below]\n"
           "                      [--no-collisions] [--collision-gap MM] [--friction MU] [--no-qc]\n\n"
           "Evolves each object's template (2-simplex mesh, coarse to fine) under image targets along the normal,\n"
           "its shape memory and a global shape prior; objects evolve together, and the scene's collision pairs\n"
           "keep their surfaces apart (vertex-surface contacts, position correction shared with reduced masses).\n"
           "Writes into DIR: <name>.vtk (LPS unless --mesh-space ras; <name>.vtu too for a volumetric object;\n"
           "point data displacement_mm and image_residual_mm), labels.nii.gz (on the input grid with its affine),\n"
           "report.json (parameters, version, timings, steps, volumes) and qc/<name>_{axial,coronal,sagittal}.png.\n"
           "  --quality   preset (default balanced): fast = 1 level x 15 steps, tolerance 0.04 voxel, XPBD 2\n"
           "              substeps x 2 iterations; balanced = 2 x 50, 0.02, Gauss-Seidel 1 x 1; accurate = 3 x 200,\n"
           "              0.004, XPBD 2 x 2, finest image scale 0.25 voxel instead of 0.5 (fast is ~10x quicker than\n"
           "              accurate; see mskseg bench tradeoff)\n"
           "              --levels/--steps/--tolerance/--scheme/--substeps/--iterations/--sigma-fine override it\n"
           "  --scheme NAME   gauss-seidel | coloured-gauss-seidel | jacobi | xpbd | explicit | implicit\n"
           "                  (default: the preset's; another scheme comes with the substeps x iterations\n"
           "                  it needs: jacobi 1x2, xpbd 2x2 (k = 4, mass-relative), explicit 4x1, others 1x1)\n"
           "  --substeps N, --iterations N   substeps per step and projection sweeps per substep (1..1000)\n"
           "  --threads N     threads of the coloured, Jacobi and CG schemes (0 = all cores, default 1);\n"
           "                  results do not depend on it\n"
           "  --internal-stiffness, --image-stiffness   gamma in [0,1] (defaults 1, 0.25)\n"
           "  --prior-start, --prior-end   global shape prior weight, ramped linearly over the run (0.3 -> 0.1)\n"
           "  --no-collisions   ignore the scene's collision pairs (objects may then overlap)\n"
           "  --collision-gap MM, --collision-proximity MM, --friction MU   contact gap, search reach beyond the\n"
           "                    gap and friction (defaults 0.2 mm, max(1 mm, half the largest spacing), 0)\n"
           "  --collision-resolution sequential|global   contacts of pairs without \"resolution\" in the scene:\n"
           "                    projected one by one (default) or solved together by conjugate gradient\n"
           "  --separation-sweeps N   most sweeps separating the output surfaces of each pair at the end (default 32)\n"
           "  --keep-template-mesh   evolve every template on its own triangulation (default: muscles' and generic\n"
           "                    objects' templates are remeshed isotropically to their vertex count first, so their\n"
           "                    output surfaces do not fold onto themselves; bones keep theirs; scene key \"remesh\"\n"
           "                    per object wins)\n"
           "advanced (relative to the voxel size, so they hold at any resolution):\n"
           "  --sigma-fine, --sigma-coarse  image smoothing at the finest/coarsest level, x smallest spacing\n"
           "                                (defaults 0.5 (accurate: 0.25) and 1.5)\n"
           "  --range-fine, --range-coarse  search range +- along the normal, x largest spacing (+2 mm coarse)\n"
           "  --range-coarse-extra MM       the length added at the coarsest level (default 2)\n"
           "  --edge-penalty                score lost per mm away from the vertex, relative to the best edge\n"
           "  --axis-first                  objects with a medial axis first move as a generalised cylinder\n"
           "                                (the axis carries the surface; scene key \"axis_first\" per object wins)\n"
           "  --edge-focusing               gradient force at coarse levels: relocate each edge found to the\n"
           "                                finest scale's edge next to it (a blurred thin bright shell, e.g.\n"
           "                                CT cortex at 3 mm, shows its edge ~sigma too far out); default off\n"
           "  --edge-level                  gradient force: an edge counts only where the intensity crosses\n"
           "                                the object's level (midway between inside and outside at the\n"
           "                                template) -- ignores edges of neighbouring boundaries; default off\n"
           "  --refine                      one more pass at the finest level: each converged surface becomes\n"
           "                                its own reference shape, pulled by the gradient force with the edge\n"
           "                                level (the image's own edges place it); default off. For bones on\n"
           "                                CT; scene key \"refine\" per object wins (others stay fixed)\n"
           "  --refine-sigma                image scale of that pass, x smallest spacing (default 0.5)\n"
           "  --far-target MM               a target d mm away pulls with weight 1/(1+(d/MM)^2) (default 0: off)\n"
           "  --muscle-target-step E        a muscle's image target is at most E local edge lengths from its vertex\n"
           "                                in a step (default 1; 0: no limit; bones are not limited)\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  const SegmentOptions opts = segmentOptionsFrom(args);
  const MeshSpace space = parseMeshSpace(args.str("mesh-space", "lps"));

  const std::string imagePath = args.str("image"), scenePath = args.str("scene"), out = args.str("out");
  checkOutputFolder(out);
  NiftiInfo info;
  const ImageF image = readNifti<float>(imagePath, &info);
  const Scene scene = loadScene(scenePath);
  const SegmentationResult res = segmentScene(image, scene, opts, stderrProgress("segment"));

  writeFolderAtomically(out, [&](const std::string& dir) {
    Json report;
    report["mskseg_version"] = MSK_VERSION;
    report["command"] = commandLineJson("segment", argv);
    report["image"] = fs::absolute(imagePath).string();
    report["scene"] = fs::absolute(scenePath).string();
    Json img;
    img["dims"] = vec3(image.grid.dims.cast<double>());
    img["spacing_mm"] = vec3(image.grid.spacing);
    img["affine_source"] = affineSourceName(info.affineSource);
    img["datatype"] = dataTypeName(info.datatype);
    report["image_info"] = img;
    report["parameters"] = settingsJson(opts, res.settings);
    report["mesh_space"] = meshSpaceName(space);
    Json timing;
    timing["total_s"] = res.seconds;
    for (const auto& kv : res.secondsPerStage) timing[kv.first + "_s"] = kv.second;
    timing["image_scales_built"] = res.featureScalesBuilt;
    report["timing"] = timing;
    report["overlap_voxels"] = static_cast<double>(res.overlapVoxels);
    report["collision_sets_built"] = res.collisionSetsBuilt;
    report["medial_axes_built"] = res.medialAxesBuilt;
    report["volume_models_built"] = res.volumeModelsBuilt;
    Json pairs = Json::array();
    for (size_t k = 0; k < scene.collisions.size(); ++k) {
      Json pj;
      const CollisionPair& cp = scene.collisions[k];
      pj["objects"] = Json(Json::Array{scene.objects[static_cast<size_t>(cp.a)].name,
                                       scene.objects[static_cast<size_t>(cp.b)].name});
      pj["gap_mm"] = cp.gapMm >= 0 ? cp.gapMm : opts.collisionGapMm;
      if (cp.proximityMm > 0) pj["proximity_mm"] = cp.proximityMm;
      pj["friction"] = cp.friction >= 0 ? cp.friction : opts.collisionFriction;
      pj["declared"] = cp.fromAuto ? "auto" : "by name";
      if (k < res.pairPenetrationMm.size()) pj["max_penetration_mm"] = res.pairPenetrationMm[k];
      pairs.push(pj);
    }
    report["collision_pairs"] = pairs;
    report["separation_sweeps_run"] = res.separationSweeps;
    report["separation_corrections"] = static_cast<double>(res.separationCorrections);
    report["overlap_voxels_repaired"] = static_cast<double>(res.overlapVoxelsRepaired);
    Json objects = Json::array();
    std::vector<QcObject> qc;
    for (const auto& o : res.objects) {
      writeMesh(dir + "/" + o.name + ".vtk", o.mesh, space);
      Json j;
      j["name"] = o.name;
      j["label"] = o.label;
      j["mesh"] = o.name + ".vtk";
      j["polarity"] = polarityName(o.polarity);
      j["vertices"] = o.mesh.vertexCount();
      j["seconds"] = o.seconds;
      j["volume_mm3"] = o.volumeMm3;
      j["template_volume_mm3"] = o.templateVolumeMm3;
      j["template_vertices"] = o.templateVertices;
      j["template_remeshed"] = o.remeshed;
      j["self_intersections"] = static_cast<double>(o.selfIntersections);
      j["folds_unfolded"] = static_cast<double>(o.foldsFound);
      j["vertices_unfolded"] = o.unfoldedVertices;
      if (o.selfIntersections > 0)
        log::warn(o.name + ": " + std::to_string(o.selfIntersections) +
                  " pairs of faces of its surface cross each other");
      if (o.volumeMesh.tetCount() > 0) {
        // A tet mesh with inverted elements is not written (it would not be a valid volume); the report says so.
        Json vm;
        if (o.invertedTets == 0) {
          writeTetMesh(dir + "/" + o.name + ".vtu", o.volumeMesh, space);
          vm["mesh"] = o.name + ".vtu";
        } else {
          log::warn(o.name + ".vtu not written: " + std::to_string(o.invertedTets) + " of " +
                    std::to_string(o.volumeMesh.tetCount()) + " tets of the volume model are inverted");
        }
        vm["inverted_tets"] = o.invertedTets;
        vm["tets"] = o.volumeMesh.tetCount();
        vm["volume_mm3"] = o.volumeModelMm3;
        vm["template_volume_mm3"] = o.volumeModelTemplateMm3;
        vm["volume_change_percent"] = 100.0 * (o.volumeModelMm3 / o.volumeModelTemplateMm3 - 1.0);
        vm["volume_decision"] = o.volumeDecision;
        j["volume_model"] = vm;
      }
      j["mean_image_residual_mm"] = o.meanImageResidualMm;
      j["mean_displacement_mm"] = o.mesh.pointData.at("displacement_mm").mean();
      Json lv = Json::array();
      int totalSteps = 0;
      for (const auto& l : o.levels) {
        Json r;
        r["simplex_vertices"] = l.vertices;
        r["steps"] = l.steps;
        r["converged"] = l.converged;
        r["last_max_move_mm"] = l.lastMaxMoveMm;
        r["sigma_mm"] = l.sigmaMm;
        r["range_mm"] = l.rangeMm;
        if (l.refinement) r["refinement"] = true;
        lv.push(r);
        totalSteps += l.steps;
      }
      j["steps"] = totalSteps;
      j["levels"] = lv;
      Json fam;
      for (const auto& kv : o.secondsPerFamily) fam[kv.first] = kv.second;
      j["seconds_per_constraint_family"] = fam;
      objects.push(j);
      qc.push_back({o.name, o.label});
    }
    report["objects"] = objects;
    NiftiWriteOptions wo;
    wo.like = &info;
    wo.description = "mskseg segment";
    int maxLabel = 0;
    for (const auto& o : scene.objects) maxLabel = std::max(maxLabel, o.label);
    writeNifti(dir + "/labels.nii.gz", res.labels, maxLabel <= 255 ? DataType::UInt8 : DataType::Int16, wo);
    if (!args.has("no-qc")) {
      fs::create_directories(dir + "/qc");
      writeQcPictures(dir + "/qc", image, res.labels, qc);
    }
    report.writeFile(dir + "/report.json");
  });
  std::cout << "segmented " << res.objects.size() << " object(s) in " << res.seconds << " s -> " << out << "\n";
  if (scene.objects.size() > 1)
    std::cout << "  voxels inside two objects: " << res.overlapVoxels
              << (res.collisionSetsBuilt > 0 ? "" : " (no collision response: no pairs declared or --no-collisions)") << "\n";
  if (!res.pairPenetrationMm.empty()) {
    double worst = 0;
    for (double d : res.pairPenetrationMm) worst = std::max(worst, d);
    std::cout << "  deepest penetration between collision partners: " << worst << " mm\n";
  }
  for (const auto& o : res.objects) {
    int steps = 0;
    for (const auto& l : o.levels) steps += l.steps;
    std::cout << "  " << o.name << ": " << steps << " steps, " << o.seconds << " s, volume " << o.volumeMm3 / 1000.0
              << " mL (template " << o.templateVolumeMm3 / 1000.0 << " mL), mean residual " << o.meanImageResidualMm
              << " mm\n";
  }
  return 0;
}

}  // namespace msk::cli
