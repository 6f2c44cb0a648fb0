#pragma once
/// Batch kernel of the 2-simplex internal constraint (shape memory): the data of a SimplexInternalConstraints set as a
/// struct of arrays (one row per vertex, in vertex order, plus the Solver's colour order), and Jacobi and coloured
/// Gauss–Seidel sweeps over it without virtual calls or per-row allocation, sixteen rows at a time (two 8-lane packs)
/// where the processor has AVX-512, eight (two 4-lane packs) where it has AVX2 (chosen at run time; the build flags
/// stay baseline), else two (SSE2 doubles, or plain scalars off x86). The sweeps read and write a packed working copy
/// of the set's particles (x, y, z, w: 32 bytes per particle, one load per neighbour instead of four gathers), filled
/// by loadRange() and written back by storeRange().
/// Inside the batch, rows and particles are kept in a locality order (BatchOrder::Locality, the default): a
/// breadth-first (Cuthill–McKee) order of the mesh, computed once, so that a row's neighbours sit a few thousand places
/// away at most (a window the L2 cache holds) however the mesh numbers its vertices; a colour's rows are swept in that
/// order too. The order changes no result: a colour's rows share no particle, and every Jacobi sum over a particle's
/// rows keeps the mesh order of its terms, so the sweeps are bitwise those of BatchOrder::Mesh.
/// They give the corrections of the Solver's per-row path (solver.h: ConstraintRow of SimplexInternalConstraints,
/// PBD step Δλ = −γ C / W, same skip rules) up to rounding.
///
/// Wiring into a scheme (what Solver's Jacobi and coloured Gauss–Seidel would call instead of row()):
///   SimplexInternalBatch b(reference, gamma);  b.setFirstParticle(first);     // once per set
///   coloured:  b.loadRange(p, w, 0, size()), then for each colour k: b.projectRange(b.colourBegin(k),
///              b.colourBegin(k + 1)) (a colour's range may be split over threads: its rows share no particle), then
///              b.storeRange(p, 0, size()); loadRange() and storeRange() may be split over threads too.
///   Jacobi:    b.loadRange(p, w, 0, size()), b.computeRange(begin, end) over [0, size()), then b.addCounts(w, counts)
///              (adding to the other sets' counts), then once every set is counted b.scaleRange(counts, omega, begin,
///              end) and b.applyRange(p, begin, end) over [0, size()); every step but addCounts() may be split over
///              threads. A set counted alone with no row skipped and b.equalShares(w) may instead call
///              b.applyEqualShares(p, omega, begin, end) after computeRange() (every share ω/4).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "msk/core/graph_colouring.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

/// Instruction set of the batch sweeps: SSE2 (two rows at a time), AVX2 (eight, as two 4-lane packs) or AVX-512 F/DQ/VL
/// (sixteen, as two 8-lane packs, 32 registers). All run the same operations lane by lane (no fused multiply-add), so
/// their results are bitwise the same.
enum class BatchLanes { Sse2, Avx2, Avx512 };

/// Order of the batch's rows and packed particles: the mesh's own vertex order, or a breadth-first (Cuthill–McKee)
/// order of its neighbour graph, whose gathers stay within a window of a few rings (the default; sets under 32 768
/// rows, which fit in L2 anyway, keep the mesh order). The results are bitwise the same; only the speed on large
/// meshes differs.
enum class BatchOrder { Mesh, Locality };

/// 2-simplex internal constraints (DESIGN-NOTES §2, method 2; shape memory P̃ = Σ ε̃i Pi + h̃ r⊥ n) as a batch: one row
/// per vertex, the colouring the Solver computes for the same set; lengths in mm, inverse masses w ≥ 0.
class SimplexInternalBatch {
 public:
  /// Reference parameters ε̃, h̃ = h / r⊥ of `reference` computed as SimplexInternalConstraints does; γ ∈ [0, 1]
  /// (ParameterError otherwise). Throws Error if `reference` is not a 2-simplex mesh.
  SimplexInternalBatch(const SimplexMesh& reference, double gamma, BatchOrder order = BatchOrder::Locality);
  /// From a set's own data: the neighbour table (#V×3), ε̃ (#V×3) and h̃ (#V) as simplexReferenceParameters()
  /// (simplex_internal_constraint.h) gives them, γ ∈ [0, 1] (ParameterError otherwise).
  SimplexInternalBatch(const NeighborTable& neighbors, const Eigen::MatrixX3d& eps, const Eigen::VectorXd& hOverR,
                       double gamma, BatchOrder order = BatchOrder::Locality);

  /// Number of rows (one per vertex).
  int size() const { return static_cast<int>(order_.size()); }
  /// Index of the set's first particle in the solver's arrays.
  void setFirstParticle(int first) { first_ = first; }
  /// See setFirstParticle().
  int firstParticle() const { return first_; }
  /// User stiffness γ.
  double gamma() const { return gamma_; }
  /// Number of colours.
  int colours() const { return static_cast<int>(colourStart_.size()) - 1; }
  /// First position of colour k in the colour order (k = colours() gives size()).
  int colourBegin(int k) const { return colourStart_[static_cast<size_t>(k)]; }
  /// The widest instruction set the processor has (the default), or SSE2 (2 rows at a time) with `on` = false.
  void useWideLanes(bool on);
  /// Whether the sweeps take a path wider than SSE2.
  bool wideLanes() const { return lanes_ != BatchLanes::Sse2; }
  /// The widest instruction set the processor has, up to `widest` (SSE2 always runs).
  void useLanes(BatchLanes widest);
  /// The instruction set the sweeps take.
  BatchLanes lanes() const { return lanes_; }
  /// Vertex (local index) at position i of the colour order.
  int colourOrder(int i) const { return order_[static_cast<size_t>(i)]; }
  /// The order of the batch's rows and packed particles.
  BatchOrder order() const { return orderKind_; }
  /// Vertex (local index) at place i of the batch's order (the row and packed particle there; i itself with
  /// BatchOrder::Mesh).
  int vertexAt(int i) const { return vertexAt_[static_cast<size_t>(i)]; }

  /// Copies the set's particles [begin, end) (local indices) of `p` (#N×3, mm) and `w` (#N), the solver's whole
  /// arrays, into the working copy the sweeps use. Disjoint ranges may run at the same time.
  void loadRange(const Points& p, const Eigen::VectorXd& w, int begin, int end);
  /// Writes the working copy's positions of particles [begin, end) back into `p`. Disjoint ranges may run at once.
  void storeRange(Points& p, int begin, int end) const;
  /// Coloured Gauss–Seidel on positions [begin, end) of the colour order, within one colour, on the working copy
  /// (loadRange()): each row's PBD correction applied at once (ΔPj = wj rj Δλ, Δλ = γ (P̃ − P) / W). Returns the
  /// number of rows skipped (degenerate or every particle fixed).
  int projectRange(int begin, int end);
  /// Every colour's projectRange() in turn on one thread, as a wavefront over the batch's order: colour k runs on the
  /// rows of chunk s − k at step s (chunks of places longer than twice the largest place distance between a row and
  /// its particles, so rows sharing a particle lie in the same or adjacent chunks and still run in colour order). The
  /// same positions bitwise, while a window of (colours + 1) chunks stays in cache instead of every colour streaming
  /// the whole working copy. Returns the rows skipped.
  int projectColours();
  /// One coloured Gauss–Seidel sweep over every row of `p`, colour by colour (load, projectColours(), store); returns
  /// the rows skipped.
  int colouredSweep(Points& p, const Eigen::VectorXd& w);

  /// Jacobi, step 1: the corrections of the rows at places [begin, end) of the batch's order (vertexAt()) at the
  /// working copy's positions (loadRange()), kept for the next steps (skipped rows keep zeros). Disjoint ranges may
  /// run at the same time. Returns the rows skipped.
  int computeRange(int begin, int end);
  /// Jacobi, step 2: counts[j] += the number of rows kept by computeRange() that touch particle j, for every free
  /// particle j (w > 0) of the set (the Solver's counts, summed over every set before step 3).
  void addCounts(const Eigen::VectorXd& w, Eigen::VectorXi& counts) const;
  /// Jacobi, step 3, rows at places [begin, end) of the batch's order: each kept correction scaled by ω / (largest
  /// count at one of its row's particles, at least 1), as Solver's weighted-sum Jacobi does. Disjoint ranges may run at
  /// the same time.
  void scaleRange(const Eigen::VectorXi& counts, double omega, int begin, int end);
  /// Jacobi, step 4, particles at places [begin, end) of the batch's order: each adds the scaled corrections of the
  /// rows touching it, gathered (no scatter), so disjoint ranges may run at the same time.
  void applyRange(Points& p, int begin, int end) const;
  /// Whether steps 2 and 3 may be skipped when this set alone is counted and computeRange() skipped no row: every
  /// particle of the set sits in exactly 4 rows (a closed 2-simplex mesh) and is free (w > 0), so every share is ω/4.
  bool equalShares(const Eigen::VectorXd& w) const;
  /// Jacobi, step 4 with equal shares (equalShares()), particles at places [begin, end): each adds ω/4 times the
  /// unscaled corrections of its 4 rows. Disjoint ranges may run at the same time.
  void applyEqualShares(Points& p, double omega, int begin, int end) const;
  /// applyEqualShares() into the packed working copy instead of `p` (bitwise the same positions; storeRange() writes
  /// them back), so that a set iterated alone needs no loadRange() between its iterations.
  void applyEqualSharesPacked(double omega, int begin, int end);
  /// Jacobi iteration of this set alone on the working copy with every share ω/4 (equalShares() must hold for the
  /// caller's w): computeRange() and applyEqualSharesPacked() over every row and particle, fused chunk by chunk over
  /// the batch's order (a chunk's rows, then the particles of the chunk before, whose rows are all done), the records
  /// in a ring that stays in cache and the new positions in a second packed copy. Bitwise the same positions. Returns
  /// the rows skipped: if any is, nothing is applied, and every row's correction is left as computeRange(0, size())
  /// leaves it (the caller goes on with addCounts(), scaleRange(), applyRange()). One thread.
  int jacobiEqualSharesPacked(double omega);
  /// One Jacobi iteration of this set alone on `p` (load, compute, counts from its own rows, scale, apply; or the
  /// equal shares when they hold, jacobiEqualSharesPacked()), relaxation ω; returns the rows skipped.
  int jacobiSweep(Points& p, const Eigen::VectorXd& w, double omega);

 private:
  /// Fills every array from the neighbour table and reference parameters (both constructors).
  void build(const NeighborTable& nb, const Eigen::MatrixX3d& eps, const Eigen::VectorXd& hOverR, BatchOrder order);
  void checkSizes(const Points& p, const Eigen::VectorXd& w) const;
  void checkRange(int begin, int end) const;
  /// applyRange() with every sum times `post`.
  void applyScaled(Points& p, int begin, int end, double post) const;
  BatchLanes lanes_ = BatchLanes::Sse2;
  BatchOrder orderKind_ = BatchOrder::Locality;
  int first_ = 0;
  double gamma_;
  std::vector<int> vertexAt_;     ///< place → vertex (local index) of the batch's order
  std::vector<int> placeOf_;      ///< vertex (local index) → its place in the batch's order
  bool scattered_ = false;        ///< some vertex not at its own place (load, store and apply go through placeOf_)
  std::vector<int> colourStart_;  ///< #colours + 1 offsets into order_
  std::vector<int> order_;        ///< rows (vertices, local indices) colour by colour
  std::vector<int> corder_;       ///< the same rows as places of the batch's order
  int waveChunk_ = 1;             ///< places per chunk of projectColours()
  std::vector<int> waveStart_;    ///< colour k's rows in chunk j: positions [waveStart_[k·(J+1) + j], .. + 1)
  // Per-row data at each place of the batch's order (row vertexAt_[i] at i); neighbours as places.
  std::vector<int> nb0_, nb1_, nb2_;        ///< each row's neighbours (places)
  std::vector<double> eps0_, eps1_, eps2_;  ///< reference ε̃i
  std::vector<double> hr_;                  ///< reference h̃ = h / r⊥ (scale-free height)
  // The same per-row data in colour order (position i: row corder_[i]), read by the Gauss–Seidel sweeps.
  std::vector<int> cnb0_, cnb1_, cnb2_;
  std::vector<double> ceps0_, ceps1_, ceps2_, chr_;
  /// First 64-byte aligned double of `buffer` (allocated 8 doubles longer than its contents).
  static double* aligned(std::vector<double>& buffer);
  static const double* aligned(const std::vector<double>& buffer);
  std::vector<double> pos_;  ///< working copy: x, y, z, w of the particle at place i at 4i .. 4i + 3 of aligned(pos_)
  // Jacobi corrections of the last computeRange(), one 64-byte record (a cache line) per row r at 8r of aligned(d_):
  // d = P̃ − P (times the row's ω / count after scaleRange()) at 8r .. 8r + 2 (8r + 3 zero), and the coefficients
  // cj of its particles, ΔPj = cj d, at 8r + 4 + j.
  std::vector<double> d_;
  // Rows touching each particle (CSR over revStart_, both as places; each particle's rows in mesh order, so that the
  // sums over them do not depend on the batch's order): the row (revRow_) and the place of its coefficient
  // (revFlat_: 8·row + 4 + slot, its record at revFlat_ & ~7).
  std::vector<int> revStart_, revRow_, revFlat_;
  std::vector<int> tFlat_;           ///< with uniform4_: revFlat_ entry e of the particle at place i at e·n + i
  int ringChunk_ = 512;              ///< places per chunk of jacobiEqualSharesPacked() (a power of two)
  std::vector<int> tRing_;           ///< tFlat_ with each row r at its ring record r mod 4·ringChunk_
  std::vector<double> ring_, next_;  ///< its ring of records, and the packed copy it writes (swapped with pos_)
  bool uniform4_ = false;            ///< every particle in exactly 4 rows (a closed 2-simplex mesh): the vector apply
  std::vector<std::uint8_t> kept_;
  Eigen::VectorXi ownCounts_;
};

}  // namespace msk
