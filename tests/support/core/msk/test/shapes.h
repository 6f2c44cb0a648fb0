#pragma once
/// The meshes tests and benchmarks share: simplex spheres, perturbed copies, joined and displaced surfaces.
#include <Eigen/Core>
#include <random>

#include "msk/core/simplex_mesh.h"
#include "msk/core/triangle_mesh.h"

namespace msk::test {

/// Simplex sphere of radius `radiusMm` about `centre` (mm): the dual of makeIcosphere(radiusMm, subdivisions, centre),
/// 20·4^subdivisions vertices.
SimplexMesh simplexSphere(double radiusMm, int subdivisions = 2,
                          const Eigen::Vector3d& centre = Eigen::Vector3d::Zero());

/// `p` with a deterministic uniform perturbation of ±amplitude (mm) per coordinate (std::mt19937 seeded by `seed`).
Points perturbed(const Points& p, double amplitude, unsigned seed = 1);

/// A vector of three draws, each uniform in [−halfWidth, halfWidth) (mm), from `rng`.
Eigen::Vector3d uniformVector(std::mt19937& rng, double halfWidth = 1.0);

/// `count` points about the origin in uniformly random directions, at radius radiusMm × (1 ± spread) (uniform), from
/// std::mt19937 seeded by `seed`.
Points pointsNearSphere(int count, double radiusMm, double spread, unsigned seed);

/// One mesh holding both surfaces (b's vertices after a's, its faces renumbered): a surface covering some points
/// twice, or with a turned-over sheet when b's faces are reversed.
TriangleMesh joinedMeshes(const TriangleMesh& a, const TriangleMesh& b);

/// The mesh scaled by `scale` about its vertex centroid, then moved by `offsetMm` (a template never exactly in place).
TriangleMesh displacedScaled(const TriangleMesh& mesh, const Eigen::Vector3d& offsetMm, double scale);

}  // namespace msk::test
