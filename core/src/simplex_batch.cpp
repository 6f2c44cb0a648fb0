#include "msk/core/simplex_batch.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include <Eigen/Dense>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "msk/core/error.h"
#include "msk/core/graph_colouring.h"

namespace msk {

namespace {

// ------------------------------------------------------------------------------------------------ two lanes

// Two doubles processed together: SSE2 registers on x86-64 (part of the baseline, no -march needed), a pair of
// scalars elsewhere. Masks are all-ones / all-zeros lanes, as the SSE2 comparisons give them.
#if defined(__SSE2__)
struct D2 {
  __m128d v;
};
inline D2 set2(double lo, double hi) { return {_mm_set_pd(hi, lo)}; }
inline D2 splat(double a) { return {_mm_set1_pd(a)}; }
inline D2 operator+(D2 a, D2 b) { return {_mm_add_pd(a.v, b.v)}; }
inline D2 operator-(D2 a, D2 b) { return {_mm_sub_pd(a.v, b.v)}; }
inline D2 operator*(D2 a, D2 b) { return {_mm_mul_pd(a.v, b.v)}; }
inline D2 operator/(D2 a, D2 b) { return {_mm_div_pd(a.v, b.v)}; }
inline D2 vsqrt(D2 a) { return {_mm_sqrt_pd(a.v)}; }
inline D2 vmax(D2 a, D2 b) { return {_mm_max_pd(a.v, b.v)}; }
inline D2 vabs(D2 a) { return {_mm_andnot_pd(_mm_set1_pd(-0.0), a.v)}; }
inline D2 gt(D2 a, D2 b) { return {_mm_cmpgt_pd(a.v, b.v)}; }
inline D2 lt(D2 a, D2 b) { return {_mm_cmplt_pd(a.v, b.v)}; }
inline D2 notGe(D2 a, D2 b) { return {_mm_cmpnge_pd(a.v, b.v)}; }  // true where a < b or either is NaN
inline D2 notLe(D2 a, D2 b) { return {_mm_cmpnle_pd(a.v, b.v)}; }  // true where a > b or either is NaN
inline D2 operator&(D2 a, D2 b) { return {_mm_and_pd(a.v, b.v)}; }
inline D2 operator|(D2 a, D2 b) { return {_mm_or_pd(a.v, b.v)}; }
inline D2 operator~(D2 m) { return {_mm_xor_pd(m.v, _mm_castsi128_pd(_mm_set1_epi32(-1)))}; }
/// m ? a : b per lane.
inline D2 select(D2 m, D2 a, D2 b) { return {_mm_or_pd(_mm_and_pd(m.v, a.v), _mm_andnot_pd(m.v, b.v))}; }
/// Bit 0: lane 0's mask, bit 1: lane 1's.
inline int bits(D2 m) { return _mm_movemask_pd(m.v); }
inline void store2(D2 a, double* out) { _mm_storeu_pd(out, a.v); }
#else
struct D2 {
  double v[2];
};
inline double maskOf(bool b) {
  const std::uint64_t u = b ? ~std::uint64_t(0) : 0;
  double d;
  std::memcpy(&d, &u, sizeof d);
  return d;
}
inline bool isSet(double m) {
  std::uint64_t u;
  std::memcpy(&u, &m, sizeof u);
  return u != 0;
}
template <class F>
inline D2 map2(D2 a, D2 b, F f) {
  return {{f(a.v[0], b.v[0]), f(a.v[1], b.v[1])}};
}
inline D2 set2(double lo, double hi) { return {{lo, hi}}; }
inline D2 splat(double a) { return {{a, a}}; }
inline D2 operator+(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return x + y; }); }
inline D2 operator-(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return x - y; }); }
inline D2 operator*(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return x * y; }); }
inline D2 operator/(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return x / y; }); }
inline D2 vsqrt(D2 a) { return {{std::sqrt(a.v[0]), std::sqrt(a.v[1])}}; }
inline D2 vmax(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return x > y ? x : y; }); }
inline D2 vabs(D2 a) { return {{std::fabs(a.v[0]), std::fabs(a.v[1])}}; }
inline D2 gt(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return maskOf(x > y); }); }
inline D2 lt(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return maskOf(x < y); }); }
inline D2 notGe(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return maskOf(!(x >= y)); }); }
inline D2 notLe(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return maskOf(!(x <= y)); }); }
inline D2 operator&(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return maskOf(isSet(x) && isSet(y)); }); }
inline D2 operator|(D2 a, D2 b) { return map2(a, b, [](double x, double y) { return maskOf(isSet(x) || isSet(y)); }); }
inline D2 operator~(D2 m) { return {{maskOf(!isSet(m.v[0])), maskOf(!isSet(m.v[1]))}}; }
inline D2 select(D2 m, D2 a, D2 b) { return {{isSet(m.v[0]) ? a.v[0] : b.v[0], isSet(m.v[1]) ? a.v[1] : b.v[1]}}; }
inline int bits(D2 m) { return (isSet(m.v[0]) ? 1 : 0) | (isSet(m.v[1]) ? 2 : 0); }
inline void store2(D2 a, double* out) {
  out[0] = a.v[0];
  out[1] = a.v[1];
}
#endif

/// Finite lanes (false for ±inf and NaN).
inline D2 finite(D2 x) { return lt(vabs(x), splat(std::numeric_limits<double>::infinity())); }

struct V3 {
  D2 x, y, z;
};
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline D2 dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

/// Positions of the solver's arrays seen from the set's first particle (Points is column-major: x, y, z columns).
struct Coords {
  double* x;
  double* y;
  double* z;
  V3 load(int i, int j) const { return {set2(x[i], x[j]), set2(y[i], y[j]), set2(z[i], z[j])}; }
};

/// Inputs of two rows.
struct RowPair {
  V3 p, q0, q1, q2;   ///< P and its neighbours P1..P3, mm
  D2 w, w0, w1, w2;   ///< inverse masses
  D2 e0, e1, e2, hr;  ///< reference ε̃i and h̃ = h / r⊥
};

/// Outputs of two rows: Δλ = γ (P̃ − P) / W (mm) and the reaction weights λ, so ΔP = w Δλ and ΔPi = −wi λi Δλ.
struct RowResult {
  V3 dl;
  D2 l0, l1, l2;
  int kept;  ///< bit k set: lane k is a correction (not skipped)
};

/// The 2-simplex internal constraint of two rows (DESIGN-NOTES §2, method 2; thesis seed §4.8.1), the arithmetic of
/// simplexShapeTarget() + simplexInternalCorrection() and of the Solver's row path (W = w + Σ ε̃i λi wi > 0, finite
/// Δλ), rearranged to take one square root and three divisions per row and no branch on common data:
/// - target P̃ = Σ ε̃i Pi + h̃ r⊥ n with r⊥ n = (la lb lc / 2A) x / A = √(la² lb² lc²) x / (2 |x|²), x = P1P2 × P1P3,
///   skipped where !(|x| > 1e-12 max li²) or non-finite (the test done on squares);
/// - λ'i ∝ μi (Cramer without the determinant): μ1 = PP2·(PP3×d), μ2 = −PP1·(PP3×d), μ3 = d·(PP1×PP2), d = P̃ − P;
///   the torque-free split λ = μ/Σμ where |Σμ| > 0.05 Σ|μi|, pulled toward ε̃ so max|λi − ε̃i| ≤ 0.75, else λ = ε̃;
///   back to λ = ε̃ where W < w + ½ Σ ε̃i² wi, W non-finite or max|λi| > 3.
inline RowResult internalRows(const RowPair& in, double gamma) {
  const V3 &p = in.p, &q0 = in.q0, &q1 = in.q1, &q2 = in.q2;
  const V3 e1 = q1 - q0, e2 = q2 - q0, f = q1 - q2;
  const V3 x = cross(e1, e2);
  const D2 a2 = dot(x, x), la2 = dot(f, f), lb2 = dot(e2, e2), lc2 = dot(e1, e1);
  const D2 s2 = vmax(la2, vmax(lb2, lc2));
  const D2 frameOk = gt(a2, splat(1e-24) * s2 * s2) & finite(a2);
  const D2 k = in.hr * vsqrt(la2 * lb2 * lc2) / (a2 + a2);
  const V3 t = {in.e0 * q0.x + in.e1 * q1.x + in.e2 * q2.x + k * x.x,
                in.e0 * q0.y + in.e1 * q1.y + in.e2 * q2.y + k * x.y,
                in.e0 * q0.z + in.e1 * q1.z + in.e2 * q2.z + k * x.z};
  const V3 d = t - p;  // finite iff the target and P are
  D2 ok = frameOk & finite(d.x) & finite(d.y) & finite(d.z);
  const D2 zero = splat(0.0);
  ok = ok & (notLe(in.w, zero) | notLe(in.w0, zero) | notLe(in.w1, zero) | notLe(in.w2, zero));

  const V3 a1 = q0 - p, a2v = q1 - p, a3 = q2 - p;
  const V3 y = cross(a3, d), z = cross(a1, a2v);
  const D2 mu0 = dot(a2v, y), mu1 = zero - dot(a1, y), mu2 = dot(d, z);
  const D2 sum = mu0 + mu1 + mu2;
  const D2 absSum = vabs(mu0) + vabs(mu1) + vabs(mu2);
  const D2 split = gt(vabs(sum), splat(0.05) * absSum) & gt(vabs(sum), zero);
  const D2 inv = splat(1.0) / sum;
  D2 l0 = mu0 * inv, l1 = mu1 * inv, l2 = mu2 * inv;
  const D2 dev = vmax(vabs(l0 - in.e0), vmax(vabs(l1 - in.e1), vabs(l2 - in.e2)));
  const D2 far = split & gt(dev, splat(0.75));
  if (bits(far)) {  // rare: pull λ toward ε̃
    const D2 s = select(far, splat(0.75) / dev, splat(1.0));
    l0 = in.e0 + s * (l0 - in.e0);
    l1 = in.e1 + s * (l1 - in.e1);
    l2 = in.e2 + s * (l2 - in.e2);
  }
  l0 = select(split, l0, in.e0);
  l1 = select(split, l1, in.e1);
  l2 = select(split, l2, in.e2);
  const D2 c0 = in.e0 * in.w0, c1 = in.e1 * in.w1, c2 = in.e2 * in.w2;
  const D2 plain = in.e0 * c0 + in.e1 * c1 + in.e2 * c2;
  D2 den = in.w + in.e0 * l0 * in.w0 + in.e1 * l1 * in.w1 + in.e2 * l2 * in.w2;
  const D2 lmax = vmax(vabs(l0), vmax(vabs(l1), vabs(l2)));
  const D2 fallback = notGe(den, in.w + splat(0.5) * plain) | ~finite(den) | gt(lmax, splat(3.0));
  l0 = select(fallback, in.e0, l0);
  l1 = select(fallback, in.e1, l1);
  l2 = select(fallback, in.e2, l2);
  den = select(fallback, in.w + plain, den);
  // The Solver's row test: W = w + Σ ε̃i λi wi (= den) positive and finite, and a finite Δλ.
  ok = ok & gt(den, zero) & finite(den);
  const D2 g = select(ok, splat(gamma) / den, zero);
  RowResult r;
  r.dl = {g * d.x, g * d.y, g * d.z};
  ok = ok & finite(r.dl.x) & finite(r.dl.y) & finite(r.dl.z);
  r.l0 = l0;
  r.l1 = l1;
  r.l2 = l2;
  r.kept = bits(ok);
  return r;
}

}  // namespace

/// Inputs of stored rows r and s (s = r for a lone last row) from the solver's arrays.
struct SimplexInternalBatch::Source {
  Coords c;
  const double* w;
  const int *v, *n0, *n1, *n2;
  const double *e0, *e1, *e2, *hr;

  RowPair load(int r, int s) const {
    RowPair in;
    const int va = v[r], vb = v[s], a0 = n0[r], b0 = n0[s], a1 = n1[r], b1 = n1[s], a2 = n2[r], b2 = n2[s];
    in.p = c.load(va, vb);
    in.q0 = c.load(a0, b0);
    in.q1 = c.load(a1, b1);
    in.q2 = c.load(a2, b2);
    in.w = set2(w[va], w[vb]);
    in.w0 = set2(w[a0], w[b0]);
    in.w1 = set2(w[a1], w[b1]);
    in.w2 = set2(w[a2], w[b2]);
    in.e0 = set2(e0[r], e0[s]);
    in.e1 = set2(e1[r], e1[s]);
    in.e2 = set2(e2[r], e2[s]);
    in.hr = set2(hr[r], hr[s]);
    return in;
  }
};

namespace {

/// Circumradius and unit normal of triangle (a, b, c), as constraints.cpp computes them for the reference; false if
/// degenerate.
bool referenceFrame(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& radius,
                    Eigen::Vector3d& normal) {
  const Eigen::Vector3d x = (b - a).cross(c - a);
  const double twiceArea = x.norm();
  const double la = (b - c).norm(), lb = (c - a).norm(), lc = (a - b).norm();
  const double scale = std::max({la, lb, lc});
  if (!(twiceArea > 1e-12 * scale * scale) || !std::isfinite(twiceArea)) return false;
  radius = la * lb * lc / (2.0 * twiceArea);
  normal = x / twiceArea;
  return true;
}

}  // namespace

SimplexInternalBatch::SimplexInternalBatch(const SimplexMesh& reference, double gamma) : gamma_(gamma) {
  checkUnitInterval("internal stiffness", gamma);
  const NeighborTable& nb = reference.neighbors;
  MSK_ASSERT(reference.k == 2 && nb.cols() == 3 && nb.rows() == reference.vertexCount(), "2-simplex mesh expected");
  const int n = reference.vertexCount();
  // Reference metric parameters, exactly as SimplexInternalConstraints computes them.
  Eigen::MatrixX3d eps(n, 3);
  Eigen::VectorXd hOverR(n);
  for (int v = 0; v < n; ++v) {
    for (int j = 0; j < 3; ++j) MSK_ASSERT(nb(v, j) >= 0 && nb(v, j) < n, "neighbour index out of range");
    const Eigen::Vector3d pi[3] = {reference.positions.row(nb(v, 0)), reference.positions.row(nb(v, 1)),
                                   reference.positions.row(nb(v, 2))};
    const Eigen::Vector3d p = reference.positions.row(v);
    double r = 0;
    Eigen::Vector3d nrm;
    if (!referenceFrame(pi[0], pi[1], pi[2], r, nrm)) {
      eps.row(v).setConstant(1.0 / 3.0);
      hOverR[v] = 0;
      continue;
    }
    const double h = (p - pi[0]).dot(nrm);
    const Eigen::Vector3d q = p - h * nrm;
    const Eigen::Vector3d e0 = pi[1] - pi[0], e1 = pi[2] - pi[0], f = q - pi[0];
    const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = f.dot(e0), d21 = f.dot(e1);
    const double den = d00 * d11 - d01 * d01;
    const double b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den;
    eps.row(v) << 1.0 - b1 - b2, b1, b2;
    hOverR[v] = h / r;
  }
  // The Solver's colouring of the same rows (its particles: the vertex, then its neighbours), rows stored in it.
  const Colouring col = colourConstraints(n, 4, [&nb](int r, int* out) {
    out[0] = r;
    for (int j = 0; j < 3; ++j) out[j + 1] = nb(r, j);
    return 4;
  });
  colourStart_ = col.start;
  if (colourStart_.empty()) colourStart_.push_back(0);
  const size_t un = static_cast<size_t>(n);
  vertex_.resize(un);
  nb0_.resize(un);
  nb1_.resize(un);
  nb2_.resize(un);
  eps0_.resize(un);
  eps1_.resize(un);
  eps2_.resize(un);
  hr_.resize(un);
  for (size_t k = 0; k < un; ++k) {
    const int v = col.order[k];
    vertex_[k] = v;
    nb0_[k] = nb(v, 0);
    nb1_[k] = nb(v, 1);
    nb2_[k] = nb(v, 2);
    eps0_[k] = eps(v, 0);
    eps1_[k] = eps(v, 1);
    eps2_[k] = eps(v, 2);
    hr_[k] = hOverR[v];
  }
  for (auto* a : {&qx_, &qy_, &qz_, &l0_, &l1_, &l2_}) a->assign(un, 0.0);
  kept_.assign(un, 0);
}

void SimplexInternalBatch::checkSizes(const Points& p, const Eigen::VectorXd& w) const {
  MSK_ASSERT(first_ >= 0 && p.rows() >= first_ + size() && w.size() == p.rows(),
             "simplex internal batch: size mismatch");
}

SimplexInternalBatch::Source SimplexInternalBatch::source(const Points& p, const Eigen::VectorXd& w) const {
  // Points is column-major: the x, y and z columns are each contiguous.
  double* base = const_cast<double*>(p.data());
  const Eigen::Index rows = p.rows();
  Source s;
  s.c = Coords{base + first_, base + rows + first_, base + 2 * rows + first_};
  s.w = w.data() + first_;
  s.v = vertex_.data();
  s.n0 = nb0_.data();
  s.n1 = nb1_.data();
  s.n2 = nb2_.data();
  s.e0 = eps0_.data();
  s.e1 = eps1_.data();
  s.e2 = eps2_.data();
  s.hr = hr_.data();
  return s;
}

int SimplexInternalBatch::projectRange(Points& p, const Eigen::VectorXd& w, int begin, int end) const {
  checkSizes(p, w);
  MSK_ASSERT(begin >= 0 && begin <= end && end <= size(), "simplex internal batch: bad row range");
  const Source src = source(p, w);
  const Coords& c = src.c;
  int skipped = 0;
  for (int r = begin; r < end; r += 2) {
    const int s = r + 1 < end ? r + 1 : r;
    const RowResult out = internalRows(src.load(r, s), gamma_);
    double dx[2], dy[2], dz[2], l0[2], l1[2], l2[2];
    store2(out.dl.x, dx);
    store2(out.dl.y, dy);
    store2(out.dl.z, dz);
    store2(out.l0, l0);
    store2(out.l1, l1);
    store2(out.l2, l2);
    const int lanes = s == r ? 1 : 2;
    // Rows of one colour share no particle: applying the two lanes one after the other is the sequential order.
    for (int k = 0; k < lanes; ++k) {
      if (!(out.kept & (1 << k))) {
        ++skipped;
        continue;
      }
      const size_t row = static_cast<size_t>(r + k);
      const int idx[4] = {vertex_[row], nb0_[row], nb1_[row], nb2_[row]};
      const double react[4] = {1.0, -l0[k], -l1[k], -l2[k]};
      for (int j = 0; j < 4; ++j) {
        const double a = src.w[idx[j]] * react[j];
        c.x[idx[j]] += a * dx[k];
        c.y[idx[j]] += a * dy[k];
        c.z[idx[j]] += a * dz[k];
      }
    }
  }
  return skipped;
}

int SimplexInternalBatch::colouredSweep(Points& p, const Eigen::VectorXd& w) const {
  int skipped = 0;
  for (int k = 0; k < colours(); ++k) skipped += projectRange(p, w, colourBegin(k), colourBegin(k + 1));
  return skipped;
}

int SimplexInternalBatch::computeRange(const Points& p, const Eigen::VectorXd& w, int begin, int end) {
  checkSizes(p, w);
  MSK_ASSERT(begin >= 0 && begin <= end && end <= size(), "simplex internal batch: bad row range");
  const Source src = source(p, w);
  int skipped = 0;
  for (int r = begin; r < end; r += 2) {
    const int s = r + 1 < end ? r + 1 : r;
    const RowResult out = internalRows(src.load(r, s), gamma_);
    double t[6][2];
    store2(out.dl.x, t[0]);
    store2(out.dl.y, t[1]);
    store2(out.dl.z, t[2]);
    store2(out.l0, t[3]);
    store2(out.l1, t[4]);
    store2(out.l2, t[5]);
    const int lanes = s == r ? 1 : 2;
    for (int k = 0; k < lanes; ++k) {
      const size_t row = static_cast<size_t>(r + k);
      qx_[row] = t[0][k];
      qy_[row] = t[1][k];
      qz_[row] = t[2][k];
      l0_[row] = t[3][k];
      l1_[row] = t[4][k];
      l2_[row] = t[5][k];
      kept_[row] = static_cast<std::uint8_t>((out.kept >> k) & 1);
      skipped += 1 - kept_[row];
    }
  }
  return skipped;
}

void SimplexInternalBatch::addCounts(const Eigen::VectorXd& w, Eigen::VectorXi& counts) const {
  MSK_ASSERT(counts.size() == w.size() && w.size() >= first_ + size(), "simplex internal batch: size mismatch");
  const double* wv = w.data() + first_;
  int* cnt = counts.data() + first_;
  for (size_t r = 0; r < vertex_.size(); ++r) {
    if (!kept_[r]) continue;
    const int idx[4] = {vertex_[r], nb0_[r], nb1_[r], nb2_[r]};
    for (int j = 0; j < 4; ++j) cnt[idx[j]] += wv[idx[j]] > 0 ? 1 : 0;
  }
}

void SimplexInternalBatch::applyRange(Points& p, const Eigen::VectorXd& w, const Eigen::VectorXi& counts,
                                      double omega, int begin, int end) const {
  checkSizes(p, w);
  MSK_ASSERT(counts.size() == w.size(), "simplex internal batch: size mismatch");
  MSK_ASSERT(begin >= 0 && begin <= end && end <= size(), "simplex internal batch: bad row range");
  const Source src = source(p, w);
  const Coords& c = src.c;
  const int* cnt = counts.data() + first_;
  for (int r = begin; r < end; ++r) {
    const size_t ur = static_cast<size_t>(r);
    if (!kept_[ur]) continue;
    const int idx[4] = {vertex_[ur], nb0_[ur], nb1_[ur], nb2_[ur]};
    const int most = std::max(std::max(1, std::max(cnt[idx[0]], cnt[idx[1]])), std::max(cnt[idx[2]], cnt[idx[3]]));
    const double scale = omega / most;
    const double react[4] = {1.0, -l0_[ur], -l1_[ur], -l2_[ur]};
    for (int j = 0; j < 4; ++j) {
      const double a = scale * src.w[idx[j]] * react[j];
      c.x[idx[j]] += a * qx_[ur];
      c.y[idx[j]] += a * qy_[ur];
      c.z[idx[j]] += a * qz_[ur];
    }
  }
}

int SimplexInternalBatch::jacobiSweep(Points& p, const Eigen::VectorXd& w, double omega) {
  const int skipped = computeRange(p, w, 0, size());
  ownCounts_.setZero(w.size());
  addCounts(w, ownCounts_);
  for (int k = 0; k < colours(); ++k) applyRange(p, w, ownCounts_, omega, colourBegin(k), colourBegin(k + 1));
  return skipped;
}

}  // namespace msk
