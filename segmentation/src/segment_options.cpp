#include "msk/segmentation/segment_options.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "msk/core/error.h"

namespace msk {

Quality parseQuality(const std::string& t) {
  if (t == "fast") return Quality::Fast;
  if (t == "balanced") return Quality::Balanced;
  if (t == "accurate") return Quality::Accurate;
  throw ParameterError("--quality", t, "must be fast, balanced or accurate");
}

const char* qualityName(Quality q) {
  switch (q) {
    case Quality::Fast:
      return "fast";
    case Quality::Balanced:
      return "balanced";
    case Quality::Accurate:
      return "accurate";
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
    case PriorTransform::Rigid:
      return "rigid";
    case PriorTransform::Similarity:
      return "similarity";
    case PriorTransform::Affine:
      return "affine";
  }
  return "?";
}

namespace {

/// A number as a person writes it (up to 10 significant digits, no trailing zeros).
std::string shown(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.10g", v);
  return text;
}

/// A number in [lo, hi] (NaN fails), named by its command-line option.
void checkRange(const char* option, double v, double lo, double hi, const char* unit = "") {
  if (!(v >= lo && v <= hi))
    throw ParameterError(option, shown(v), "must be in [" + shown(lo) + ", " + shown(hi) + "]" + unit);
}

/// A whole number in lo..hi, named by its command-line option.
void checkCount(const char* option, int v, int lo, int hi, const char* meaning = "") {
  if (v < lo || v > hi)
    throw ParameterError(option, std::to_string(v),
                         "must be " + std::to_string(lo) + ".." + std::to_string(hi) + meaning);
}

}  // namespace

void checkSegmentOptions(const SegmentOptions& o) {
  const EvolutionOptions& e = o.evolution;
  checkCount("--levels", e.levels, 0, 5, " (0: the preset's)");
  checkCount("--steps", e.maxStepsPerLevel, 0, 100000, " (0: the preset's)");
  if (!(e.toleranceMm >= 0) || !std::isfinite(e.toleranceMm))
    throw ParameterError("--tolerance", shown(e.toleranceMm), "must be >= 0 mm (0: the preset's)");
  checkCount("--substeps", e.substeps, 0, 1000, " (0: the scheme's)");
  checkCount("--iterations", e.iterations, 0, 1000, " (0: the scheme's)");
  checkCount("--threads", e.threads, 0, 1024, " (0: all cores)");
  {
    std::error_code ec;
    const std::string& cache = o.surface.templateCache;
    if (!cache.empty() && std::filesystem::exists(cache, ec) && !std::filesystem::is_directory(cache, ec))
      throw ParameterError("--template-cache", cache, "is a file, not a folder");
  }
  validateSolverOptions(resolveSettings(o, Grid{}).solver);  // dt, damping, drag, ω, k

  const ShapeOptions& s = o.shape;
  checkRange("--internal-stiffness", s.internalStiffness, 0.0, 1.0);
  checkRange("--prior-start", s.priorStart, 0.0, 1.0);
  checkRange("--prior-end", s.priorEnd, 0.0, 1.0);

  const ImageSearchOptions& i = o.image;
  checkRange("--image-stiffness", i.stiffness, 0.0, 1.0);
  if (i.sigmaFine) checkRange("--sigma-fine", *i.sigmaFine, 0.0, 10.0);
  checkRange("--sigma-coarse", i.sigmaCoarse, 0.0, 10.0);
  checkRange("--refine-sigma", i.refineSigma, 0.0, 10.0);
  checkRange("--range-fine", i.rangeFine, 0.0, 20.0);
  if (!(i.rangeFine > 0)) throw ParameterError("--range-fine", shown(i.rangeFine), "must be positive");
  checkRange("--range-coarse", i.rangeCoarse, 0.0, 20.0);
  checkRange("--range-coarse-extra", i.rangeCoarseExtraMm, 0.0, 1000.0, " mm");
  checkRange("--edge-penalty", i.edgePenalty, 0.0, 10.0);
  if (!(i.farTargetScaleMm >= 0) || !std::isfinite(i.farTargetScaleMm))
    throw ParameterError("--far-target", shown(i.farTargetScaleMm), "must be >= 0 mm (0: off)");
  checkRange("--muscle-target-step", i.muscleTargetStepEdges, 0.0, 1000.0, " edge lengths (0: no limit)");
  if (i.reuseTargetVoxels) checkRange("--reuse-targets", *i.reuseTargetVoxels, 0.0, 1.0, " voxels (0: off)");

  const CollisionOptions& c = o.collision;
  checkRange("--collision-gap", c.gapMm, 0.0, 10.0, " mm");
  checkRange("--collision-proximity", c.proximityMm, 0.0, 50.0, " mm (0: auto)");
  checkRange("--friction", c.friction, 0.0, 1.0);
  checkRange("bone mass ratio", c.boneMassRatio, 1e-3, 1e3);
  if (!(c.positionBeyondMm >= 0))
    throw ParameterError("collision position threshold", shown(c.positionBeyondMm), "must be >= 0 mm");
  checkCount("collision final sweeps", c.finalSweeps, 0, 1000);
  checkCount("collision side test interval", c.sideTestEvery, 0, 100000);
  checkCount("--separation-sweeps", c.separationSweeps, 0, 1000);

  const AxisOptions& a = o.axis;
  checkRange("radial stiffness", a.radialStiffness, 0.0, 1.0);
  checkRange("axis spacing", a.spacingMm, 0.5, 100.0, " mm");
  checkRange("axis centring", a.centering, 0.0, 1.0);
  checkCount("axis-first steps", a.firstSteps, 0, 100000);
  checkRange("axis-first image gain", a.firstStage.imageGain, 0.0, 1.0);
  checkRange("axis-first shape memory", a.firstStage.shapeMemory, 0.0, 1.0);

  checkRange("volume stiffness", o.volume.stiffness, 0.0, 1.0);
}

ResolvedSettings resolveSettings(const SegmentOptions& o, const Grid& grid) {
  const EvolutionOptions& e = o.evolution;
  ResolvedSettings s;
  const double minSp = grid.spacing.minCoeff(), maxSp = grid.spacing.maxCoeff();
  // The presets (measured with `mskseg bench tradeoff`, docs/measurements.md): levels, step cap per level, tolerance
  // in units of the smallest spacing, scheme, substeps × iterations.
  int levels = 2, steps = 50, substeps = 1, iterations = 1;
  double tolFactor = 0.02;
  Scheme scheme = Scheme::GaussSeidel;
  switch (e.quality) {
    case Quality::Fast:  // one level: no coarse search, one image scale (capture range ± 1.5 voxels only)
      levels = 1;
      steps = 15;
      tolFactor = 0.04;
      scheme = Scheme::Xpbd;
      substeps = 2;
      iterations = 2;
      break;
    case Quality::Balanced:
      levels = 2;
      steps = 50;
      tolFactor = 0.02;
      scheme = Scheme::GaussSeidel;
      substeps = 1;
      iterations = 1;
      break;
    case Quality::Accurate:  // a tight tolerance and a lighter finest blur (sigmaFineVoxels): the least surface
                             // distance
      levels = 3;
      steps = 200;
      tolFactor = 0.004;
      scheme = Scheme::Xpbd;
      substeps = 2;
      iterations = 2;
      break;
  }
  s.levels = e.levels > 0 ? e.levels : levels;
  s.maxStepsPerLevel = e.maxStepsPerLevel > 0 ? e.maxStepsPerLevel : steps;
  s.toleranceMm = e.toleranceMm > 0 ? e.toleranceMm : tolFactor * minSp;
  if (e.scheme && *e.scheme != scheme) {
    // Another scheme than the preset's: the substeps × iterations it needs on the same schedule (measured on the
    // femur phantoms: explicit Euler needs ≥ 4 substeps, Jacobi two sweeps to keep pace with Gauss–Seidel).
    scheme = *e.scheme;
    substeps = scheme == Scheme::Xpbd ? 2 : scheme == Scheme::Explicit ? 4 : 1;
    iterations = scheme == Scheme::Xpbd || scheme == Scheme::Jacobi ? 2 : 1;
  }
  s.solver.scheme = scheme;
  s.solver.dt = e.dt;
  s.solver.damping = e.damping;
  s.solver.drag = e.drag;
  s.solver.substeps = e.substeps > 0 ? e.substeps : substeps;
  s.solver.iterations = e.iterations > 0 ? e.iterations : iterations;
  s.solver.threads = e.threads;
  s.solver.stiffness = e.xpbdStiffness;
  s.solver.xpbdStiffness = XpbdStiffness::MassRelative;
  s.solver.omega = e.jacobiOmega;
  const ImageSearchOptions& i = o.image;
  s.sigmaFineVoxels = i.sigmaFine ? *i.sigmaFine : e.quality == Quality::Accurate ? 0.25 : 0.5;
  // A vertex that moved less than a tenth of a voxel keeps its target: the search's answer moves by about as much
  // (bundled thigh: 69-83 % of the searches kept, every Dice within 0.0002); accurate searches every vertex.
  s.reuseTargetVoxels = i.reuseTargetVoxels ? *i.reuseTargetVoxels : e.quality == Quality::Accurate ? 0.0 : 0.1;
  // Coarse levels see a smoother image over a longer range; the finest level a light blur over a short range.
  for (int l = 0; l < s.levels; ++l) {
    const double f = s.levels == 1 ? 0.0 : 1.0 - static_cast<double>(l) / (s.levels - 1);  // 1 coarse → 0 fine
    s.sigmaMm.push_back(minSp * (s.sigmaFineVoxels + (i.sigmaCoarse - s.sigmaFineVoxels) * f));
    s.rangeMm.push_back(maxSp * (i.rangeFine + (i.rangeCoarse - i.rangeFine) * f) + i.rangeCoarseExtraMm * f);
  }
  return s;
}

}  // namespace msk
