#pragma once
/// Axis-first scenarios, shared by tests/segmentation/axis_first_stage_test.cpp (which asserts on them) and
/// bench/phantom_bench.cpp (which reports their figures): a tube bent in the image reached from a straight, displaced
/// template, and the bundled phantom's hamstrings and adductors from moved templates, each with no medial axis, with
/// the axis alone and with the axis evolved first.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk::test {

/// A rounded tube along x: |x/half|⁴ + (ρ/radius)² ≤ 1 (ρ the distance from the x axis), bent across by
/// bend · (x/half)² mm along y, then moved by `offset` mm.
struct BentTube {
  double half = 40.0, radius = 8.0, bend = 0.0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  /// Whether world point p (mm) is inside.
  bool inside(const Eigen::Vector3d& p) const;
  /// The surface: an icosphere mapped onto the tube (x = half·sign(a)·|a|^½ for a unit-sphere point (a, b, c)), bent
  /// and moved like inside().
  TriangleMesh mesh(int subdivisions = 4) const;
};

/// A 1 mm grid covering x ∈ ±52, y ∈ [−18, 30], z ∈ ±18 mm.
Grid tubeGrid();

/// The tube as an image with partial volume (4³ samples per voxel): 800 inside, 200 outside.
ImageF tubeImage(const Grid& g, const BentTube& t);

/// One muscle named "tube" (label 1) from `templ`, with a medial axis if `medialAxis` and then axis-first `axisFirst`.
Scene tubeScene(const TriangleMesh& templ, bool medialAxis, bool axisFirst);

/// A run and its result surface against the truth surface.
struct AxisRun {
  SegmentationResult res;
  SegmentationMetrics m;
};

/// The bent-tube scenario: the bend of the tube in the image, and how far the straight template is moved (mm).
struct BentTubeCase {
  double bendMm;
  Eigen::Vector3d offsetMm;
};
/// Straight and moved 6.7 mm; bent 8 mm, not moved; bent 12 mm and moved 6.7 mm.
const std::vector<BentTubeCase>& bentTubeCases();

/// The template against the truth, then the runs with no medial axis, with the axis alone and with the axis first.
struct BentTubeRuns {
  SegmentationMetrics start;
  AxisRun plain, axis, first;
};
BentTubeRuns runBentTube(const BentTubeCase& c);

/// A muscle of the bundled thigh alone, its template moved by (8, 4, 0) mm: label metrics of the template as it is and
/// as the stage alone leaves it (one step without image force), then of the full runs with no axis, with the axis
/// alone and with the axis first (and the stage's steps).
struct DisplacedMuscleRuns {
  SegmentationMetrics templ, stage, plain, axis, first;
  int stageSteps = 0;
};
/// Which full runs runDisplacedThighMuscle() makes: all three, or only the one with the axis first (`plain` and `axis`
/// left empty).
enum class FullRuns { All, AxisFirstOnly };
DisplacedMuscleRuns runDisplacedThighMuscle(const std::string& name, FullRuns full = FullRuns::All);

}  // namespace msk::test
