#pragma once
/// Batch kernel of the 2-simplex internal constraint (shape memory): the data of a SimplexInternalConstraints set as a
/// struct of arrays in coloured order, and Jacobi and coloured Gauss–Seidel sweeps over it without virtual calls or
/// per-row allocation, four rows at a time with AVX where the processor has it (chosen at run time; the build flags
/// stay baseline), else two (SSE2 doubles, or plain scalars off x86). The sweeps give the corrections of the
/// Solver's per-row path (solver.h, ConstraintRow of simplexInternalCorrection(), same skip rules) up to rounding.
///
/// Wiring into a scheme (what Solver's Jacobi and coloured Gauss–Seidel would call instead of row()):
///   SimplexInternalBatch b(reference, gamma);   b.setFirstParticle(first);   // once per set
///   coloured:  for each colour k: b.projectRange(p, w, b.colourBegin(k), b.colourBegin(k + 1))  (split the range
///              over threads: rows of one colour share no particle)
///   Jacobi:    b.computeRange(p, w, 0, b.size()) (any split), then b.addCounts(w, counts) (serial, with the other
///              sets' counts), then b.applyRange(p, w, counts, omega, colourBegin(k), colourBegin(k + 1)) per colour.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "msk/core/graph_colouring.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

/// 2-simplex internal constraints (DESIGN-NOTES §2, method 2; shape memory P̃ = Σ ε̃i Pi + h̃ r⊥ n) as a batch. Rows are
/// stored colour by colour (the colouring the Solver computes for the same set), lengths in mm, inverse masses w ≥ 0.
class SimplexInternalBatch {
 public:
  /// Reference parameters ε̃, h̃ = h / r⊥ of `reference` computed as SimplexInternalConstraints does; γ ∈ [0, 1]
  /// (ParameterError otherwise). Throws Error if `reference` is not a 2-simplex mesh.
  SimplexInternalBatch(const SimplexMesh& reference, double gamma);

  /// Number of rows (one per vertex).
  int size() const { return static_cast<int>(vertex_.size()); }
  /// Index of the set's first particle in the solver's arrays.
  void setFirstParticle(int first) { first_ = first; }
  /// See setFirstParticle().
  int firstParticle() const { return first_; }
  /// User stiffness γ.
  double gamma() const { return gamma_; }
  /// Number of colours.
  int colours() const { return static_cast<int>(colourStart_.size()) - 1; }
  /// First stored row of colour k (k = colours() gives size()).
  int colourBegin(int k) const { return colourStart_[static_cast<size_t>(k)]; }
  /// Four rows at a time with AVX where the processor has it (the default), or two (SSE2) with `on` = false. Both
  /// give the per-row path's corrections up to rounding, but not bitwise the same ones.
  void useWideLanes(bool on);
  /// Whether the sweeps run four rows at a time.
  bool wideLanes() const { return wide_; }
  /// Vertex (local index) of stored row r.
  int vertexOfRow(int r) const { return vertex_[static_cast<size_t>(r)]; }

  /// Coloured Gauss–Seidel on stored rows [begin, end) of one colour: each row's PBD correction at `p` applied at once
  /// (ΔPj = wj rj Δλ, Δλ = γ (P̃ − P) / W). `p` (#N×3, mm) and `w` (#N) are the solver's whole arrays. Returns the
  /// number of rows skipped (degenerate or every particle fixed).
  int projectRange(Points& p, const Eigen::VectorXd& w, int begin, int end) const;
  /// One coloured Gauss–Seidel sweep over every row, colour by colour; returns the rows skipped.
  int colouredSweep(Points& p, const Eigen::VectorXd& w) const;

  /// Jacobi, first half: the corrections of stored rows [begin, end) at positions `p`, kept for applyRange(). Rows of
  /// different ranges may be computed at the same time. Returns the rows skipped.
  int computeRange(const Points& p, const Eigen::VectorXd& w, int begin, int end);
  /// Jacobi, counting: counts[j] += 1 for every free particle j (w > 0) of every row kept by computeRange().
  void addCounts(const Eigen::VectorXd& w, Eigen::VectorXi& counts) const;
  /// Jacobi, second half, on stored rows [begin, end) of one colour: each kept correction scaled by ω / (largest count
  /// at one of its row's particles, at least 1), as Solver's weighted-sum Jacobi does.
  void applyRange(Points& p, const Eigen::VectorXd& w, const Eigen::VectorXi& counts, double omega, int begin,
                  int end) const;
  /// One Jacobi iteration of this set alone (counts from its own rows), relaxation ω; returns the rows skipped.
  int jacobiSweep(Points& p, const Eigen::VectorXd& w, double omega);

 private:
  void checkSizes(const Points& p, const Eigen::VectorXd& w) const;
  bool wide_ = false;
  int first_ = 0;
  double gamma_;
  std::vector<int> colourStart_;            ///< #colours + 1 offsets into the stored rows
  std::vector<int> vertex_, nb0_, nb1_, nb2_;  ///< local indices of each stored row's vertex and its neighbours
  std::vector<double> eps0_, eps1_, eps2_;  ///< reference ε̃i
  std::vector<double> hr_;                  ///< reference h̃ = h / r⊥ (scale-free height)
  // Jacobi corrections of the last computeRange(): d = P̃ − P and the coefficients cj, ΔPj = wj cj d (before ω).
  std::vector<double> dx_, dy_, dz_, c0_, c1_, c2_, c3_;
  std::vector<std::uint8_t> kept_;
  Eigen::VectorXi ownCounts_;
};

}  // namespace msk
