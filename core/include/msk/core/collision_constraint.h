#pragma once
/// Vertex–surface collision constraints (thesis seed Tables 4.23 and 4.24, DESIGN-NOTES §3): one object's vertices
/// against a partner surface, each contact a row g = r = (−1, b) over the vertex and the partner triangle's corners,
/// and the global resolution of many contacts together (DESIGN-NOTES §5).
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "msk/core/collision_response.h"
#include "msk/core/collision_surface.h"
#include "msk/core/constraint_set.h"

namespace msk {

/// A contact's position correction as a row over (P, P1, P2, P3) (indices 0..3): Pc = Σ bi Pi − P is to change by
/// `delta` (contactPositionChange()), so C = −delta, g = r = (−1, b0, b1, b2) (Table 4.24), γ = 1, a hard row (zero
/// compliance under XPBD). The PBD step (pbdCorrections()) shares the change with the reduced mass
/// m̄ = (w + Σ bi² wi)⁻¹: ΔP = −w m̄ δ, ΔPi = wi bi m̄ δ, so Σ m ΔP = 0 (linear momentum conserved) and Pc changes by δ;
/// velocity and acceleration changes are shared the same way.
void contactRow(const Eigen::Vector3d& delta, const double bary[3], ConstraintRow& row);

/// The spring position correction (Table 4.23) of vertex P (inverse mass w) against the point Σ bi Pi of a partner
/// triangle (corners `pi`, inverse masses `wi`) with outward normal `normal`: contactPositionChange() with the spring
/// target, then the PBD step of contactRow(); P ends `gap` mm outside with its tangential offset scaled by (1 − μ).
/// Returns false when nothing is violated (P at least `gap` outside) or every particle is fixed.
bool collisionCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const double bary[3],
                         const Eigen::Vector3d& normal, double gap, double friction, double w, const double wi[3],
                         Eigen::Vector3d& dp, Eigen::Vector3d dpi[3]);

/// Vertex–surface collisions of object A's vertices against a partner surface B (one direction; declare the reverse
/// set too). Contacts are detected once per step (detect()): the closest point of B within gap + proximity, and the
/// contact normal along the direction from that point to the vertex, signed (see detect()). The response
/// (collision_response.h, Table 4.23) is chosen per set: position mode corrects positions with the other constraints
/// (each contact a row), velocity mode corrects velocities after each substep's velocity update (correctVelocities()),
/// acceleration mode before each prediction (correctBeforePrediction()); each contact is resolved on its own here,
/// or, with CollisionResolution::Global, by a GlobalCollisionResolution that owns this set's contacts together with
/// others' (this set alone then has no rows). The reference target's distance d_ref is recorded per vertex of A the
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
  /// the side comes from B's winding number (right even where B folds; a vertex that provably has not met B since the
  /// last detection keeps the side it had, which is the winding number's, see side_); without it every vertex is taken
  /// to be outside B, which is exact when the positions are collision-free and costs nothing (use the test where
  /// overlaps may already exist: first step of a level, clean-up sweeps, reports). `threads` > 1 splits A's vertices
  /// over that many threads (sets of at least 1024 vertices a thread), with the same result. With `followContacts` and
  /// without `insideTest`, where B's triangles are small (CollisionSurface::walkPays()), a vertex that found a triangle
  /// of B at the last detection looks for its closest point by walking from that triangle
  /// (CollisionSurface::closestAround(), a local answer) instead of scanning B's grid.
  void detect(const Points& p, bool insideTest = true, int threads = 1, bool followContacts = false);
  /// One row per contact of the last detect(): position mode with sequential resolution, the contact's position
  /// change toward the set's target; velocity and acceleration modes, the spring position correction of a contact
  /// whose vertex is more than response().positionBeyondMm inside the partner (none when that is +inf); position mode
  /// with global resolution, none.
  int rowCount() const override;
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// Acceleration mode, sequential: each contact's velocity change h·Ãc shared in turn.
  void correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) override;
  /// Velocity mode, sequential: each contact's velocity change Ṽc − Vc shared in turn.
  void correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) override;
  /// Position correction of every contact in turn with the set's target, whatever its mode and resolution (clean-up
  /// sweeps). Returns the number of contacts corrected (0: `p` is unchanged).
  int projectPositions(Points& p, const Eigen::VectorXd& w);
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
  /// The global indices of contact `c`: its vertex, then its triangle's corners.
  void contactParticles(const Contact& c, int index[4]) const;
  /// The position row of contact `c` at `p` toward `params`' target (spring: `deepOnly` contacts only); false if the
  /// contact has nothing to correct.
  bool positionRow(const Contact& c, const Points& p, const ContactParameters& params, bool deepOnly,
                   ConstraintRow& out) const;
  /// Shares `delta` of contact `c` onto `q` (velocities).
  void apply(const Contact& c, const Eigen::Vector3d& delta, const Eigen::VectorXd& w, Points& q) const;
  int firstA_, count_;
  std::shared_ptr<CollisionSurface> surface_;
  bool ownsSurface_;
  double gap_, proximity_, friction_;
  CollisionResponse response_;
  std::vector<Contact> contacts_;
  std::vector<double> dref_;  ///< per vertex of A: recorded reference distance (NaN = none)
  std::vector<int> hint_;     ///< per vertex of A: the partner triangle its last query found (−1 = none)
  /// Per vertex of A, from its last scan of B's grid that found nothing: the distance no triangle of B was nearer
  /// than (0 = none known), where the vertex was, and B's travelled() then. While the distance, less the vertex's
  /// move and B's travel since, stays beyond the reach, nothing can be found and the query is skipped.
  struct Clearance {
    double distance = 0;
    Eigen::Vector3d at = Eigen::Vector3d::Zero();
    double travelled = 0;
  };
  std::vector<Clearance> clear_;
  /// Per vertex of A, its side of B as of its last detection, while it is known: a lower bound on its distance to B
  /// then (0 = side not known), where it was, and B's travelled() then. If that distance, less the vertex's move and
  /// B's travel since, is still above zero, the vertex cannot have met B in between (on the straight path between the
  /// two configurations), and a closed surface's winding number changes only where a point crosses it: the side holds
  /// and a side test need not recompute it. Each detection carries the side on with its own bound (the distance a scan
  /// of B's grid found, or the clearance), so that the bound is that of one step's motion, not of many.
  struct Side {
    double distance = 0;
    Eigen::Vector3d at = Eigen::Vector3d::Zero();
    double travelled = 0;
    bool inside = false;
  };
  std::vector<Side> side_;
};

/// Global collision resolution (DESIGN-NOTES §5): the contacts of every member set (all built with
/// CollisionResolution::Global and this set's mode) resolved together by solveContactsGlobal() — in project() for
/// position mode, correctVelocities() for velocity mode, correctBeforePrediction() for acceleration mode; in position
/// mode each call solves up to three times, over the contacts still violated after the last solve. In velocity and
/// acceleration modes project() runs the members' rows (their deep contacts' position corrections). Members
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

}  // namespace msk
