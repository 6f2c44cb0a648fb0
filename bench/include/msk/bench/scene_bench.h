#pragma once
/// The scene benchmark (`mskseg bench scene`): a synthetic phantom scene segmented from its mean-anatomy templates,
/// with the time per stage, the projection time per constraint family, peak memory and accuracy per object.
#include <map>
#include <string>
#include <vector>

#include "msk/core/log.h"
#include "msk/phantom/phantom.h"
#include "msk/segmentation/segmenter.h"

namespace msk {

/// What the scene benchmark runs.
struct SceneBenchOptions {
  int structures = 24;     ///< 24 (both thighs and lower legs) or 4 (the thigh)
  PhantomOptions phantom;  ///< seed, spacing, vertices of the phantom
  SegmentOptions segment;  ///< the run's settings (quality, threads, collisions)
};

/// One object's figures against the phantom's truth.
struct SceneBenchObject {
  std::string name, kind;
  int label = 0;
  double dice = 0, assdMm = 0, meshAssdMm = 0, templateDice = 0;
  size_t selfIntersections = 0;  ///< face pairs of the output surface that cross each other
};

/// What the scene benchmark measured.
struct SceneBenchFigures {
  SceneBenchOptions options;
  Scene scene;
  SegmentationResult result;
  Grid grid;  ///< the phantom image's grid
  double generationSeconds = 0, generationCpu = 0, segmentSeconds = 0, segmentCpu = 0, scoreSeconds = 0;
  double peakRssMiB = 0;
  size_t simplexVertices = 0;  ///< at the finest level, over every object
  /// Projection time per family: a stacked solver's time once, per-object times (image search) summed.
  std::map<std::string, double> secondsPerFamily;
  std::vector<SceneBenchObject> objects;
};

/// Generates the phantom, segments it and scores every object (progress of both on `progress`).
SceneBenchFigures runSceneBench(const SceneBenchOptions& opts, const ProgressFn& progress = {});

/// The figures as a table on stdout.
void printSceneBench(const SceneBenchFigures& f);

/// Writes bench.json, objects.csv, the result label map (labels.nii.gz) and surfaces (result_<name>.vtk, LPS) into
/// the existing folder `dir`.
void writeSceneBench(const std::string& dir, const SceneBenchFigures& f);

/// CPU time of this process (user + system, all threads), s.
double processCpuSeconds();
/// Peak resident set size of this process, MiB.
double processPeakRssMiB();

}  // namespace msk
