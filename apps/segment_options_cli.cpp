// The options of `mskseg segment` that steer the segmentation (shared with `mskseg batch`, which forwards them),
// bound into SegmentOptions; their ranges are checked once, by checkSegmentOptions().
#include <cstdlib>

#include "commands.h"
#include "msk/core/solver.h"

namespace msk::cli {

void addSegmentOptions(CLI::App& app, SegmentOptions& o, SegmentOutputs& out) {
  app.add_option_function<std::string>(
      "--quality", [&o](const std::string& s) { o.evolution.quality = parseQuality(s); },
      "preset: fast = 1 level x 15 steps, tolerance 0.04 voxel, XPBD 2 substeps x 2 iterations; balanced (default) "
      "= 2 x 50, 0.02, Gauss-Seidel 1 x 1; accurate = 3 x 200, 0.004, XPBD 2 x 2, finest image scale 0.25 voxel "
      "(mskseg bench tradeoff measures them); the options below override it");
  const CLI::Validator positive(
      [](std::string& v) {
        char* end = nullptr;
        const double x = std::strtod(v.c_str(), &end);
        if (v.empty() || *end != '\0') return std::string("must be a number");
        return x > 0 ? std::string() : std::string("must be > 0 (leave the option out for the preset's)");
      },
      "> 0");
  // Given, these take values that mean what they say (a 0 is refused, not replaced by the preset's); left out, the
  // preset's apply.
  app.add_option("--levels", o.evolution.levels,
                 "mesh resolution levels, x4 vertices apart, 1..5 (default: the preset's)")
      ->check(CLI::Range(1, 5));
  app.add_option("--steps", o.evolution.maxStepsPerLevel, "step cap per level, >= 1 (default: the preset's)")
      ->check(positive);
  addNumber(app, "--tolerance", o.evolution.toleranceMm,
            "a level stops when no vertex moves more than this in a step, mm, > 0 (default: the preset's)")
      ->check(positive);
  app.add_option_function<std::string>(
      "--scheme", [&o](const std::string& s) { o.evolution.scheme = parseScheme(s, "--scheme"); },
      "gauss-seidel | coloured-gauss-seidel | jacobi | xpbd | explicit | implicit (default: the preset's; another "
      "scheme comes with the substeps x iterations it needs: jacobi 1x2, xpbd 2x2, explicit 4x1, others 1x1)");
  app.add_option("--substeps", o.evolution.substeps, "substeps per step, >= 1 (default: the scheme's)")
      ->check(positive);
  app.add_option("--iterations", o.evolution.iterations, "projection sweeps per substep, >= 1 (default: the scheme's)")
      ->check(positive);
  app.add_option("--threads", o.evolution.threads,
                 "threads of the image search, collision detection, the output separation and the coloured, Jacobi and "
                 "CG schemes (0: all cores; default: all cores in segment, a share of them per case in batch); results "
                 "do not depend on it");
  addNumber(app, "--internal-stiffness", o.shape.internalStiffness, "gamma of the shape memory, [0, 1] (default 1)");
  addNumber(app, "--image-stiffness", o.image.stiffness, "gamma of the image targets, [0, 1] (default 0.25)");
  app.add_option_function<std::string>(
      "--prior", [&o](const std::string& s) { o.shape.priorTransform = parsePriorTransform(s, "--prior"); },
      "global shape prior: rigid | similarity (default) | affine");
  addNumber(app, "--prior-start", o.shape.priorStart, "global prior weight at the start, [0, 1] (default 0.3)");
  addNumber(app, "--prior-end", o.shape.priorEnd, "... at the end, ramped linearly over the run (default 0.1)");
  app.add_flag_function(
      "--no-collisions", [&o](std::int64_t) { o.collision.enabled = false; },
      "ignore the scene's collision pairs (objects may then overlap)");
  addNumber(app, "--collision-gap", o.collision.gapMm, "clearance kept between partners, mm, [0, 10] (default 0.2)");
  addNumber(app, "--collision-proximity", o.collision.proximityMm,
            "contact search reach beyond the gap, mm, [0, 50] (0 = max(1 mm, half the largest spacing), default)");
  addNumber(app, "--friction", o.collision.friction, "contact friction, [0, 1] (default 0)");
  app.add_option_function<std::string>(
      "--collision-resolution",
      [&o](const std::string& s) {
        if (s != "sequential" && s != "global")
          throw ParameterError("--collision-resolution", s, "must be sequential or global");
        o.collision.resolution = s == "global" ? CollisionResolution::Global : CollisionResolution::Sequential;
      },
      "contacts of pairs without \"resolution\" in the scene: projected one by one (sequential, default) or solved "
      "together by conjugate gradient (global)");
  app.add_option("--separation-sweeps", o.collision.separationSweeps,
                 "most sweeps separating the output surfaces of each pair at the end, 0..1000 (default 32)");
  app.add_flag_function(
      "--keep-template-mesh", [&o](std::int64_t) { o.surface.remeshTemplates = false; },
      "evolve every template on its own triangulation (default: muscles' and generic objects' templates are "
      "remeshed isotropically to their vertex count first, so their output surfaces do not fold; bones keep theirs; "
      "the scene key \"remesh\" per object wins)");
  app.add_option("--template-cache", o.surface.templateCache,
                 "folder where the meshes derived from the templates (remeshed, coarser levels) are kept and reused "
                 "by later runs of this build, bitwise the same; for cohorts (batch gives its cases one by default)")
      ->type_name("DIR");
  app.add_option_function<double>(
         "--sigma-fine", [&o](double v) { o.image.sigmaFine = v; },
         "image scale at the finest level, x the smallest spacing (default 0.5; accurate 0.25)")
      ->type_name("NUMBER");
  addNumber(app, "--sigma-coarse", o.image.sigmaCoarse, "image scale at the coarsest level, same units (default 1.5)");
  addNumber(app, "--range-fine", o.image.rangeFine,
            "search range +- along the normal at the finest level, x the largest spacing (default 1.5)");
  addNumber(app, "--range-coarse", o.image.rangeCoarse, "... at the coarsest level (default 3), plus:");
  addNumber(app, "--range-coarse-extra", o.image.rangeCoarseExtraMm,
            "mm added to the coarsest level's range (default 2)");
  addNumber(app, "--edge-penalty", o.image.edgePenalty,
            "score lost per mm away from the vertex, relative to the best edge (default 0.1)");
  app.add_flag("--axis-first", o.axis.first,
               "objects with a medial axis first move as a generalised cylinder of it (the scene key \"axis_first\" "
               "per object wins)");
  app.add_flag("--edge-focusing", o.image.edgeFocusing,
               "gradient force at coarse levels: each edge found moves to the finest scale's edge next to it (a "
               "blurred thin bright shell, e.g. CT cortex, shows its edge too far out)");
  app.add_flag("--edge-level", o.image.edgeLevel,
               "gradient force: an edge counts only where the intensity crosses the object's level (midway between "
               "inside and outside at the template), ignoring edges of neighbouring boundaries");
  app.add_flag("--refine", o.image.refinePass,
               "one more pass at the finest level: each converged surface becomes its own reference shape, pulled by "
               "the gradient force with the edge level (for bones on CT; the scene key \"refine\" per object wins; the "
               "others stay fixed)");
  addNumber(app, "--refine-sigma", o.image.refineSigma,
            "image scale of that pass, x the smallest spacing (default 0.5)");
  addNumber(app, "--far-target", o.image.farTargetScaleMm,
            "a target d mm away pulls with weight 1/(1+(d/MM)^2), mm (default 0: off)");
  addNumber(app, "--muscle-target-step", o.image.muscleTargetStepEdges,
            "a muscle's image target lies at most this many local edge lengths from its vertex in a step (default "
            "1; 0: no limit; bones are not limited)");
  app.add_option_function<double>(
         "--reuse-targets", [&o](double v) { o.image.reuseTargetVoxels = v; },
         "a vertex that moved less than this x the smallest spacing (normal turned < 2 deg) since its last image "
         "search keeps its target, 0..1 (default 0.1; accurate 0: every vertex searched every step)")
      ->type_name("NUMBER");
  addMeshSpace(app, out.space, "space of the mesh files: lps (default) or ras; tagged either way");
  app.add_flag_function(
      "--no-qc", [&out](std::int64_t) { out.qcPictures = false; }, "no QC pictures");
  app.add_option("--image-export", out.imageExport,
                 "vti: also image.vti and labels.vti, the image and the label map with their world placement in the "
                 "meshes' space (--mesh-space), for VTK-based viewers such as ParaView")
      ->check(CLI::IsMember({"vti"}));
  app.add_flag("--split", out.split, "also one mask per structure: labels/<name>.nii.gz (1 inside, 0 outside)");
  app.add_option("--qc-reference", out.qcReference,
                 "a label map on the image's grid (e.g. a manual segmentation) drawn dashed in the QC pictures");
}

}  // namespace msk::cli
