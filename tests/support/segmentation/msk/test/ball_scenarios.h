#pragma once
/// Ball scenarios of the segmenter at the extremes, shared by tests/segmentation/extremes_test.cpp (which asserts on
/// them) and bench/solver_bench.cpp (which reports their figures): a template segmented into a ball image on small
/// grids, quickly (one or two levels, a coarse template), and the same scene in other length units.
#include <Eigen/Core>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/grid.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk::test {

/// A grid of spacing `spacing` (mm) covering ±halfWidth (mm) about the origin along each axis (at least 2 voxels).
Grid boxGrid(const Eigen::Vector3d& spacing, const Eigen::Vector3d& halfWidth);

/// One object named "ball" (label 1) from `templ`, its polarity fixed dark inside (so the polarity estimate, whose
/// sampling distances are in mm, plays no part).
Scene ballScene(const TriangleMesh& templ);

/// Small, fast settings: `levels` levels, at most `steps` steps each.
SegmentOptions quickOptions(int levels, int steps);

/// Mean distance (mm) of the mesh's vertices from `centre`.
double meanRadius(const TriangleMesh& m, const Eigen::Vector3d& centre);

/// The ball scene with every length multiplied by `unit` (1 = mm, 1e-3 = metres): a ball of radius 10 (200 inside,
/// 800 outside) on a 1-voxel grid of ±15, an icosphere template of radius 8, segmented with `levels` levels of at most
/// 25 steps; the result returned in mm. Lengths given in mm in the options are scaled too (the coarse levels' extra
/// search range; edge penalty off: its rate is per mm).
TriangleMesh ballInUnits(double unit, int levels);

}  // namespace msk::test
