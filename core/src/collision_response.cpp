#include "msk/core/collision_response.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>

namespace msk {

const char* collisionModeName(CollisionMode m) {
  switch (m) {
    case CollisionMode::Position:
      return "position";
    case CollisionMode::Velocity:
      return "velocity";
    case CollisionMode::Acceleration:
      return "acceleration";
  }
  return "unknown";
}

const char* collisionTargetName(CollisionTarget t) {
  switch (t) {
    case CollisionTarget::Spring:
      return "spring";
    case CollisionTarget::Reaction:
      return "reaction";
    case CollisionTarget::Reference:
      return "reference";
  }
  return "unknown";
}

const char* collisionResolutionName(CollisionResolution r) {
  switch (r) {
    case CollisionResolution::Sequential:
      return "sequential";
    case CollisionResolution::Global:
      return "global";
  }
  return "unknown";
}

// ------------------------------------------------------------------------------------------------ kernels

double proximityFactor(double pcn, double gap, double proximity) {
  return std::clamp(1.0 + (pcn + gap) / proximity, 0.0, 1.0);
}

Eigen::Vector3d contactPositionTarget(const Eigen::Vector3d& pc, const Eigen::Vector3d& n, const ContactParameters& c,
                                      double dref) {
  const double pcn = pc.dot(n);
  const Eigen::Vector3d tangential = pc - pcn * n;
  const double normal = c.target == CollisionTarget::Reference ? dref : -c.gap;
  return (1.0 - c.friction) * tangential + normal * n;
}

namespace {

/// Within the gap (λ = 1 and Pc·n + g > 0, the condition of the seed's position correction).
bool withinGap(double pcn, const ContactParameters& c) { return pcn + c.gap > 0; }

/// Reaction of Table 4.23 applied to a relative motion `u` (a velocity, or a displacement over a step) at proximity
/// factor λ: an approach (u·n > 0) keeps (1 − λ) of its normal part, the tangential part keeps (1 − λμ).
Eigen::Vector3d reaction(const Eigen::Vector3d& u, const Eigen::Vector3d& n, double lambda, double friction) {
  const double un = u.dot(n);
  const Eigen::Vector3d ut = u - un * n;
  return ((un > 0 ? 1.0 - lambda : 1.0) * un) * n + (1.0 - lambda * friction) * ut;
}

bool nonZeroFinite(const Eigen::Vector3d& d) { return d.allFinite() && d.squaredNorm() > 0; }

}  // namespace

bool contactPositionChange(const Eigen::Vector3d& pc, const Eigen::Vector3d& pc0, const Eigen::Vector3d& n,
                           const ContactParameters& c, double dref, Eigen::Vector3d& delta) {
  const double pcn = pc.dot(n);
  Eigen::Vector3d d;
  if (c.target == CollisionTarget::Reference) {
    if (!(proximityFactor(pcn, c.gap, c.proximity) > 0) || !std::isfinite(dref)) return false;
    d = contactPositionTarget(pc, n, c, dref) - pc;
  } else if (withinGap(pcn, c)) {
    ContactParameters spring = c;
    spring.target = CollisionTarget::Spring;
    d = contactPositionTarget(pc, n, spring, 0.0) - pc;
  } else if (c.target == CollisionTarget::Reaction) {
    const double lambda0 = proximityFactor(pc0.dot(n), c.gap, c.proximity);
    if (!(lambda0 > 0)) return false;
    const Eigen::Vector3d moved = pc - pc0;  // this step's relative displacement D
    d = reaction(moved, n, lambda0, c.friction) - moved;
  } else {
    return false;
  }
  if (!nonZeroFinite(d)) return false;
  delta = d;
  return true;
}

bool contactVelocityChange(const Eigen::Vector3d& pc, const Eigen::Vector3d& vc, const Eigen::Vector3d& n,
                           const ContactParameters& c, double dref, double h, Eigen::Vector3d& delta) {
  if (!(h > 0)) return false;
  const double pcn = pc.dot(n);
  const double lambda = proximityFactor(pcn, c.gap, c.proximity);
  Eigen::Vector3d wanted;
  if (c.target == CollisionTarget::Reference) {
    if (!(lambda > 0) || !std::isfinite(dref)) return false;
    wanted = (contactPositionTarget(pc, n, c, dref) - pc) / h;
  } else if (withinGap(pcn, c)) {
    ContactParameters spring = c;
    spring.target = CollisionTarget::Spring;
    wanted = (contactPositionTarget(pc, n, spring, 0.0) - pc) / h;
  } else if (c.target == CollisionTarget::Reaction && lambda > 0) {
    wanted = reaction(vc, n, lambda, c.friction);
  } else {
    return false;
  }
  const Eigen::Vector3d d = wanted - vc;
  if (!nonZeroFinite(d)) return false;
  delta = d;
  return true;
}

bool contactAccelerationChange(const Eigen::Vector3d& pc, const Eigen::Vector3d& vc, const Eigen::Vector3d& n,
                               const ContactParameters& c, double dref, double h, Eigen::Vector3d& delta) {
  if (!(h > 0)) return false;
  const double pcn = pc.dot(n);
  const double lambda = proximityFactor(pcn, c.gap, c.proximity);
  Eigen::Vector3d d;  // h·Ãc
  if (c.target == CollisionTarget::Reference) {
    if (!(lambda > 0) || !std::isfinite(dref)) return false;
    d = (contactPositionTarget(pc, n, c, dref) - pc) / h;
  } else if (withinGap(pcn, c)) {
    ContactParameters spring = c;
    spring.target = CollisionTarget::Spring;
    d = (contactPositionTarget(pc, n, spring, 0.0) - pc) / h;
  } else if (c.target == CollisionTarget::Reaction && lambda > 0) {
    d = reaction(vc, n, lambda, c.friction) - vc;
  } else {
    return false;
  }
  if (!nonZeroFinite(d)) return false;
  delta = d;
  return true;
}

// ------------------------------------------------------------------------------------------------ global

namespace {

/// The scalar system of a global contact solve: each contact in use (finite change, a free particle) gives a row
/// along its normal, and one along its wanted tangential change when there is one (friction, reaction); particles get
/// compact local indices. H_kl = Σ_{i∈k∩l} a_ik w_i a_il (d_k·d_l), regularised by ε on the diagonal.
class ContactSystem {
 public:
  ContactSystem(const std::vector<ContactRow>& rows, const Eigen::VectorXd& w, double regularization) : rows_(rows) {
    std::unordered_map<int, int> local;
    for (size_t k = 0; k < rows.size(); ++k) {
      const ContactRow& r = rows[k];
      double d = 0;
      for (int j = 0; j < 4; ++j) d += r.weight[j] * r.weight[j] * w[r.index[j]];
      const double nn = r.normal.norm();
      if (!(d > 0) || !std::isfinite(d) || !r.change.allFinite() || !(nn > 0) || !std::isfinite(nn)) continue;
      std::array<int, 4> l;
      for (int j = 0; j < 4; ++j) {
        const auto [it, fresh] = local.emplace(r.index[j], static_cast<int>(particle_.size()));
        if (fresh) particle_.push_back(r.index[j]);
        l[static_cast<size_t>(j)] = it->second;
      }
      ++contacts_;
      const Eigen::Vector3d n = r.normal / nn;
      sc_.push_back({static_cast<int>(k), n, r.change.dot(n), d, r.unilateral, l});
      const Eigen::Vector3d t = r.change - r.change.dot(n) * n;
      const double tl = t.norm();
      if (tl > 1e-12 * (1.0 + r.change.norm())) sc_.push_back({static_cast<int>(k), t / tl, tl, d, false, l});
    }
    K_ = static_cast<int>(sc_.size());
    if (K_ == 0) return;
    double meanDiag = 0;
    for (const Scalar& r : sc_) meanDiag += r.diag;
    meanDiag /= K_;
    eps_ = std::max(0.0, regularization) * meanDiag;  // bounds dependent contacts' multipliers
    wl_.resize(static_cast<Eigen::Index>(particle_.size()));
    for (size_t i = 0; i < particle_.size(); ++i) wl_[static_cast<Eigen::Index>(i)] = w[particle_[i]];
    active_.assign(static_cast<size_t>(K_), 1);
    acc_.resize(particle_.size());
  }

  int rows() const { return K_; }
  int contacts() const { return contacts_; }

  /// out = (H + ε) y over the active rows; `decouple`: inactive rows get out = y (identity, zero right-hand side: they
  /// stay at W = 0), else (H y)_k for every row, y = 0 on inactive ones.
  void applyH(const Eigen::VectorXd& y, Eigen::VectorXd& out, bool decouple) {
    std::fill(acc_.begin(), acc_.end(), Eigen::Vector3d::Zero());
    for (int k = 0; k < K_; ++k) {
      if (!active_[static_cast<size_t>(k)]) continue;
      const Scalar& s = sc_[static_cast<size_t>(k)];
      const ContactRow& r = rows_[static_cast<size_t>(s.contact)];
      for (int j = 0; j < 4; ++j)
        acc_[static_cast<size_t>(s.loc[static_cast<size_t>(j)])] += (r.weight[j] * y[k]) * s.dir;
    }
    out.resize(K_);
    for (int k = 0; k < K_; ++k) {
      const bool on = active_[static_cast<size_t>(k)];
      if (!on && decouple) {
        out[k] = y[k];
        continue;
      }
      const Scalar& s = sc_[static_cast<size_t>(k)];
      const ContactRow& r = rows_[static_cast<size_t>(s.contact)];
      double v = on ? eps_ * y[k] : 0.0;
      for (int j = 0; j < 4; ++j) {
        const int li = s.loc[static_cast<size_t>(j)];
        v += r.weight[j] * wl_[li] * acc_[static_cast<size_t>(li)].dot(s.dir);
      }
      out[k] = v;
    }
  }

  /// One Jacobi-preconditioned conjugate-gradient solve of (H + ε) W = Y from the last round's W (0 on the rows let
  /// go); `rzRef` is the first round's initial residual (the scale of the tolerance). Returns the relative residual.
  double solve(Eigen::VectorXd& F, int round, double& rzRef, const GlobalContactOptions& opts, int& iterations) {
    Eigen::VectorXd Y(K_), r, z(K_), d, hd;
    for (int k = 0; k < K_; ++k) {
      Y[k] = active_[static_cast<size_t>(k)] ? sc_[static_cast<size_t>(k)].y : 0.0;
      if (!active_[static_cast<size_t>(k)]) F[k] = 0;
    }
    if (round == 0) {
      r = Y;
    } else {
      applyH(F, hd, true);
      r = Y - hd;
    }
    auto precondition = [&] {
      for (int k = 0; k < K_; ++k)
        z[k] = active_[static_cast<size_t>(k)] ? r[k] / (sc_[static_cast<size_t>(k)].diag + eps_) : r[k];
    };
    precondition();
    d = z;
    double rz = r.dot(z);
    if (round == 0) rzRef = rz;
    const double rz0 = rzRef;
    if (!(rz > opts.tolerance * opts.tolerance * rz0 && rz0 > 0 && std::isfinite(rz0))) return 0;
    int it = 0;
    for (; it < opts.maxIterations; ++it) {
      applyH(d, hd, true);
      const double dhd = d.dot(hd);
      if (!(dhd > 0) || !std::isfinite(dhd)) break;
      const double a = rz / dhd;
      F += a * d;
      r -= a * hd;
      precondition();
      const double rzNew = r.dot(z);
      const double beta = rzNew / rz;
      rz = rzNew;
      if (!(rzNew > opts.tolerance * opts.tolerance * rz0)) {
        ++it;
        break;
      }
      d = z + beta * d;
    }
    iterations += it;
    return std::sqrt(std::max(rz, 0.0) / rz0);
  }

  /// The active set of the unilateral (normal) rows after a solve: one whose multiplier pulls the partners together
  /// (W_k > 0 along n with y_k < 0 wanted) is let go; one let go that the others leave short of its wanted change is
  /// taken back. Returns how many changed; counts the rows let go in `dropped`.
  int updateActiveSet(const Eigen::VectorXd& F, int& dropped) {
    Eigen::VectorXd achieved;
    applyH(F, achieved, false);
    int changed = 0;
    for (int k = 0; k < K_; ++k) {
      const Scalar& s = sc_[static_cast<size_t>(k)];
      if (!s.unilateral) continue;
      if (active_[static_cast<size_t>(k)] && F[k] > 0) {
        active_[static_cast<size_t>(k)] = 0;
        ++dropped;
        ++changed;
      } else if (!active_[static_cast<size_t>(k)] && s.y < 0 && achieved[k] > s.y * (1.0 - 1e-9)) {
        active_[static_cast<size_t>(k)] = 1;
        ++changed;
      }
    }
    return changed;
  }

  /// ΔX_i = w_i Σ_k a_ik d_k W_k added to `q`.
  void apply(const Eigen::VectorXd& F, const Eigen::VectorXd& w, Points& q) const {
    for (int k = 0; k < K_; ++k) {
      if (!active_[static_cast<size_t>(k)] || F[k] == 0) continue;
      const Scalar& s = sc_[static_cast<size_t>(k)];
      const ContactRow& r = rows_[static_cast<size_t>(s.contact)];
      for (int j = 0; j < 4; ++j) q.row(r.index[j]) += (w[r.index[j]] * r.weight[j] * F[k]) * s.dir.transpose();
    }
  }

 private:
  struct Scalar {
    int contact;             // index into rows
    Eigen::Vector3d dir;     // unit direction d
    double y;                // wanted change along d
    double diag;             // H_kk = Σ a_j² w_j
    bool unilateral;         // may only push (y along −n)
    std::array<int, 4> loc;  // local particle indices
  };
  const std::vector<ContactRow>& rows_;
  std::vector<Scalar> sc_;
  std::vector<int> particle_;
  int contacts_ = 0, K_ = 0;
  double eps_ = 0;
  Eigen::VectorXd wl_;
  std::vector<char> active_;
  std::vector<Eigen::Vector3d> acc_;
};

}  // namespace

GlobalContactReport solveContactsGlobal(const std::vector<ContactRow>& rows, const Eigen::VectorXd& w, Points& q,
                                        const GlobalContactOptions& opts) {
  GlobalContactReport rep;
  ContactSystem system(rows, w, opts.regularization);
  rep.rows = system.contacts();
  if (system.rows() == 0) return rep;
  Eigen::VectorXd F = Eigen::VectorXd::Zero(system.rows());
  const int rounds = std::max(1, opts.activeSetRounds);
  double rzRef = 0;
  for (int round = 0; round < rounds; ++round) {
    rep.residual = system.solve(F, round, rzRef, opts, rep.iterations);
    if (round + 1 >= rounds) break;  // the last solve stands
    if (system.updateActiveSet(F, rep.dropped) == 0) break;
  }
  system.apply(F, w, q);
  return rep;
}

}  // namespace msk
