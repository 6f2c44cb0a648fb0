#pragma once
/// Untangling and smoothing of tet-mesh nodes. The signed volume of a tet is linear in each of its nodes
/// (V_t(x) = (f0 − x)·n_t / 6, n_t the outward area normal of the face opposite x), so with relative volumes
/// u_t = V_t / R_t the energy E = Σ_t exp(−k u_t) is convex in every single node. It grows steeply on flat and inverted
/// tets and is negligible on good ones, so lowering it untangles (a smooth stand-in for maximising the smallest volume,
/// Freitag & Plassmann 2000, "Local optimization-based simplicial mesh untangling and improvement"). It is lowered by
/// node-wise damped Newton steps (block coordinate descent, so neighbouring nodes can trade), Gauss–Seidel in index
/// order, sweep after sweep, visiting only nodes next to a tet with u_t below a threshold; when the sweeps stall with
/// tets still inverted, k is raised fourfold (up to 64 times the start), nearer to max-min volume. A node whose tets
/// are all positive is never moved so that one inverts (a valid mesh stays valid). A node may carry a move
/// limit L (a ball around its start, plus the anchor term β|x − x_start|²/L² so it moves no more than it must).
/// Moving nodes inside a mesh does not change the sum of signed volumes; moving only interior nodes keeps the total
/// volume exactly.
#include <Eigen/Core>
#include <vector>

#include "msk/core/volume_simplex.h"

namespace msk {

/// Options of untangleTets().
struct TetUntangleOptions {
  /// A movable node is optimised while one of its tets has a relative volume V_t/R_t under this (dimensionless;
  /// +infinity optimises every movable node in every sweep, i.e. smoothing).
  double minRelativeVolume = 0.05;
  int maxSweeps = 200;      ///< Gauss–Seidel sweeps at most (a sweep visits only the nodes that qualify)
  double sharpness = 20;    ///< k of the energy (dimensionless): how much more a flat tet weighs than a good one
  double anchorWeight = 1;  ///< β of the anchor term of nodes with a finite move limit (dimensionless)
  /// Sweeps stop once no node moved more than this fraction of its tets' length scale (cube root of R_t).
  double tolerance = 1e-4;
};

/// What untangleTets() did.
struct TetUntangleReport {
  int invertedBefore = 0;             ///< tets with V ≤ 0 at the start
  int invertedAfter = 0;              ///< tets with V ≤ 0 at the end
  int sweeps = 0;                     ///< sweeps run
  int moves = 0;                      ///< node moves kept
  double minRelativeVolumeAfter = 0;  ///< smallest V_t/R_t at the end
};

/// Moves the nodes of `mesh` to raise the smallest relative volume V_t/R_t of their tets, as in the file comment, each
/// node i at most `moveLimit[i]` mm from where it starts (#N; 0 = fixed, infinity = free). `reference` (#T, mm³, all
/// > 0) gives R_t, e.g. the rest volumes of the tets; empty means R_t = 1 mm³. Throws ParameterError on sizes that do
/// not match, a negative or NaN limit, or a non-positive reference volume.
TetUntangleReport untangleTets(TetMesh& mesh, const Eigen::VectorXd& moveLimit, const Eigen::VectorXd& reference = {},
                               const TetUntangleOptions& options = {});

/// What untangleTetMesh() did.
struct TetMeshUntangleReport {
  TetUntangleReport interior;        ///< first pass: interior nodes only
  TetUntangleReport boundary;        ///< second pass (sweeps = 0 if not needed): boundary nodes near inverted tets too
  int invertedAfter = 0;             ///< tets with V ≤ 0 at the end
  int boundaryNodesMoved = 0;        ///< boundary nodes the second pass moved
  double largestBoundaryMoveMm = 0;  ///< how far the furthest of them moved
};

/// Untangles a tet mesh whose boundary nodes sit on a surface that must be kept: first the interior nodes alone (free,
/// untangleTets()); if tets stay inverted (the surface leaves an interior node no room), a second pass where also the
/// boundary nodes of the tets touching an inverted tet's nodes may move, at most `boundaryReachMm` each (the interior
/// nodes still free). `reference` as in untangleTets(). The total volume changes only by the boundary moves.
TetMeshUntangleReport untangleTetMesh(TetMesh& mesh, const Eigen::VectorXd& reference, double boundaryReachMm,
                                      const TetUntangleOptions& options = {});

/// Shape smoothing of valid tets: every node marked 1 in `movable` (#N) is moved, sweep after sweep (at most
/// `sweeps`), to raise the smallest shape quality q = 6√2 V / l_rms³ of its tets (1 for a regular tet, 0 flat, < 0
/// inverted; l_rms the root mean square edge length) by a compass search (steps along ±x, ±y, ±z from a quarter of the
/// mean edge at the node, halved down to 1e-3 of it); a move is kept only if it raises that smallest quality. Returns
/// the smallest quality over the whole mesh at the end (a node whose tets are all positive keeps them so). Throws
/// ParameterError if `movable` has not #N entries.
double improveTetShapes(TetMesh& mesh, const std::vector<char>& movable, int sweeps = 5);

/// improveTetShapes() where it is needed: on the interior nodes (off the boundary faces) of the tets whose shape
/// quality is under `below` (dimensionless, 0..1); the boundary stays, so does the total volume, and a node whose tets
/// are all positive keeps them so. Returns the smallest quality at the end. Throws ParameterError if `below` is NaN.
double improveWorstTetShapes(TetMesh& mesh, double below = 0.3, int sweeps = 5);

/// Shape quality 6√2 V / l_rms³ of every tet, #T (1 regular, 0 flat, negative inverted).
Eigen::VectorXd tetShapeQualities(const TetMesh& mesh);

/// untangleTets() with the nodes marked 1 in `movable` (#N) free and the others fixed.
TetUntangleReport untangleTets(TetMesh& mesh, const std::vector<char>& movable, const Eigen::VectorXd& reference = {},
                               const TetUntangleOptions& options = {});

}  // namespace msk
