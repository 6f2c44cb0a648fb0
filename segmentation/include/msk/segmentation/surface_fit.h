#pragma once
/// A template surface fitted onto another subject's surface of the same structure, keeping the template's
/// triangulation: the vertex-to-vertex correspondence that an atlas of several subjects averages its shape and its
/// learned intensity profiles over.
#include <cstddef>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Parameters of fitSurface().
struct SurfaceFitOptions {
  int similarityIterations = 30;  ///< closest-point alignment by rotation, uniform scale and translation
  int iterations = 40;            ///< non-rigid steps, from a stiff to a loose fit
  /// Smoothing of the displacement field in the first and the last non-rigid step (Jacobi sweeps of the umbrella
  /// average over the template's edges: stiff first, so that the template moves as a whole and keeps its
  /// correspondence, then loose so that it follows the target's detail).
  int smoothingFirst = 60, smoothingLast = 2;
};

/// What fitSurface() reached.
struct SurfaceFitReport {
  double scale = 1;                  ///< the similarity stage's uniform scale
  double meanDistanceMm = 0;         ///< fitted vertices to the target's triangles, mean
  double maxDistanceMm = 0;          ///< ... largest
  double meanReverseDistanceMm = 0;  ///< the target's vertices to the fitted triangles, mean
  double volumeRatio = 1;            ///< fitted volume / target volume
  size_t selfIntersections = 0;      ///< face pairs of the fitted surface that cross
};

/// `moving` (a closed template, already roughly in place, e.g. by image registration) deformed onto `target` (a
/// closed surface of the same structure): a similarity alignment by symmetric closest points, then non-rigid steps
/// toward the target (each vertex to its closest target point, each target vertex pulling its closest fitted
/// point) with the displacements smoothed over the template's edges, stiff to loose, and a tangential relaxation
/// that keeps the triangles' shapes. The result has `moving`'s faces and vertex order. Throws Error if either mesh is
/// not closed.
TriangleMesh fitSurface(const TriangleMesh& moving, const TriangleMesh& target, const SurfaceFitOptions& opts = {},
                        SurfaceFitReport* report = nullptr);

}  // namespace msk
