#pragma once
/// The scaling benchmark (`mskseg bench scaling`): the same anatomy (the thigh phantom) segmented from templates of
/// growing resolution, each template subdivided 0, 1, 2, … times (every triangle into four, the new vertices at the
/// edge midpoints, so the shape is the same), with the time of every stage per simplex vertex and step and the peak
/// memory per vertex.
#include <map>
#include <string>
#include <vector>

#include "msk/core/log.h"
#include "msk/phantom/phantom.h"
#include "msk/segmentation/segmenter.h"

namespace msk {

/// What the scaling benchmark runs.
struct ScalingBenchOptions {
  int subdivisions = 3;    ///< the largest number of subdivisions (runs 0..subdivisions), 0..5
  PhantomOptions phantom;  ///< seed, spacing and the template vertices of the unsubdivided run
  SegmentOptions segment;  ///< the run's settings (quality, threads)
  int repeat = 1;          ///< runs at each resolution, 1..20: the fastest one's figures are kept
};

/// One resolution's figures.
struct ScalingPoint {
  int subdivisions = 0;
  long simplexVertices = 0;  ///< at the finest level, over every object
  double vertexSteps = 0;    ///< Σ over objects and levels of simplex vertices × steps
  double segmentSeconds = 0;
  /// Wall seconds per stage: "segmentation", "evolution", "collision-detection", "image-search" (the objects' own
  /// search times summed, CPU), "constraint-projection", "separation", "features".
  std::map<std::string, double> seconds;
  double peakRssMiB = 0;             ///< of the process after the run (the runs grow, so it is this run's)
  double meanDice = 0;               ///< against the phantom's labels
  int runs = 1;                      ///< runs at this resolution; the figures above are the fastest one's
  double slowestSegmentSeconds = 0;  ///< the slowest run's segmentation seconds (= segmentSeconds for one run)
};

/// Midpoint subdivision: every triangle into four, the new vertices at the edges' midpoints (shared by both faces of
/// an edge); the surface, its orientation and its volume are unchanged. Point data is not kept.
TriangleMesh subdivideMidpoints(const TriangleMesh& mesh);

/// Generates the phantom once, then segments it at each resolution, opts.repeat times each, keeping the fastest run's
/// figures (a machine shared with other work slows some runs; the fastest is the closest to the code's own cost);
/// progress on `progress`.
std::vector<ScalingPoint> runScalingBench(const ScalingBenchOptions& opts, const ProgressFn& progress = {});

/// The figures as a table on stdout: seconds per stage, µs per vertex-step, memory per vertex, and how the evolution's
/// µs per vertex-step at the largest size compares with the smallest.
void printScalingBench(const std::vector<ScalingPoint>& points);

/// Writes scaling.csv and scaling.png (µs per vertex-step of each stage against simplex vertices, log x axis) into the
/// existing folder `dir`.
void writeScalingBench(const std::string& dir, const std::vector<ScalingPoint>& points, const std::string& title);

}  // namespace msk
