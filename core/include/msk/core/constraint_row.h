#pragma once
/// One constraint linearised at the current positions (ConstraintRow), the common currency of every scheme
/// (solver.h), and its position-based correction.
#include <Eigen/Core>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Most particles one constraint row touches (a 3-simplex vertex and its 4 neighbours).
constexpr int kMaxRowParticles = 5;

/// A target-position constraint linearised at the current positions: a 3-vector residual C (mm) and scalar blocks,
/// ∂C/∂Pj = gj·I (`grad`); the correction is shared as ΔPj = wj rj Δλ (`react`), with generalised inverse mass
/// W = Σ gj rj wj. Then
/// - PBD (Gauss–Seidel, Jacobi): Δλ = −γ C / W (pbdCorrections(); γ = 1 removes C to first order);
/// - XPBD: Δλ = (−C − α̃ λ) / (W + α̃), α̃ = 1/(k γ dt²), or α̃ = 0 for a row that is not `compliant`;
/// - forces (DESIGN-NOTES §2, α = γ m̄ dt⁻², m̄ = 1/W): Fj = −rj α C, so that ΔPj = wj Fj dt² is the PBD step;
///   derivatives ∂Fj/∂Pl = −α gj gl S with S = I (target position) or k I + (1 − k) uuᵀ (target direction `direction`,
///   u = C/|C|); the non-symmetric 2-simplex blocks (r ≠ g) are replaced by these symmetric ones (Table 4.25).
/// Σ rj = 0 over a row's particles means its corrections and forces carry no linear momentum.
struct ConstraintRow {
  int count = 0;                   ///< particles used, ≤ kMaxRowParticles
  int index[kMaxRowParticles];     ///< particle indices (global in a set's rows, 0 .. count − 1 from a kernel)
  double grad[kMaxRowParticles];   ///< gj, ∂C/∂Pj = gj I
  double react[kMaxRowParticles];  ///< rj, ΔPj = wj rj Δλ
  Eigen::Vector3d c = Eigen::Vector3d::Zero();  ///< residual C, mm
  double gamma = 1.0;      ///< user stiffness of this constraint, γ ∈ [0, 1] (set stiffness × weight)
  bool direction = false;  ///< target direction (anisotropic derivative) rather than target position
  bool compliant = true;   ///< false: a hard constraint (contacts), which XPBD solves with zero compliance
};

/// Σ gj rj wj over the row's particles, `w` the inverse masses of the whole system: its generalised inverse mass W.
double rowInverseMass(const ConstraintRow& row, const Eigen::VectorXd& w);

/// The position-based corrections of one row (Δλ = −γ C / W, ΔPj = wj rj Δλ, j < row.count) for particles of inverse
/// masses `wj` (in row order) into `dp`. A one-particle row moves it by −γ C / g: its inverse mass cancels exactly.
/// Returns false (leaving `dp` untouched) if W ≤ 0 or is not finite, or C is not finite.
bool pbdCorrections(const ConstraintRow& row, const double wj[], Eigen::Vector3d dp[]);

/// pbdCorrections() of a kernel's row over (P, P1 .. Pn) (indices 0 .. n, n = row.count − 1): ΔP into `dp` and ΔPi
/// into `dpi`, for the inverse masses w of P and wi of the Pi.
bool pbdCorrections(const ConstraintRow& row, double w, const double wi[], Eigen::Vector3d& dp, Eigen::Vector3d dpi[]);

/// pbdCorrections() of a row over global indices, with the inverse masses `w`, added to the positions `p`.
bool applyPbdRow(const ConstraintRow& row, const Eigen::VectorXd& w, Points& p);

}  // namespace msk
