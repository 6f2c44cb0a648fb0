#pragma once
/// Collision response of a vertex–surface contact (thesis seed Table 4.23, DESIGN-NOTES §3 and §5): the pure kernels
/// that turn one contact into the wanted change of its relative position, velocity or acceleration (position,
/// velocity or acceleration correction; spring, reaction or reference target), and the global resolution Y = H W of
/// many contacts at once by conjugate gradient. The constraint sets that own contacts (CollisionConstraints,
/// GlobalCollisionResolution in collision_constraint.h) are thin owners of these kernels; a single contact's change is
/// shared between the vertex and the triangle's corners as a constraint row (contactRow()).
///
/// Notation: vertex P (inverse mass w) against P̄ = Σ bi Pi on a partner triangle (corners Pi, inverse masses wi),
/// contact normal n (unit, from the partner toward P's allowed side). Relative position Pc = P̄ − P, velocity
/// Vc = Σ bi Vi − V; Pc·n = −(distance of P outside the partner). Gap g ≥ 0 mm, proximity d_max > 0 mm, friction
/// μ ∈ [0, 1], proximity factor λ = clamp(1 + (Pc·n + g)/d_max, 0, 1): 1 within the gap, 0 beyond g + d_max.
#include <Eigen/Core>
#include <limits>
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// What a contact corrects (Table 4.23).
enum class CollisionMode {
  Position,     ///< "position": the predicted positions, projected with the other constraints (PBD)
  Velocity,     ///< "velocity": the velocities, after the velocity update of each substep
  Acceleration  ///< "acceleration": the velocities by h·Ãc, before the prediction of each substep (1st order)
};
/// "position" | "velocity" | "acceleration".
const char* collisionModeName(CollisionMode m);

/// Where a contact is sent (Table 4.23).
enum class CollisionTarget {
  Spring,    ///< "spring": within the gap (λ = 1), P̃c = (1 − μ) Pc_t − g n
  Reaction,  ///< "reaction": in the proximity band (0 < λ < 1) an approach is slowed by λ; within the gap, spring
  Reference  ///< "reference": soft attachment (0 < λ ≤ 1), P̃c = (1 − μ) Pc_t + d_ref n, d_ref recorded
};
/// "spring" | "reaction" | "reference".
const char* collisionTargetName(CollisionTarget t);

/// How the contacts of a set are resolved together (DESIGN-NOTES §5).
enum class CollisionResolution {
  Sequential,  ///< "sequential": one contact after the other (Gauss–Seidel), each at the current state
  Global       ///< "global": all contacts at once, Y = H W solved by conjugate gradient
};
/// "sequential" | "global".
const char* collisionResolutionName(CollisionResolution r);

/// The response a collision pair asks for; the default is the seed's position correction with a spring target,
/// resolved sequentially.
struct CollisionResponse {
  CollisionMode mode = CollisionMode::Position;                      ///< what is corrected
  CollisionTarget target = CollisionTarget::Spring;                  ///< where contacts are sent
  CollisionResolution resolution = CollisionResolution::Sequential;  ///< one by one or all at once
  /// Velocity and acceleration modes: a contact whose vertex is more than this far inside the partner (Pc·n > it, mm)
  /// is corrected in position instead, sequentially with the spring target, in the projection phase (the seed's
  /// robust practice: position correction first, with thresholds). +inf (default): never.
  double positionBeyondMm = std::numeric_limits<double>::infinity();
};

/// Contact parameters: gap g (mm, ≥ 0), proximity d_max (mm, > 0), friction μ ∈ [0, 1], target.
struct ContactParameters {
  double gap = 0.2;                                  ///< g, mm
  double proximity = 1.0;                            ///< d_max, mm
  double friction = 0.0;                             ///< μ
  CollisionTarget target = CollisionTarget::Spring;  ///< spring | reaction | reference
};

/// Proximity factor λ = clamp(1 + (Pc·n + g)/d_max, 0, 1) of Table 4.23 (`pcn` = Pc·n in mm).
double proximityFactor(double pcn, double gap, double proximity);

/// The target relative position P̃c of a contact at Pc (Table 4.23): spring (1 − μ) Pc_t − g n, reference
/// (1 − μ) Pc_t + d_ref n (`dref` mm, signed like Pc·n: −(wanted distance outside)).
Eigen::Vector3d contactPositionTarget(const Eigen::Vector3d& pc, const Eigen::Vector3d& n, const ContactParameters& c,
                                      double dref);

/// Position correction (Table 4.23): the wanted change ΔPc (mm) of a contact now at `pc`, which was at `pc0` when it
/// was detected (start of the step). Spring: P̃c − Pc within the gap (λ = 1). Reference: P̃c − Pc while λ > 0.
/// Reaction: within the gap as spring; in the band (0 < λ0 < 1, λ0 at `pc0`) the displacement D = Pc − Pc0 of this
/// step is replaced by the reaction of the velocity correction applied to it ((1 − λ0) D_n + (1 − λ0 μ) D_t if
/// approaching, D·n > 0; D_n + (1 − λ0 μ) D_t otherwise). Returns false when there is nothing to correct.
bool contactPositionChange(const Eigen::Vector3d& pc, const Eigen::Vector3d& pc0, const Eigen::Vector3d& n,
                           const ContactParameters& c, double dref, Eigen::Vector3d& delta);

/// Velocity correction (Table 4.23): the wanted change ΔVc = Ṽc − Vc (mm per unit time) of a contact at `pc` moving
/// at `vc`, for a substep `h` (> 0). Spring (λ = 1) and reference (λ > 0): Ṽc = (P̃c − Pc)/h. Reaction: in the band
/// (0 < λ < 1) Ṽc = (1 − λ) Vc_n + (1 − λμ) Vc_t when approaching (Vc·n > 0), else Vc_n + (1 − λμ) Vc_t; within the
/// gap as spring. Returns false when there is nothing to correct.
bool contactVelocityChange(const Eigen::Vector3d& pc, const Eigen::Vector3d& vc, const Eigen::Vector3d& n,
                           const ContactParameters& c, double dref, double h, Eigen::Vector3d& delta);

/// Acceleration correction, first order (Table 4.23): the velocity change h·ΔAc (mm per unit time) applied before
/// the prediction of a substep `h`, with ΔAc = Ãc − Ac and Ac = 0 (the position-based schemes carry no external
/// acceleration). Spring (λ = 1) and reference (λ > 0): Ãc = (P̃c − Pc)/h²; reaction in the band: Ãc = (Ṽc − Vc)/h
/// with Ṽc of the velocity correction; within the gap as spring. Returns false when there is nothing to correct.
bool contactAccelerationChange(const Eigen::Vector3d& pc, const Eigen::Vector3d& vc, const Eigen::Vector3d& n,
                               const ContactParameters& c, double dref, double h, Eigen::Vector3d& delta);

/// One contact linearised for the global resolution: Pc = Σ_j a_j X_j over 4 particles (a = −1 for the vertex, bi
/// for the corners), the wanted change Y = ΔPc (or ΔVc), and its normal.
struct ContactRow {
  int index[4] = {0, 0, 0, 0};                        ///< global particle indices: vertex, then the triangle's corners
  double weight[4] = {-1, 0, 0, 0};                   ///< a_j
  Eigen::Vector3d change = Eigen::Vector3d::Zero();   ///< Y_k, mm (or mm per unit time)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< n_k
  bool unilateral = true;  ///< may only push apart (spring, reaction); false: attachment (reference)
};

/// Settings of the global resolution.
struct GlobalContactOptions {
  int maxIterations = 100;       ///< conjugate-gradient iterations per solve (≥ 1)
  double tolerance = 1e-4;       ///< stop when the preconditioned residual falls below this share of the first (> 0)
  double regularization = 1e-6;  ///< ε added to H's diagonal, relative to its mean (≥ 0): bounds dependent contacts'
                                 ///< multipliers and the conditioning; each contact then reaches its change to ~ε
  int activeSetRounds = 4;       ///< most solves of the active-set loop over unilateral rows (1 = one plain solve)
};

/// What the last global solve did.
struct GlobalContactReport {
  int rows = 0;         ///< contacts in the system (free ones)
  int iterations = 0;   ///< conjugate-gradient iterations over all rounds
  double residual = 0;  ///< relative preconditioned residual left
  int dropped = 0;      ///< times a unilateral row was let go because it pulled
};

/// Global collision resolution (DESIGN-NOTES §5, thesis seed): solves Y = H W with Y_k = `rows[k].change`,
/// H_kl = Σ_{i ∈ k∩l} a_ik w_i a_il (d_k·d_l) over scalar rows along each contact's normal and its wanted tangential
/// change d (symmetric positive semi-definite; opts.regularization × the mean diagonal added so that dependent
/// contacts give a bounded solution, rows whose particles are all fixed left out), W_l = m_l ΔC_l the
/// contact's multiplier, by Jacobi-preconditioned conjugate gradient on the three columns together, then applies
/// ΔX_i = w_i Σ_k a_ik W_k to `q` (positions or velocities, #V×3), which conserves linear momentum. Unilateral rows
/// (contacts may push, not pull) go through an active-set loop: a row whose multiplier pulls (W_k·n_k > 0) is let go,
/// one let go that the others leave short of its wanted normal change is taken back, and the system solved again
/// (at most opts.activeSetRounds solves). Inverse masses `w` (#V, 0 = fixed).
GlobalContactReport solveContactsGlobal(const std::vector<ContactRow>& rows, const Eigen::VectorXd& w, Points& q,
                                        const GlobalContactOptions& opts = {});

}  // namespace msk
