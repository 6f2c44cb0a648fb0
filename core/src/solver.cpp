#include "msk/core/solver.h"

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>
#include <unordered_map>

#include "msk/core/error.h"
#include "msk/core/graph_colouring.h"
#include "msk/core/simplex_batch.h"
#include "msk/core/simplex_internal_constraint.h"
#include "rigid_motion_damping.h"
#include "worker_pool.h"

namespace msk {

// ------------------------------------------------------------------------------------------------ names, options

std::string schemeName(Scheme scheme) {
  switch (scheme) {
    case Scheme::GaussSeidel:
      return "gauss-seidel";
    case Scheme::ColouredGaussSeidel:
      return "coloured-gauss-seidel";
    case Scheme::Jacobi:
      return "jacobi";
    case Scheme::Xpbd:
      return "xpbd";
    case Scheme::Explicit:
      return "explicit";
    case Scheme::Implicit:
      return "implicit";
  }
  return "unknown";
}

std::vector<Scheme> allSchemes() {
  return {Scheme::GaussSeidel, Scheme::ColouredGaussSeidel, Scheme::Jacobi, Scheme::Xpbd, Scheme::Explicit,
          Scheme::Implicit};
}

Scheme parseScheme(const std::string& name, const std::string& option) {
  for (Scheme s : allSchemes())
    if (name == schemeName(s)) return s;
  if (name == "colored-gauss-seidel") return Scheme::ColouredGaussSeidel;
  throw ParameterError(option, name, "must be gauss-seidel, coloured-gauss-seidel, jacobi, xpbd, explicit or implicit");
}

void validateSolverOptions(const SolverOptions& o) {
  if (!(o.dt > 0) || !std::isfinite(o.dt)) throw ParameterError("dt", std::to_string(o.dt), "must be positive");
  if (o.substeps < 1) throw ParameterError("substeps", std::to_string(o.substeps), "must be at least 1");
  if (o.iterations < 1) throw ParameterError("iterations", std::to_string(o.iterations), "must be at least 1");
  checkUnitInterval("damping", o.damping);
  checkUnitInterval("drag", o.drag);
  checkUnitInterval("anisotropy", o.anisotropy);
  if (!(o.omega > 0 && o.omega < 2)) throw ParameterError("omega", std::to_string(o.omega), "must be in (0, 2)");
  if (!(o.stiffness >= 0)) throw ParameterError("stiffness", std::to_string(o.stiffness), "must be >= 0");
  if (!(o.forceDamping >= 0) || !std::isfinite(o.forceDamping))
    throw ParameterError("force damping", std::to_string(o.forceDamping), "must be >= 0");
  if (o.cgIterations < 1) throw ParameterError("cg iterations", std::to_string(o.cgIterations), "must be at least 1");
  if (!(o.cgTolerance > 0) || !std::isfinite(o.cgTolerance))
    throw ParameterError("cg tolerance", std::to_string(o.cgTolerance), "must be positive");
  if (o.threads < 0) throw ParameterError("threads", std::to_string(o.threads), "must be >= 0");
}

// ------------------------------------------------------------------------------------------------ state

namespace {

using Clock = std::chrono::steady_clock;

/// What a solver keeps per constraint set between steps.
struct SetCache {
  std::uint64_t uid = 0, layout = 0;
  int rows = -1, first = -1;
  Colouring colouring;
  std::vector<ConstraintRow> row;                  ///< rows of the current pass (Jacobi, force-based)
  std::vector<char> active;                        ///< row r evaluated and in use
  std::vector<Eigen::Vector3d> lambda;             ///< XPBD multipliers; Jacobi Δλ
  std::vector<double> alpha, beta;                 ///< force-based: stiffness α and damping β of each row
  std::vector<Eigen::Vector3d> dir;                ///< force-based: unit force direction u of each row
  Points diff;                                     ///< sets without rows: correction of a projection on a copy
  const SimplexInternalBatch* sharesOf = nullptr;  ///< batch whose equalShares() `equalShares` holds (null: none)
  std::uint64_t sharesLayout = 0;                  ///< ... at this row layout
  bool equalShares = false;
};

}  // namespace

struct Solver::Impl {
  explicit Impl(const SolverOptions& o)
      : opts(o), pool(o.threads > 0 ? o.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()))) {}

  SolverOptions opts;
  WorkerPool pool;
  Points x, v, p, force, scratch;
  Points x0, v0;             ///< state before the step, restored if it fails (buffers kept from step to step)
  Points v1;                 ///< the next step's v0, copied by the current step's last check of v
  bool backupValid = false;  ///< v0 holds the current v (set by a completed step, cleared by reset() and failures)
  Eigen::VectorXd w, fallbackK;
  ParticleWeights weights;  ///< masses and free flags from w (set by reset())
  Eigen::VectorXi counts;
  SimplexInternalBatch* resident = nullptr;  ///< batch whose packed copy is newer than p
  int steps = 0, cgIterations = 0;
  double cgResidual = 0;
  std::map<std::string, double> seconds;
  std::unordered_map<std::uint64_t, SetCache> caches;

  SetCache& cacheFor(ConstraintSet& s) {
    SetCache& c = caches[s.uid()];
    const int rows = s.rowCount();
    if (c.uid != s.uid() || c.rows != rows || c.first != s.firstParticle() || c.layout != s.rowLayout()) {
      c.uid = s.uid();
      c.rows = rows;
      c.first = s.firstParticle();
      c.layout = s.rowLayout();
      c.colouring = colourConstraints(rows, kMaxRowParticles, [&s](int r, int* out) { return s.rowParticles(r, out); });
      const int n = static_cast<int>(x.rows());
      for (int i = 0; i < rows; ++i) {  // rows must stay inside the system
        int idx[kMaxRowParticles];
        const int k = s.rowParticles(i, idx);
        for (int j = 0; j < k; ++j)
          MSK_ASSERT(idx[j] >= 0 && idx[j] < n, s.name() + ": row particle outside the system");
      }
    }
    const size_t rows_ = static_cast<size_t>(std::max(rows, 0));
    if (c.row.size() != rows_) {
      c.row.assign(rows_, ConstraintRow{});
      c.active.assign(rows_, 0);
      c.lambda.assign(rows_, Eigen::Vector3d::Zero());
      c.alpha.assign(rows_, 0.0);
      c.beta.assign(rows_, 0.0);
      c.dir.assign(rows_, Eigen::Vector3d::Zero());
    }
    return c;
  }

  /// Calls f(r) for every row of `c`, colour by colour; rows of one colour run in parallel.
  template <class F>
  void forRows(const SetCache& c, F&& f) {
    for (int k = 0; k < c.colouring.colours(); ++k) {
      const int begin = c.colouring.start[static_cast<size_t>(k)];
      const int size = c.colouring.start[static_cast<size_t>(k) + 1] - begin;
      pool.run(size, [&](int b, int e) {
        for (int i = b; i < e; ++i) f(c.colouring.order[static_cast<size_t>(begin + i)]);
      });
    }
  }

  void addSeconds(const ConstraintSet& s, Clock::time_point t0) {
    seconds[s.name()] += std::chrono::duration<double>(Clock::now() - t0).count();
  }

  /// The batch kernel of `s` where it has one and SolverOptions::batchKernels allows it (the same corrections as its
  /// rows, several rows at a time), else nullptr.
  SimplexInternalBatch* batchOf(ConstraintSet& s) const {
    if (!opts.batchKernels) return nullptr;
    auto* internal = dynamic_cast<SimplexInternalConstraints*>(&s);
    return internal ? internal->batch() : nullptr;
  }

  /// b.equalShares(w) of the batch of set `s`, kept until the inverse masses change (reset() clears the caches) or
  /// the set's rows do (a pass over w per Jacobi iteration otherwise).
  bool equalSharesOf(const ConstraintSet& s, const SimplexInternalBatch& b) {
    SetCache& c = caches[s.uid()];
    if (c.sharesOf != &b || c.sharesLayout != s.rowLayout()) {
      c.sharesOf = &b;
      c.sharesLayout = s.rowLayout();
      c.equalShares = b.equalShares(w);
    }
    return c.equalShares;
  }

  /// Writes the packed copy of the batch swept last (colouredSweep(), or Jacobi of a set alone with equal shares)
  /// back into p (its positions are newer than p's until then); every other reader of p calls this first.
  void storeResident() {
    if (!resident) return;
    SimplexInternalBatch* b = resident;
    pool.run(b->size(), [&](int lo, int hi) { b->storeRange(p, lo, hi); });
    resident = nullptr;
  }

  void applyRow(const ConstraintRow& r, const Eigen::Vector3d& dl, double scale, Points& q) const {
    for (int j = 0; j < r.count; ++j) q.row(r.index[j]) += ((scale * w[r.index[j]] * r.react[j]) * dl).transpose();
  }

  // -------------------------------------------------------------------------------------------- position-based

  /// One sweep of set `s` over p in coloured order: PBD (xpbdStep ≤ 0) or XPBD with substep h = xpbdStep.
  void colouredSweep(ConstraintSet& s, double xpbdStep) {
    if (SimplexInternalBatch* b = xpbdStep <= 0 ? batchOf(s) : nullptr) {
      if (resident != b) {  // consecutive sweeps of one batch keep its packed copy (storeResident() writes it back)
        storeResident();
        pool.run(b->size(), [&](int lo, int hi) { b->loadRange(p, w, lo, hi); });
        resident = b;
      }
      if (pool.size() == 1) {  // one thread: the colours as a cache-friendly wavefront (bitwise the same)
        b->projectColours();
        return;
      }
      for (int k = 0; k < b->colours(); ++k) {
        const int begin = b->colourBegin(k);
        pool.run(b->colourBegin(k + 1) - begin, [&](int lo, int hi) { b->projectRange(begin + lo, begin + hi); });
      }
      return;
    }
    storeResident();
    SetCache& c = cacheFor(s);
    s.beginRows(p, w);
    const double k = opts.stiffness;
    forRows(c, [&](int r) {
      ConstraintRow row;
      if (!s.row(r, p, w, row)) return;
      if (xpbdStep <= 0) {
        applyPbdRow(row, w, p);
        return;
      }
      const double W = rowInverseMass(row, w);
      if (!(W > 0) || !std::isfinite(W)) return;
      // XPBD (Macklin et al. 2016, eq. 18): Δλ = (−C − α̃ λ) / (W + α̃), α̃ = 1 / (k γ h²); a hard row has α̃ = 0.
      double kr = row.compliant ? k * row.gamma : std::numeric_limits<double>::infinity();  // row stiffness
      if (row.compliant && opts.xpbdStiffness == XpbdStiffness::MassRelative) kr /= W * opts.dt * opts.dt;
      if (!(kr > 0)) return;
      const double alphaT = std::isinf(kr) ? 0.0 : 1.0 / (kr * xpbdStep * xpbdStep);
      if (!std::isfinite(alphaT)) return;
      Eigen::Vector3d& lam = c.lambda[static_cast<size_t>(r)];
      const Eigen::Vector3d dl = (-row.c - alphaT * lam) / (W + alphaT);
      lam += dl;
      if (dl.allFinite()) applyRow(row, dl, 1.0, p);
    });
  }

  /// One weighted-sum Jacobi iteration over every set: all corrections from the same positions, each row's
  /// correction scaled by ω / (largest number of corrections at one of its particles), so every row keeps its
  /// momentum balance and the sum at any particle never exceeds ω times the mean correction.
  void jacobiIteration(const std::vector<ConstraintSet*>& sets) {
    const int n = static_cast<int>(p.rows());
    const bool loneBatch = sets.size() == 1 && batchOf(*sets[0]);  // zeroes the counts only if it needs them
    if (!loneBatch) counts.setZero(n);
    SimplexInternalBatch* equalShares = nullptr;  // the batch applied with equal shares ω/4 (no counts)
    SimplexInternalBatch* fused = nullptr;        // ... already applied (one thread: computed and applied in one pass)
    if (sets.size() != 1) storeResident();        // only a set iterated alone keeps its packed copy between iterations
    for (ConstraintSet* s : sets) {
      const auto t0 = Clock::now();
      if (SimplexInternalBatch* b = batchOf(*s)) {
        if (resident != b) pool.run(b->size(), [&](int lo, int hi) { b->loadRange(p, w, lo, hi); });
        std::atomic<int> skipped{0};
        const bool alone = sets.size() == 1 && equalSharesOf(*s, *b);
        if (alone && pool.size() == 1) {
          skipped = b->jacobiEqualSharesPacked(opts.omega);  // bitwise the same as compute + applyEqualSharesPacked
          if (skipped == 0) fused = b;
        } else {
          pool.run(b->size(), [&](int lo, int hi) { skipped += b->computeRange(lo, hi); });
        }
        // Counted alone with every row kept on a closed mesh of free particles: every share is ω/4 (no counts).
        if (alone && skipped == 0) {
          equalShares = b;
        } else {
          if (loneBatch) counts.setZero(n);
          b->addCounts(w, counts);
        }
      } else if (s->rowCount() > 0) {
        SetCache& c = cacheFor(*s);
        s->beginRows(p, w);
        forRows(c, [&](int r) {
          const size_t i = static_cast<size_t>(r);
          c.active[i] = 0;
          ConstraintRow& row = c.row[i];
          if (!s->row(r, p, w, row)) return;
          const double W = rowInverseMass(row, w);
          if (!(W > 0) || !std::isfinite(W)) return;
          c.lambda[i] = (-row.gamma / W) * row.c;
          if (c.lambda[i].allFinite()) c.active[i] = 1;
        });
        for (int r = 0; r < c.rows; ++r)
          if (c.active[static_cast<size_t>(r)]) {
            const ConstraintRow& row = c.row[static_cast<size_t>(r)];
            for (int j = 0; j < row.count; ++j)
              if (w[row.index[j]] > 0) ++counts[row.index[j]];
          }
      } else if (opts.rowless == RowlessSets::Blend) {
        SetCache& c = caches[s->uid()];
        c.diff = p;
        s->project(c.diff, w);
        c.diff -= p;
        for (int i = 0; i < n; ++i)
          if (c.diff.row(i).squaredNorm() > 0) ++counts[i];
      }
      addSeconds(*s, t0);
    }
    for (ConstraintSet* s : sets) {
      const auto t0 = Clock::now();
      if (SimplexInternalBatch* b = batchOf(*s)) {
        if (b == equalShares) {  // alone: into its packed copy, kept for the next iteration (storeResident())
          if (b != fused) pool.run(b->size(), [&](int lo, int hi) { b->applyEqualSharesPacked(opts.omega, lo, hi); });
          resident = b;
        } else {
          storeResident();  // p current before the corrections are added to it
          pool.run(b->size(), [&](int lo, int hi) { b->scaleRange(counts, opts.omega, lo, hi); });
          pool.run(b->size(), [&](int lo, int hi) { b->applyRange(p, lo, hi); });
        }
      } else if (s->rowCount() > 0) {
        SetCache& c = cacheFor(*s);
        forRows(c, [&](int r) {
          const size_t i = static_cast<size_t>(r);
          if (!c.active[i]) return;
          const ConstraintRow& row = c.row[i];
          int most = 1;
          for (int j = 0; j < row.count; ++j) most = std::max(most, counts[row.index[j]]);
          applyRow(row, c.lambda[i], opts.omega / most, p);
        });
      } else if (opts.rowless == RowlessSets::Blend) {
        SetCache& c = caches[s->uid()];
        int most = 1;
        for (int i = 0; i < n; ++i)
          if (c.diff.row(i).squaredNorm() > 0) most = std::max(most, counts[i]);
        p += (opts.omega / most) * c.diff;
      }
      addSeconds(*s, t0);
    }
    if (opts.rowless == RowlessSets::Project) projectRowless(sets, p);
  }

  /// Projects the sets without rows on `q`, in order (RowlessSets::Project).
  void projectRowless(const std::vector<ConstraintSet*>& sets, Points& q) {
    for (ConstraintSet* s : sets) {
      if (s->rowCount() > 0) continue;
      const auto t0 = Clock::now();
      s->project(q, w);
      addSeconds(*s, t0);
    }
  }

  /// Force-based schemes with RowlessSets::Project: projects the sets without rows on x after a substep of length h
  /// and lets the velocities follow (v += Δx / h).
  void correctRowless(const std::vector<ConstraintSet*>& sets, double h) {
    if (opts.rowless != RowlessSets::Project) return;
    bool any = false;
    for (ConstraintSet* s : sets) any = any || s->rowCount() == 0;
    if (!any) return;
    scratch = x;
    projectRowless(sets, x);
    for (int i = 0; i < x.rows(); ++i)
      if (w[i] > 0) v.row(i) += (x.row(i) - scratch.row(i)) / h;
  }

  /// Velocity passes of the sets (collision response in acceleration mode): before the prediction of a substep.
  void beforePrediction(const std::vector<ConstraintSet*>& sets, double h) {
    for (ConstraintSet* s : sets) {
      const auto t0 = Clock::now();
      s->correctBeforePrediction(x, v, w, h);
      addSeconds(*s, t0);
    }
  }

  /// Velocity passes of the sets (collision response in velocity mode): after the velocity update of a substep.
  void velocityPass(const std::vector<ConstraintSet*>& sets, double h) {
    for (ConstraintSet* s : sets) {
      const auto t0 = Clock::now();
      s->correctVelocities(x, v, w, h);
      addSeconds(*s, t0);
    }
  }

  /// Predicts p = x + h v (x on fixed particles; no external forces: image forces enter as target constraints). The
  /// prediction is written over v, which the substep's velocity update overwrites anyway (one pass whose stores go to
  /// the lines it has just read), and then swapped into p; v is left holding p's former storage.
  void predict(double h) {
    for (int c = 0; c < 3; ++c) {
      const double* xc = x.col(c).data();
      double* vc = v.col(c).data();
      forLaneBlocks(static_cast<int>(x.rows()), [&](int i, auto k) {  // fixed: x + 0 v = x (v is finite)
        storeLanes(loadLanes(xc, i, k) + (h * weights.freeFlags(i, k)) * loadLanes(vc, i, k), vc, i, k);
      });
    }
    p.swap(v);
  }

  /// One position-based substep; `velocities`: run the sets' velocity passes at its end (the step's last substep
  /// runs them after the damping instead); without `update` it stops before the velocity update, leaving the new
  /// positions in p and x unchanged (step() updates the velocities in its closing pass).
  void positionSubstep(const std::vector<ConstraintSet*>& sets, double h, bool velocities, bool update = true) {
    beforePrediction(sets, h);
    predict(h);
    if (opts.scheme == Scheme::Xpbd)
      for (ConstraintSet* s : sets)
        if (s->rowCount() > 0)
          for (auto& l : cacheFor(*s).lambda) l.setZero();
    resident = nullptr;  // p was just predicted: no packed copy holds newer positions
    for (int it = 0; it < opts.iterations; ++it) {
      if (opts.scheme == Scheme::Jacobi) {
        jacobiIteration(sets);
        continue;
      }
      for (ConstraintSet* s : sets) {
        const auto t0 = Clock::now();
        if (opts.scheme == Scheme::GaussSeidel || s->rowCount() == 0) {
          storeResident();
          s->project(p, w);
        } else {
          colouredSweep(*s, opts.scheme == Scheme::Xpbd ? h : 0.0);
        }
        addSeconds(*s, t0);
      }
    }
    storeResident();
    if (!update) return;
    v = (p - x) / h;
    x.swap(p);
    if (velocities) velocityPass(sets, h);
  }

  // -------------------------------------------------------------------------------------------- force-based

  /// Forces at (x, v) into `force` (DESIGN-NOTES §2: Fj = −rj α C, α = γ m̄ dt⁻², plus projected damping
  /// −rj β (u·Ċ) u, Ċ = Σ gl vl); keeps each row's α, β, u for the implicit solve. Sets without rows give
  /// F = M Δp / dt² of a projection on a copy and add M dt⁻² to `fallbackK`.
  void evaluateForces(const std::vector<ConstraintSet*>& sets) {
    const int n = static_cast<int>(x.rows());
    const double dt2 = opts.dt * opts.dt;
    force.setZero(n, 3);
    fallbackK.setZero(n);
    for (ConstraintSet* s : sets) {
      const auto t0 = Clock::now();
      if (s->rowCount() > 0) {
        SetCache& c = cacheFor(*s);
        s->beginRows(x, w);
        forRows(c, [&](int r) {
          const size_t i = static_cast<size_t>(r);
          c.active[i] = 0;
          ConstraintRow& row = c.row[i];
          if (!s->row(r, x, w, row)) return;
          const double W = rowInverseMass(row, w);
          if (!(W > 0) || !std::isfinite(W) || !(row.gamma > 0)) return;
          const double alpha = row.gamma / (W * dt2);
          const double beta = 2.0 * opts.forceDamping * std::sqrt(alpha / W);
          const double len = row.c.norm();
          const Eigen::Vector3d u = len > 0 ? Eigen::Vector3d(row.c / len) : Eigen::Vector3d::Zero();
          Eigen::Vector3d cdot = Eigen::Vector3d::Zero();
          for (int j = 0; j < row.count; ++j) cdot += row.grad[j] * v.row(row.index[j]).transpose();
          const Eigen::Vector3d f = alpha * row.c + (beta * u.dot(cdot)) * u;
          if (!f.allFinite()) return;
          for (int j = 0; j < row.count; ++j) force.row(row.index[j]) -= (row.react[j] * f).transpose();
          c.alpha[i] = alpha;
          c.beta[i] = beta;
          c.dir[i] = u;
          c.active[i] = 1;
        });
      } else if (opts.rowless == RowlessSets::Blend) {
        scratch = x;
        s->project(scratch, w);
        for (int i = 0; i < n; ++i) {
          if (!(w[i] > 0)) continue;
          const Eigen::RowVector3d d = scratch.row(i) - x.row(i);
          if (d.squaredNorm() == 0) continue;  // a non-finite correction passes on, and step() reports it
          force.row(i) += d / (w[i] * dt2);
          fallbackK[i] += 1.0 / (w[i] * dt2);
        }
      }
      addSeconds(*s, t0);
    }
  }

  void explicitSubstep(const std::vector<ConstraintSet*>& sets, double h, bool velocities) {
    beforePrediction(sets, h);
    evaluateForces(sets);
    // Symplectic Euler: v ← v + h M⁻¹ F(x, v), x ← x + h v.
    for (int i = 0; i < x.rows(); ++i) {
      if (w[i] > 0) {
        v.row(i) += (h * w[i]) * force.row(i);
        x.row(i) += h * v.row(i);
      } else {
        v.row(i).setZero();
      }
    }
    correctRowless(sets, h);
    if (velocities) velocityPass(sets, h);
  }

  /// 3×3 block of one row in the implicit matrix: h β uuᵀ + h² α S, applied to s.
  Eigen::Vector3d rowBlock(const SetCache& c, size_t i, bool direction, const Eigen::Vector3d& s, double h) const {
    const Eigen::Vector3d& u = c.dir[i];
    const double us = u.dot(s);
    const double k = direction ? opts.anisotropy : 1.0;
    return (h * h * c.alpha[i]) * (k * s + ((1.0 - k) * us) * u) + (h * c.beta[i] * us) * u;
  }

  /// out = (M − h ∂F/∂v − h² ∂F/∂x) y on the free particles (fixed rows of out are zero).
  void applySystem(const std::vector<ConstraintSet*>& sets, const Points& y, Points& out, double h) {
    const int n = static_cast<int>(x.rows());
    out.resize(n, 3);
    for (int i = 0; i < n; ++i)
      out.row(i) =
          w[i] > 0 ? ((1.0 / w[i] + h * h * fallbackK[i]) * y.row(i)).eval() : Eigen::RowVector3d::Zero().eval();
    for (ConstraintSet* s : sets) {
      if (s->rowCount() <= 0) continue;
      const SetCache& c = cacheFor(*s);
      forRows(c, [&](int r) {
        const size_t i = static_cast<size_t>(r);
        if (!c.active[i]) return;
        const ConstraintRow& row = c.row[i];
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int j = 0; j < row.count; ++j) sum += row.grad[j] * y.row(row.index[j]).transpose();
        const Eigen::Vector3d t = rowBlock(c, i, row.direction, sum, h);
        for (int j = 0; j < row.count; ++j)
          if (w[row.index[j]] > 0) out.row(row.index[j]) += (row.grad[j] * t).transpose();
      });
    }
  }

  void implicitSubstep(const std::vector<ConstraintSet*>& sets, double h, bool velocities) {
    const int n = static_cast<int>(x.rows());
    beforePrediction(sets, h);
    evaluateForces(sets);
    const auto t0 = Clock::now();
    // Right-hand side h (F + h ∂F/∂x v): ∂F/∂x v = −Σ rows gj α S (Σ gl vl) − K_fallback v.
    Points rhs = h * force;
    for (int i = 0; i < n; ++i) rhs.row(i) -= (h * h * fallbackK[i]) * v.row(i);
    std::vector<Eigen::Matrix3d> blocks(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i)
      blocks[static_cast<size_t>(i)] =
          (w[i] > 0 ? 1.0 / w[i] + h * h * fallbackK[i] : 1.0) * Eigen::Matrix3d::Identity();
    for (ConstraintSet* s : sets) {
      if (s->rowCount() <= 0) continue;
      const SetCache& c = cacheFor(*s);
      forRows(c, [&](int r) {
        const size_t i = static_cast<size_t>(r);
        if (!c.active[i]) return;
        const ConstraintRow& row = c.row[i];
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int j = 0; j < row.count; ++j) sum += row.grad[j] * v.row(row.index[j]).transpose();
        const double k = row.direction ? opts.anisotropy : 1.0;
        const Eigen::Vector3d& u = c.dir[i];
        const Eigen::Vector3d kv = c.alpha[i] * (k * sum + ((1.0 - k) * u.dot(sum)) * u);
        const Eigen::Matrix3d b =
            (h * h * c.alpha[i]) * (k * Eigen::Matrix3d::Identity() + (1.0 - k) * u * u.transpose()) +
            (h * c.beta[i]) * u * u.transpose();
        for (int j = 0; j < row.count; ++j) {
          const int pj = row.index[j];
          if (!(w[pj] > 0)) continue;
          rhs.row(pj) -= (h * h * row.grad[j]) * kv.transpose();
          blocks[static_cast<size_t>(pj)] += (row.grad[j] * row.grad[j]) * b;
        }
      });
    }
    for (int i = 0; i < n; ++i) {
      if (!(w[i] > 0)) rhs.row(i).setZero();
      blocks[static_cast<size_t>(i)] = blocks[static_cast<size_t>(i)].inverse().eval();
    }
    auto precondition = [&](const Points& r, Points& z) {
      z.resize(n, 3);
      for (int i = 0; i < n; ++i) z.row(i) = (blocks[static_cast<size_t>(i)] * r.row(i).transpose()).transpose();
    };
    auto dot = [](const Points& a, const Points& b) { return (a.array() * b.array()).sum(); };
    // Preconditioned conjugate gradient from Δv = 0 (the matrix is symmetric positive definite on the free DOFs).
    Points dv = Points::Zero(n, 3), r = rhs, z, d, q;
    precondition(r, z);
    d = z;
    double rz = dot(r, z);
    const double rz0 = rz;
    double rel = 0;
    int it = 0;
    if (!std::isfinite(rz0)) dv.setConstant(std::numeric_limits<double>::quiet_NaN());  // reported by step()
    if (rz0 > 0 && std::isfinite(rz0)) {
      for (; it < opts.cgIterations; ++it) {
        applySystem(sets, d, q, h);
        const double dq = dot(d, q);
        if (!(dq > 0) || !std::isfinite(dq)) break;
        const double a = rz / dq;
        dv += a * d;
        r -= a * q;
        precondition(r, z);
        const double rzNew = dot(r, z);
        if (!(rzNew > opts.cgTolerance * opts.cgTolerance * rz0)) {
          rz = rzNew;
          ++it;
          break;
        }
        d = z + (rzNew / rz) * d;
        rz = rzNew;
      }
      rel = std::sqrt(std::max(rz, 0.0) / rz0);
    }
    cgIterations += it;
    cgResidual = std::max(cgResidual, rel);
    seconds["cg-solve"] += std::chrono::duration<double>(Clock::now() - t0).count();
    for (int i = 0; i < n; ++i) {
      if (w[i] > 0) {
        v.row(i) += dv.row(i);
        x.row(i) += h * v.row(i);
      } else {
        v.row(i).setZero();
      }
    }
    correctRowless(sets, h);
    if (velocities) velocityPass(sets, h);
  }
};

// ------------------------------------------------------------------------------------------------ Solver

Solver::Solver(const SolverOptions& opts) {
  validateSolverOptions(opts);
  impl_ = std::make_unique<Impl>(opts);
}

Solver::~Solver() = default;

void Solver::prepare(const Points& positions, const Eigen::VectorXd& inverseMass) {
  reset(positions, inverseMass);
  impl_->steps = 0;
  impl_->seconds.clear();
}

void Solver::reset(const Points& positions, const Eigen::VectorXd& inverseMass) {
  if (positions.rows() != inverseMass.size()) throw Error("solver: positions and inverse masses differ in size");
  if (!positions.allFinite()) throw Error("solver: non-finite initial positions");
  if ((inverseMass.array() < 0).any() || !inverseMass.allFinite())
    throw Error("solver: inverse masses must be finite and non-negative");
  impl_->x = positions;
  impl_->w = inverseMass;
  impl_->weights.assign(inverseMass);
  impl_->v = Points::Zero(positions.rows(), 3);
  impl_->backupValid = false;
  impl_->caches.clear();
}

double Solver::step(const std::vector<ConstraintSet*>& sets) {
  Impl& m = *impl_;
  const double h = m.opts.dt / m.opts.substeps;
  const int n = static_cast<int>(m.x.rows());
  // A single position-based substep leaves x untouched until the velocity update, which the closing pass below does:
  // the positions before the step stay in x (in p once the new ones are swapped in). Otherwise they are copied. The
  // velocities before the step are in v0, copied by the previous step's last check (or here after a reset or failure).
  const bool single = m.opts.substeps == 1 && m.opts.scheme != Scheme::Explicit && m.opts.scheme != Scheme::Implicit;
  if (!m.backupValid) m.v0 = m.v;  // same size from step to step: no allocation
  if (!single) m.x0 = m.x;
  m.backupValid = false;
  bool swapped = false;  // single: x holds the new positions, p the old ones
  auto restore = [&] {   // the state before the step
    if (!single)
      m.x.swap(m.x0);
    else if (swapped)
      m.x.swap(m.p);
    m.v.swap(m.v0);
  };
  auto fail = [&] {
    restore();
    throw Error("numerical failure: non-finite position after " + schemeName(m.opts.scheme) + " step " +
                std::to_string(m.steps + 1));
  };
  m.cgIterations = 0;
  m.cgResidual = 0;
  try {
    for (int s = 0; s < m.opts.substeps; ++s) {
      const bool velocities = s + 1 < m.opts.substeps;  // the last substep's velocity pass follows the damping
      switch (m.opts.scheme) {
        case Scheme::Explicit:
          m.explicitSubstep(sets, h, velocities);
          break;
        case Scheme::Implicit:
          m.implicitSubstep(sets, h, velocities);
          break;
        default:
          m.positionSubstep(sets, h, velocities, !single);
          break;
      }
    }
  } catch (...) {  // a set's exception: v may hold the prediction
    restore();
    throw;
  }
  // One pass: velocity update (single), finiteness of x and v, largest displacement, the damping's moments.
  const bool damp = m.opts.damping > 0 && n > 0;
  const ClosedStep closed = single ? closeStepAndMoments<true>(m.p, m.x, m.v, h, m.weights, m.w, damp)
                                   : closeStepAndMoments<false>(m.x, m.x0, m.v, h, m.weights, m.w, damp);
  if (!closed.finite) fail();
  if (single) {
    m.x.swap(m.p);
    swapped = true;
  }
  applyRigidDamping(closed.moving ? &closed.motion : nullptr, m.x, m.weights, m.opts.damping, m.opts.drag, m.v);
  // Velocity corrections (collision response in velocity mode) come after the damping, so that the velocities the
  // next prediction uses are the corrected ones.
  try {
    m.velocityPass(sets, h);
  } catch (...) {
    restore();
    throw;
  }
  if (!copyIfFinite(m.v, m.v1)) fail();  // the next step's revert state
  m.v0.swap(m.v1);
  m.backupValid = true;
  ++m.steps;
  return closed.maxDispMm;
}

const Points& Solver::positions() const { return impl_->x; }
const Points& Solver::velocities() const { return impl_->v; }
const Eigen::VectorXd& Solver::inverseMass() const { return impl_->w; }
int Solver::steps() const { return impl_->steps; }
const std::map<std::string, double>& Solver::secondsPerFamily() const { return impl_->seconds; }
const SolverOptions& Solver::options() const { return impl_->opts; }
int Solver::lastCgIterations() const { return impl_->cgIterations; }
double Solver::lastCgResidual() const { return impl_->cgResidual; }

}  // namespace msk
