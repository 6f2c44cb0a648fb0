#include "msk/core/collision_constraint.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "msk/core/error.h"
#include "msk/core/winding_number.h"

namespace msk {

void contactRow(const Eigen::Vector3d& delta, const double bary[3], ConstraintRow& row) {
  row.count = 4;
  row.c = -delta;
  row.gamma = 1.0;
  row.direction = false;
  row.compliant = false;
  row.index[0] = 0;
  row.grad[0] = row.react[0] = -1.0;
  for (int i = 0; i < 3; ++i) {
    row.index[i + 1] = i + 1;
    row.grad[i + 1] = row.react[i + 1] = bary[i];
  }
}

bool collisionCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const double bary[3],
                         const Eigen::Vector3d& normal, double gap, double friction, double w, const double wi[3],
                         Eigen::Vector3d& dp, Eigen::Vector3d dpi[3]) {
  const Eigen::Vector3d pc = bary[0] * pi[0] + bary[1] * pi[1] + bary[2] * pi[2] - p;
  const ContactParameters spring{gap, 1.0, friction, CollisionTarget::Spring};
  Eigen::Vector3d delta;
  if (!contactPositionChange(pc, pc, normal, spring, 0.0, delta)) return false;
  ConstraintRow row;
  contactRow(delta, bary, row);
  return pbdCorrections(row, w, wi, dp, dpi);
}

namespace {
void checkContactParameters(double gapMm, double proximityMm, double friction) {
  if (!(gapMm >= 0) || !std::isfinite(gapMm))
    throw ParameterError("collision gap", std::to_string(gapMm), "must be >= 0 mm");
  if (!(proximityMm > 0) || !std::isfinite(proximityMm))
    throw ParameterError("collision proximity", std::to_string(proximityMm), "must be > 0 mm");
  checkUnitInterval("collision friction", friction);
}
}  // namespace

CollisionConstraints::CollisionConstraints(int firstA, int vertexCount, std::shared_ptr<CollisionSurface> surfaceB,
                                           double gapMm, double proximityMm, double friction,
                                           const CollisionResponse& response)
    : firstA_(firstA),
      count_(vertexCount),
      surface_(std::move(surfaceB)),
      ownsSurface_(false),
      gap_(gapMm),
      proximity_(proximityMm),
      friction_(friction),
      response_(response),
      dref_(static_cast<size_t>(std::max(vertexCount, 0)), std::numeric_limits<double>::quiet_NaN()),
      hint_(static_cast<size_t>(std::max(vertexCount, 0)), -1),
      clear_(static_cast<size_t>(std::max(vertexCount, 0))),
      side_(static_cast<size_t>(std::max(vertexCount, 0))) {
  checkContactParameters(gapMm, proximityMm, friction);
  MSK_ASSERT(surface_ && surface_->reach() >= gapMm + proximityMm, "collision surface reach below gap + proximity");
  first_ = firstA;
}

CollisionConstraints::CollisionConstraints(int firstA, int vertexCount, const Triangles& trianglesB, double gapMm,
                                           double proximityMm, double friction, const CollisionResponse& response)
    : CollisionConstraints(firstA, vertexCount,
                           (checkContactParameters(gapMm, proximityMm, friction),
                            std::make_shared<CollisionSurface>(trianglesB, gapMm + proximityMm)),
                           gapMm, proximityMm, friction, response) {
  ownsSurface_ = true;
}

void CollisionConstraints::resetReference() {
  std::fill(dref_.begin(), dref_.end(), std::numeric_limits<double>::quiet_NaN());
}

void CollisionConstraints::detect(const Points& p, bool insideTest, int threads, bool followContacts) {
  contacts_.clear();
  rowLayoutChanged();
  if (surface_->triangles().rows() == 0 || count_ == 0) return;
  if (ownsSurface_) surface_->update(p);
  const double reach = gap_ + proximity_;
  const double travelled = surface_->travelled();
  const bool reference = response_.target == CollisionTarget::Reference;
  const bool walk = followContacts && !insideTest && surface_->walkPays();
  // The vertices in contiguous ranges, one per thread: each vertex's query reads the positions and B's grid and writes
  // only its own slots, and the ranges' contacts are joined in vertex order, so the result is the same for any count.
  auto examine = [&](int begin, int end, std::vector<Contact>& found) {
    const WindingNumber* winding = nullptr;  // of B at p (shared with the other sets against B), when a side is needed
    for (int v = begin; v < end; ++v) {
      const Eigen::Vector3d q = p.row(firstA_ + v).transpose();
      const double tolerance = 1e-9 * (1.0 + q.norm());
      // Whether the side known at the last detection still holds; from here on `known` is carried to this one with
      // the lower bound on the distance it finds (or left unknown).
      Side& known = side_[static_cast<size_t>(v)];
      if (known.distance > 0 && !(known.distance - (q - known.at).norm() - (travelled - known.travelled) > tolerance))
        known.distance = 0;
      const auto carrySide = [&](double distanceAtLeast) {
        if (known.distance > 0) known = {distanceAtLeast, q, travelled, known.inside};
      };
      // The triangle found last time starts the search: between detections a vertex moves a fraction of a triangle.
      int& hint = hint_[static_cast<size_t>(v)];
      Clearance& clear = clear_[static_cast<size_t>(v)];
      if (clear.distance > 0) {
        const double left = clear.distance - (q - clear.at).norm() - (travelled - clear.travelled);
        if (left > reach * (1 + 1e-9) + 1e-9) {
          hint = -1;  // what the query would find
          carrySide(left);
          continue;
        }
      }
      double clearance = 0;
      // Between side tests a vertex that found a partner triangle follows it over the triangles around it where B's
      // triangles are small against the reach (a local answer: the side test's steps scan the grid, which also sees a
      // nearer part of B the walk cannot); the grid is scanned too when the walk finds nothing within the reach.
      SurfacePoint s;
      bool walked = false;
      if (hint >= 0 && walk) {
        s = surface_->closestAround(p, q, hint, reach);
        walked = s.triangle >= 0;
      }
      if (s.triangle < 0) s = surface_->closest(p, q, reach, hint, &clearance);
      hint = s.triangle;
      clear.distance = s.triangle < 0 ? clearance : 0.0;
      clear.at = q;
      clear.travelled = travelled;
      if (s.triangle < 0) {
        carrySide(clearance);
        continue;
      }
      Contact c{v, s.triangle, {s.bary[0], s.bary[1], s.bary[2]}, Eigen::Vector3d::Zero(), s.point - q};
      // Contact normal: the direction from the closest point to the vertex. Without the inside test every vertex is
      // taken to be outside (true when each step starts collision-free), so a correction can never push it through
      // B. With it, the side comes from B's winding number, which stays right where B folds or is stretched (a face or
      // pseudonormal there can point the wrong way and push the vertex through).
      const Eigen::Vector3d off = q - s.point;
      if (s.distance > tolerance) {
        bool inside = false;
        if (insideTest) {  // a side test scans the grid (no walk): s.distance is the distance to all of B
          if (!(known.distance > 0)) {
            if (!winding) winding = &surface_->winding(p);
            known.inside = winding->inside(q);
          }
          inside = known.inside;
          known = {s.distance, q, travelled, inside};
        } else if (walked) {
          known.distance = 0;  // a walk's distance is a local one, no bound on the distance to all of B
        } else {
          carrySide(s.distance);
        }
        c.normal = (inside ? -1.0 : 1.0) * off / s.distance;
      } else {  // on the surface: B's outward side
        known.distance = 0;
        const Eigen::Vector3d pseudo = surface_->pseudonormal(p, s);
        if (!(pseudo.norm() > 1e-12)) continue;
        c.normal = pseudo.normalized();
      }
      // Reference target: the distance of the first detection is the one kept (at least the gap outside).
      if (reference && std::isnan(dref_[static_cast<size_t>(v)]))
        dref_[static_cast<size_t>(v)] = std::min(c.pc0.dot(c.normal), -gap_);
      found.push_back(c);
    }
  };
  const int ranges = std::max(1, std::min(threads, count_ / 1024));
  if (ranges == 1) {
    examine(0, count_, contacts_);
    return;
  }
  std::vector<std::vector<Contact>> found(static_cast<size_t>(ranges));
  std::vector<std::thread> pool;
  for (int r = 1; r < ranges; ++r)
    pool.emplace_back(examine, r * count_ / ranges, (r + 1) * count_ / ranges, std::ref(found[static_cast<size_t>(r)]));
  examine(0, count_ / ranges, found[0]);
  for (std::thread& t : pool) t.join();
  for (const std::vector<Contact>& part : found) contacts_.insert(contacts_.end(), part.begin(), part.end());
}

Eigen::Vector3d CollisionConstraints::relative(const Contact& c, const Points& q) const {
  const Triangles& tri = surface_->triangles();
  return c.bary[0] * q.row(tri(c.triangle, 0)).transpose() + c.bary[1] * q.row(tri(c.triangle, 1)).transpose() +
         c.bary[2] * q.row(tri(c.triangle, 2)).transpose() - q.row(firstA_ + c.vertex).transpose();
}

void CollisionConstraints::contactParticles(const Contact& c, int index[4]) const {
  const Triangles& tri = surface_->triangles();
  index[0] = firstA_ + c.vertex;
  for (int i = 0; i < 3; ++i) index[i + 1] = tri(c.triangle, i);
}

void CollisionConstraints::apply(const Contact& c, const Eigen::Vector3d& delta, const Eigen::VectorXd& w,
                                 Points& q) const {
  ConstraintRow row;
  contactRow(delta, c.bary, row);
  contactParticles(c, row.index);
  applyPbdRow(row, w, q);
}

int CollisionConstraints::rowCount() const {
  const bool rows = response_.mode == CollisionMode::Position ? response_.resolution == CollisionResolution::Sequential
                                                              : std::isfinite(response_.positionBeyondMm);
  return rows ? static_cast<int>(contacts_.size()) : 0;
}

int CollisionConstraints::rowParticles(int r, int index[kMaxRowParticles]) const {
  contactParticles(contacts_[static_cast<size_t>(r)], index);
  return 4;
}

bool CollisionConstraints::positionRow(const Contact& c, const Points& p, const ContactParameters& params,
                                       bool deepOnly, ConstraintRow& out) const {
  const Eigen::Vector3d pc = relative(c, p);
  if (deepOnly && !(pc.dot(c.normal) > response_.positionBeyondMm)) return false;
  Eigen::Vector3d delta;
  const double dref = deepOnly ? 0.0 : dref_[static_cast<size_t>(c.vertex)];
  if (!contactPositionChange(pc, c.pc0, c.normal, params, dref, delta)) return false;
  contactRow(delta, c.bary, out);
  contactParticles(c, out.index);
  return true;
}

bool CollisionConstraints::row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const {
  (void)w;
  const Contact& c = contacts_[static_cast<size_t>(r)];
  if (response_.mode == CollisionMode::Position) return positionRow(c, p, parameters(), false, out);
  const ContactParameters spring{gap_, proximity_, friction_, CollisionTarget::Spring};
  return positionRow(c, p, spring, true, out);
}

int CollisionConstraints::projectPositions(Points& p, const Eigen::VectorXd& w) {
  const ContactParameters prm = parameters();
  ConstraintRow r;
  int corrected = 0;
  for (const Contact& c : contacts_)
    if (positionRow(c, p, prm, false, r) && applyPbdRow(r, w, p)) ++corrected;
  return corrected;
}

void CollisionConstraints::correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (response_.mode != CollisionMode::Acceleration || response_.resolution != CollisionResolution::Sequential) return;
  const ContactParameters prm = parameters();
  for (const Contact& c : contacts_) {
    Eigen::Vector3d delta;
    if (contactAccelerationChange(relative(c, x), relative(c, v), c.normal, prm, dref_[static_cast<size_t>(c.vertex)],
                                  h, delta))
      apply(c, delta, w, v);
  }
}

void CollisionConstraints::correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (response_.mode != CollisionMode::Velocity || response_.resolution != CollisionResolution::Sequential) return;
  const ContactParameters prm = parameters();
  for (const Contact& c : contacts_) {
    Eigen::Vector3d delta;
    if (contactVelocityChange(relative(c, x), relative(c, v), c.normal, prm, dref_[static_cast<size_t>(c.vertex)], h,
                              delta))
      apply(c, delta, w, v);
  }
}

void CollisionConstraints::appendRows(CollisionMode mode, const Points& x, const Points& v, double h,
                                      std::vector<ContactRow>& rows) const {
  const ContactParameters prm = parameters();
  for (const Contact& c : contacts_) {
    const double dref = dref_[static_cast<size_t>(c.vertex)];
    const Eigen::Vector3d pc = relative(c, x);
    ContactRow r;
    bool any = false;
    switch (mode) {
      case CollisionMode::Position:
        any = contactPositionChange(pc, c.pc0, c.normal, prm, dref, r.change);
        break;
      case CollisionMode::Velocity:
        any = contactVelocityChange(pc, relative(c, v), c.normal, prm, dref, h, r.change);
        break;
      case CollisionMode::Acceleration:
        any = contactAccelerationChange(pc, relative(c, v), c.normal, prm, dref, h, r.change);
        break;
    }
    if (!any) continue;
    contactParticles(c, r.index);
    r.weight[0] = -1.0;
    for (int i = 0; i < 3; ++i) r.weight[i + 1] = c.bary[i];
    r.normal = c.normal;
    r.unilateral = response_.target != CollisionTarget::Reference;
    rows.push_back(r);
  }
}

double CollisionConstraints::maxPenetration(const Points& p) const {
  double worst = 0;
  for (const Contact& c : contacts_) worst = std::max(worst, relative(c, p).dot(c.normal));
  return worst;
}

GlobalCollisionResolution::GlobalCollisionResolution(CollisionMode mode, const GlobalContactOptions& opts)
    : mode_(mode), opts_(opts) {
  if (opts.maxIterations < 1)
    throw ParameterError("global collision cg iterations", std::to_string(opts.maxIterations), "must be at least 1");
  if (!(opts.tolerance > 0) || !std::isfinite(opts.tolerance))
    throw ParameterError("global collision cg tolerance", std::to_string(opts.tolerance), "must be positive");
  if (!(opts.regularization >= 0) || !std::isfinite(opts.regularization))
    throw ParameterError("global collision regularization", std::to_string(opts.regularization), "must be >= 0");
}

void GlobalCollisionResolution::add(CollisionConstraints* set) {
  MSK_ASSERT(set != nullptr, "global collision resolution: null member");
  if (set->response().resolution != CollisionResolution::Global)
    throw ParameterError("collision resolution", collisionResolutionName(set->response().resolution),
                         "a member of a global resolution must be built with resolution \"global\"");
  if (set->response().mode != mode_)
    throw ParameterError("collision mode", collisionModeName(set->response().mode),
                         std::string("differs from the global resolution's mode \"") + collisionModeName(mode_) + "\"");
  members_.push_back(set);
}

void GlobalCollisionResolution::solve(CollisionMode mode, const Points& x, const Points& v, double h,
                                      const Eigen::VectorXd& w, Points& q) {
  // Position mode: a few passes, contacts that the previous solve left short (or newly violated) solved again together
  // (the velocity and acceleration changes are not idempotent: one solve).
  report_ = GlobalContactReport{};
  const int passes = mode == CollisionMode::Position ? kPasses : 1;
  for (int pass = 0; pass < passes; ++pass) {
    rows_.clear();
    for (const CollisionConstraints* m : members_) m->appendRows(mode, x, v, h, rows_);
    if (rows_.empty()) break;
    const GlobalContactReport r = solveContactsGlobal(rows_, w, q, opts_);
    if (pass == 0)
      report_ = r;
    else {
      report_.iterations += r.iterations;
      report_.dropped += r.dropped;
      report_.residual = r.residual;
    }
  }
}

void GlobalCollisionResolution::project(Points& p, const Eigen::VectorXd& w) {
  if (mode_ == CollisionMode::Position)
    projectPositions(p, w);
  else
    for (CollisionConstraints* m : members_) m->project(p, w);
}

void GlobalCollisionResolution::projectPositions(Points& p, const Eigen::VectorXd& w) {
  solve(CollisionMode::Position, p, p, 1.0, w, p);
}

void GlobalCollisionResolution::correctBeforePrediction(const Points& x, Points& v, const Eigen::VectorXd& w,
                                                        double h) {
  if (mode_ == CollisionMode::Acceleration) solve(mode_, x, v, h, w, v);
}

void GlobalCollisionResolution::correctVelocities(const Points& x, Points& v, const Eigen::VectorXd& w, double h) {
  if (mode_ == CollisionMode::Velocity) solve(mode_, x, v, h, w, v);
}

}  // namespace msk
