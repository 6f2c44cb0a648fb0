#pragma once
/// Constraints in two layers (STYLE.md): pure kernels that compute corrections for a few points, and constraint
/// sets that own indices, reference parameters and stiffness. Every set projects positions (PBD, DESIGN-NOTES §2,
/// §6); the force-based schemes consume the same sets later.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "msk/core/collision_response.h"
#include "msk/core/collision_surface.h"
#include "msk/core/simplex_batch.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

// ------------------------------------------------------------------------------------------------ kernels

/// 2-simplex internal constraint, method 2 (DESIGN-NOTES §2; thesis seed §4.8.1): moves P toward its target
/// P̃ = Σ ε̃i Pi + h̃ n and the neighbours Pi against it with λ' = [PP1 PP2 PP3]⁻¹ PP̃, λi = λ'i / Σλ'j, so linear
/// and angular momentum are conserved. Reduced mass m̄ = (w + Σ ε̃i λi wi)⁻¹ makes the full step (γ = 1) land on the
/// target to first order. Lengths in mm, w inverse masses (0 = fixed), γ ∈ [0,1]. Writes ΔP, ΔPi; returns false on
/// degenerate input (every particle fixed, non-finite target), leaving the outputs untouched. Where no torque-free
/// split exists (PP̃ nearly parallel to the neighbours' plane, or λ extreme) the neighbours share the reaction with
/// λ = ε̃ instead (linear momentum still conserved); `torqueFree` (optional) tells which branch was taken.
bool simplexInternalCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target,
                               double w, const double wi[3], const double epsTarget[3], double gamma,
                               Eigen::Vector3d& dp, Eigen::Vector3d dpi[3], bool* torqueFree = nullptr);

/// Independent target constraint (image force, DESIGN-NOTES §2): ΔP = γ·(T − P) for a free particle (α = M dt⁻²),
/// nothing for a fixed one. Returns false if w = 0.
bool targetCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double w, double gamma,
                      Eigen::Vector3d& dp);

/// Target of the 2-simplex shape memory at the current neighbours: P̃ = Σ ε̃i Pi + h̃·r⊥·n, with the reference height
/// stored scale-free (h̃ = h_ref / r⊥_ref) and rescaled by the current circumradius r⊥ of P1P2P3, so the memory holds
/// under a change of size. Returns false if the neighbours are degenerate (collinear).
bool simplexShapeTarget(const Eigen::Vector3d pi[3], const double epsRef[3], double heightOverRadius,
                        Eigen::Vector3d& target);

// ------------------------------------------------------------------------------------------------ rows

/// Most particles one constraint row touches (a 3-simplex vertex and its 4 neighbours).
constexpr int kMaxRowParticles = 5;

/// One constraint linearised at the current positions, the common currency of every scheme (solver.h). It is a
/// target-position constraint with a 3-vector residual C (mm) and scalar blocks: ∂C/∂Pj = gj·I (`grad`), and the
/// correction is shared as ΔPj = wj rj Δλ (`react`), with generalised inverse mass W = Σ gj rj wj. Then
/// - PBD (Gauss–Seidel, Jacobi): Δλ = −γ C / W, i.e. the kernels of this file (γ = 1 removes C to first order);
/// - XPBD: Δλ = (−C − α̃ λ) / (W + α̃), α̃ = 1/(k γ dt²);
/// - forces (DESIGN-NOTES §2, α = γ m̄ dt⁻², m̄ = 1/W): Fj = −rj α C, so that ΔPj = wj Fj dt² is the PBD step;
///   derivatives ∂Fj/∂Pl = −α gj gl S with S = I (target position) or k I + (1 − k) uuᵀ (target direction `direction`,
///   u = C/|C|); the non-symmetric 2-simplex blocks (r ≠ g) are replaced by these symmetric ones (Table 4.25).
/// Σ rj = 0 over a row's particles means its corrections and forces carry no linear momentum.
struct ConstraintRow {
  int count = 0;                     ///< particles used, ≤ kMaxRowParticles
  int index[kMaxRowParticles];       ///< global particle indices
  double grad[kMaxRowParticles];     ///< gj, ∂C/∂Pj = gj I
  double react[kMaxRowParticles];    ///< rj, ΔPj = wj rj Δλ
  Eigen::Vector3d c = Eigen::Vector3d::Zero();  ///< residual C, mm
  double gamma = 1.0;                ///< user stiffness of this constraint, γ ∈ [0, 1] (set stiffness × weight)
  bool direction = false;            ///< target direction (anisotropic derivative) rather than target position
};

// ------------------------------------------------------------------------------------------------ sets

/// A family of constraints projected together (sequential Gauss–Seidel order within the set). A set may also expose
/// its constraints one by one as rows (ConstraintRow), which lets the solvers of solver.h run it in coloured, Jacobi,
/// XPBD or force-based form; a set that does not (rowCount() = 0) is run through project() by every scheme.
class ConstraintSet {
 public:
  virtual ~ConstraintSet() = default;
  /// Family name for reports ("simplex-internal", "image-targets", ...).
  virtual std::string name() const = 0;
  /// Projects every constraint once on positions `p` (#V×3) with inverse masses `w`.
  virtual void project(Points& p, const Eigen::VectorXd& w) = 0;
  /// Index of the set's first particle in the solver's arrays (several objects are stacked in one system).
  void setFirstParticle(int first) {
    first_ = first;
    ++rowLayout_;
  }
  /// See setFirstParticle().
  int firstParticle() const { return first_; }

  /// Number of constraints exposed as rows; 0 (the default) = only project() is available.
  virtual int rowCount() const { return 0; }
  /// Global particle indices row `r` touches (at most kMaxRowParticles, written to `index`); returns their number.
  /// Must not depend on positions: solvers colour the rows with it. row() reads and writes no other particle.
  virtual int rowParticles(int r, int index[kMaxRowParticles]) const {
    (void)r;
    (void)index;
    return 0;
  }
  /// Prepares a pass over the rows at positions `p` (e.g. the global fit, smoothing heights); called before row().
  virtual void beginRows(const Points& p, const Eigen::VectorXd& w) {
    (void)p;
    (void)w;
  }
  /// Linearises row `r` at positions `p`; false if it is inactive or degenerate (skipped). Thread-safe for rows that
  /// share no particle.
  virtual bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const {
    (void)r;
    (void)p;
    (void)w;
    (void)out;
    return false;
  }
  /// Velocity pass before the prediction of every substep of length `h` at positions `x` (#V×3): a set may change
  /// the velocities `v` (acceleration-mode collision response). Default: nothing. Every scheme calls it.
  virtual void correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
    (void)x;
    (void)v;
    (void)w;
    (void)h;
  }
  /// Velocity pass after the velocity update of every substep of length `h` (after the damping on a step's last
  /// substep), at the new positions `x`: a set may change the velocities `v` (velocity-mode collision response).
  /// Default: nothing. Every scheme calls it.
  virtual void correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
    (void)x;
    (void)v;
    (void)w;
    (void)h;
  }
  /// Changes whenever the particles of the rows change (a solver then recolours them).
  std::uint64_t rowLayout() const { return rowLayout_; }
  /// Identity of this set object (unique per construction), so solvers can cache its colouring.
  std::uint64_t uid() const { return uid_; }

 protected:
  /// Call when the rows' particles change (other than through setFirstParticle()).
  void rowLayoutChanged() { ++rowLayout_; }
  int first_ = 0;

 private:
  static std::uint64_t newUid();
  std::uint64_t rowLayout_ = 0;
  std::uint64_t uid_ = newUid();
};

/// How the 2-simplex internal constraint chooses its target.
enum class InternalMode {
  ShapeMemory,  ///< ε̃, h̃ of the template (scale-free), the default
  /// ε̃ = 1/3, h̃ = mean of the neighbours' current scale-free heights; the step along the normal is a quarter of the
  /// way (the consistent step: P's own move changes its neighbours' heights) and the reactions are ε̃
  Smoothing
};

/// Reference metric parameters of every vertex of a 2-simplex mesh (DESIGN-NOTES §2, method 2): ε̃ (#V×3, barycentric
/// coordinates of the vertex's projection on its neighbours' plane) and the scale-free height h̃ = h / r⊥ (#V); a
/// vertex whose neighbours are degenerate gets ε̃ = ⅓ and h̃ = 0.
void simplexReferenceParameters(const SimplexMesh& reference, Eigen::MatrixX3d& eps, Eigen::VectorXd& hOverR);

/// Internal constraints of a 2-simplex mesh: one per vertex, targets from the reference (template) geometry.
class SimplexInternalConstraints : public ConstraintSet {
 public:
  /// Records the neighbour table and the reference metric parameters of `reference` (same connectivity as the
  /// meshes it will be applied to). γ ∈ [0, 1] (throws ParameterError otherwise).
  SimplexInternalConstraints(const SimplexMesh& reference, double gamma, InternalMode mode = InternalMode::ShapeMemory);
  std::string name() const override { return "simplex-internal"; }
  void project(Points& p, const Eigen::VectorXd& w) override;
  /// One row per vertex: C = P − P̃, g = (1, −ε̃i), r = (1, −λi) (method 2 split, as simplexInternalCorrection()).
  int rowCount() const override { return static_cast<int>(nb_.rows()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// The same rows as a batch kernel (simplex_batch.h: no virtual calls, several rows at a time), which the Solver's
  /// coloured Gauss–Seidel and Jacobi schemes run instead of row(); built on first use, at the set's first particle.
  /// Shape-memory mode only: nullptr in smoothing mode (its targets need a pass over the current heights).
  SimplexInternalBatch* batch();
  /// User stiffness γ.
  double gamma() const { return gamma_; }
  /// Number of projections skipped as degenerate in the last pass.
  int skipped() const { return skipped_; }

 private:
  /// Smoothing mode: the neighbourhood means of the current scale-free heights of the set's vertices `p` (#n×3).
  Eigen::VectorXd smoothingHeights(const Eigen::Ref<const Points>& p) const;
  std::unique_ptr<SimplexInternalBatch> batch_;  ///< built by batch() on first use
  NeighborTable nb_;
  Eigen::MatrixX3d eps_;
  Eigen::VectorXd hOverR_;
  Eigen::VectorXd rowHeights_;  ///< smoothing heights of the current row pass (beginRows())
  double gamma_;
  InternalMode mode_;
  int skipped_ = 0;
};

/// Independent target constraints: each vertex pulled toward its target with γ·weight_i (weights in [0, 1]).
class TargetConstraints : public ConstraintSet {
 public:
  /// γ ∈ [0, 1] (throws ParameterError otherwise).
  explicit TargetConstraints(double gamma);
  std::string name() const override { return "image-targets"; }
  /// Sets the targets (#V×3) and per-vertex weights (#V, clamped to [0, 1]).
  void setTargets(const Points& targets, const Eigen::VectorXd& weights);
  void project(Points& p, const Eigen::VectorXd& w) override;
  /// One row per vertex with weight > 0: C = P − T, g = r = 1, γ·weight, a target direction (anisotropic).
  int rowCount() const override { return static_cast<int>(targets_.rows()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;

 private:
  double gamma_;
  Points targets_;
  Eigen::VectorXd weights_;
};

/// Collision position correction, spring target (thesis seed Table 4.23, DESIGN-NOTES §3): vertex P against the point
/// P̄ = Σ bi Pi of a partner's triangle with outward normal n. With Pc = P̄ − P, the normal part is corrected to −g
/// (P at least `gap` mm outside) and the tangential part scaled by (1 − μ); the correction of Pc is shared with the
/// reduced mass m̄ = (w + Σ bi² wi)⁻¹ so linear momentum is conserved. Returns false when nothing is violated
/// (Pc·n + g ≤ 0) or every particle is fixed.
bool collisionCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const double bary[3],
                         const Eigen::Vector3d& normal, double gap, double friction, double w, const double wi[3],
                         Eigen::Vector3d& dp, Eigen::Vector3d dpi[3]);

/// Vertex–surface collisions of object A's vertices against a partner surface B (one direction; declare the reverse
/// set too). Contacts are detected once per step (detect()): the closest point of B within gap + proximity, and the
/// contact normal along the direction from that point to the vertex, signed (see detect()). The response
/// (collision_response.h, Table 4.23) is chosen per set: position mode projects with the other constraints
/// (project()), velocity mode corrects velocities after each substep's velocity update (correctVelocities()),
/// acceleration mode before each prediction (correctBeforePrediction()); each contact is resolved sequentially here,
/// or, with CollisionResolution::Global, by a GlobalCollisionResolution that owns this set's contacts together with
/// others' (this set alone then does nothing). The reference target's distance d_ref is recorded per vertex of A the
/// first time it is detected in contact (since construction or resetReference()), never less than the gap outside.
class CollisionConstraints : public ConstraintSet {
 public:
  /// `vertexCount` vertices of A start at particle `firstA`; `surfaceB` is shared with the other sets against B and
  /// updated by its owner once per step, before detect(); its reach must cover gap + proximity. gap ≥ 0 and
  /// proximity > 0 in mm, friction μ ∈ [0, 1] (ParameterError otherwise).
  CollisionConstraints(int firstA, int vertexCount, std::shared_ptr<CollisionSurface> surfaceB, double gapMm,
                       double proximityMm, double friction, const CollisionResponse& response = {});
  /// As above with a surface of its own over `trianglesB` (global particle indices), updated by every detect().
  CollisionConstraints(int firstA, int vertexCount, const Triangles& trianglesB, double gapMm, double proximityMm,
                       double friction, const CollisionResponse& response = {});
  std::string name() const override { return "collision"; }
  /// Finds, for every vertex of A, the closest point of B within gap + proximity at positions `p`. With `insideTest`
  /// the side comes from B's winding number (right even where B folds); without it every vertex is taken to be
  /// outside B, which is exact when the positions are collision-free and costs nothing (use the test where overlaps
  /// may already exist: first step of a level, clean-up sweeps, reports).
  void detect(const Points& p, bool insideTest = true);
  /// Position mode, sequential resolution: projectPositions(); velocity and acceleration modes (either resolution):
  /// projectDeep(); otherwise nothing.
  void project(Points& p, const Eigen::VectorXd& w) override;
  /// Position correction, spring target, of the contacts whose vertex is more than response().positionBeyondMm inside
  /// the partner (nothing when that is +inf).
  void projectDeep(Points& p, const Eigen::VectorXd& w);
  /// Acceleration mode, sequential: each contact's velocity change h·Ãc shared in turn.
  void correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) override;
  /// Velocity mode, sequential: each contact's velocity change Ṽc − Vc shared in turn.
  void correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) override;
  /// Position correction of every contact in turn with the set's target, whatever its mode and resolution (used by
  /// project() and by clean-up sweeps).
  void projectPositions(Points& p, const Eigen::VectorXd& w);
  /// The contacts linearised for a global solve in `mode` at positions `x` and velocities `v` (substep `h`), appended
  /// to `rows` (only contacts with something to correct).
  void appendRows(CollisionMode mode, const Points& x, const Points& v, double h, std::vector<ContactRow>& rows) const;
  /// The response this set was built with.
  const CollisionResponse& response() const { return response_; }
  /// Contact parameters (gap, proximity, friction, target).
  ContactParameters parameters() const { return {gap_, proximity_, friction_, response_.target}; }
  /// Forgets the recorded reference distances (the next detect() records them again).
  void resetReference();
  /// The recorded d_ref of vertex `v` of A (signed like Pc·n, mm; NaN if none is recorded).
  double referenceDistance(int v) const { return dref_[static_cast<size_t>(v)]; }
  /// Contacts found by the last detect().
  int contacts() const { return static_cast<int>(contacts_.size()); }
  /// Largest penetration (mm, ≥ 0) among the contacts at positions `p`: how far a vertex of A is inside B.
  double maxPenetration(const Points& p) const;

 private:
  struct Contact {
    int vertex, triangle;
    double bary[3];
    Eigen::Vector3d normal;  ///< from B toward the vertex's allowed side, fixed at detection
    Eigen::Vector3d pc0;     ///< Pc = P̄ − P at detection
  };
  /// Relative quantity Σ bi Xi − X_P of contact `c` over rows of `q` (positions or velocities).
  Eigen::Vector3d relative(const Contact& c, const Points& q) const;
  /// Shares `delta` of contact `c` onto `q` (positions or velocities).
  void apply(const Contact& c, const Eigen::Vector3d& delta, const Eigen::VectorXd& w, Points& q) const;
  int firstA_, count_;
  std::shared_ptr<CollisionSurface> surface_;
  bool ownsSurface_;
  double gap_, proximity_, friction_;
  CollisionResponse response_;
  std::vector<Contact> contacts_;
  std::vector<double> dref_;  ///< per vertex of A: recorded reference distance (NaN = none)
};

/// Global collision resolution (DESIGN-NOTES §5): the contacts of every member set (all built with
/// CollisionResolution::Global and this set's mode) resolved together by solveContactsGlobal() — in project() for
/// position mode, correctVelocities() for velocity mode, correctBeforePrediction() for acceleration mode; in position
/// mode each call solves up to three times, over the contacts still violated after the last solve. Members
/// are detected by their owner as usual; they must outlive this set.
class GlobalCollisionResolution : public ConstraintSet {
 public:
  /// `mode` of every member; conjugate-gradient settings `opts`.
  explicit GlobalCollisionResolution(CollisionMode mode, const GlobalContactOptions& opts = {});
  std::string name() const override { return "collision"; }
  /// Adds a member (ParameterError if its resolution is not global or its mode differs).
  void add(CollisionConstraints* set);
  void project(Points& p, const Eigen::VectorXd& w) override;
  void correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) override;
  void correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) override;
  /// One global position correction of every member's contacts with their targets, whatever the mode (clean-up).
  void projectPositions(Points& p, const Eigen::VectorXd& w);
  /// What the last solve did.
  const GlobalContactReport& lastReport() const { return report_; }
  /// The members.
  const std::vector<CollisionConstraints*>& members() const { return members_; }

 private:
  /// Up to kPasses global solves, each over the contacts with something left to correct at the current state.
  void solve(CollisionMode mode, const Points& x, const Points& v, double h, const Eigen::VectorXd& w, Points& q);
  static constexpr int kPasses = 3;
  CollisionMode mode_;
  GlobalContactOptions opts_;
  std::vector<CollisionConstraints*> members_;
  std::vector<ContactRow> rows_;
  GlobalContactReport report_;
};

/// Kind of transform a global shape prior fits.
enum class PriorTransform { Rigid, Similarity, Affine };

/// Global shape prior (shape matching, DESIGN-NOTES §1): pulls every vertex toward the best-fitting transform of the
/// reference shape, mass-weighted (Umeyama for rigid/similarity, least squares for affine). The weight λ can be
/// changed between steps (ramped over a run).
class ShapeMatchingConstraint : public ConstraintSet {
 public:
  /// `reference` #V×3; λ ∈ [0, 1] (throws ParameterError otherwise).
  ShapeMatchingConstraint(const Points& reference, PriorTransform transform, double lambda);
  std::string name() const override { return "global-prior"; }
  void project(Points& p, const Eigen::VectorXd& w) override;
  /// One row per vertex: C = P − goal, g = r = 1, γ = λ, the goals of the transform fitted by beginRows().
  int rowCount() const override { return static_cast<int>(ref_.rows()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// Sets λ ∈ [0, 1].
  void setLambda(double lambda);
  /// Current λ.
  double lambda() const { return lambda_; }
  /// The last fitted 4×4 transform (reference → current).
  const Eigen::Matrix4d& lastTransform() const { return last_; }

 private:
  /// Fits last_ to the set's particles of `pAll`, mass-weighted.
  void fit(const Points& pAll, const Eigen::VectorXd& wAll);
  Points ref_;
  PriorTransform transform_;
  double lambda_;
  Eigen::Matrix4d last_ = Eigen::Matrix4d::Identity();
};

/// Best transform mapping `from` onto `to` (rows are points), weighted by `weights` (#V, ≥ 0, not all zero).
/// Rigid and similarity fits are Umeyama's (proper rotations only); affine is weighted least squares.
Eigen::Matrix4d fitTransform(const Points& from, const Points& to, const Eigen::VectorXd& weights,
                             PriorTransform transform);

}  // namespace msk
