#include "msk/core/simplex_batch.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// A wide path with AVX2 (256-bit doubles; eight rows per step as two 4-lane packs), compiled for that
// instruction set function by function and chosen at run time when the processor has it; the project's flags (no
// -march) stay as they are.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && defined(__SSE2__)
#define MSK_BATCH_AVX 1
#include <immintrin.h>
#else
#define MSK_BATCH_AVX 0
#endif

#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "msk/core/error.h"
#include "msk/core/graph_colouring.h"
#include "msk/core/simplex_internal_constraint.h"

namespace msk {

namespace {

using namespace simplex_internal;

#if defined(__GNUC__) || defined(__clang__)
#define MSK_BATCH_INLINE inline __attribute__((always_inline))
#else
#define MSK_BATCH_INLINE inline
#endif

/// The arrays one sweep reads and writes: the packed working copy (particle v's x, y, z, w at 4v, local indices,
/// 32-byte aligned), and the rows in the pass's order: vertex order (order unused) or colour order (order[i] the
/// vertex of position i).
struct BatchArrays {
  double* pos;
  const int *order, *n0, *n1, *n2;
  const double *e0, *e1, *e2, *hr;
};

/// Where computeRows() writes each row's Jacobi correction: row r's record at rec + 8 (r − base) (64-byte aligned): d
/// (x, y, z, 0) and the coefficients c0 .. c3 (inverse masses included); whether it is kept at kept[r].
struct JacobiOut {
  double* rec;
  std::uint8_t* kept;
  std::ptrdiff_t base = 0;
};

/// What the per-particle Jacobi apply reads: for particle v, entries e·n + v (e = 0..3) give the place `flat` of the
/// coefficient of a row touching it in the records (8·row + 4 + slot; the row's d at flat & ~7).
struct JacobiView {
  std::ptrdiff_t n;
  const int* flat;
  const double* rec;
  double post;        ///< factor of every sum (ω/4 when all shares are equal, else 1: the shares are in d)
  const int* vertex;  ///< the particle (column index) at each place
};

// ------------------------------------------------------------------------------------------------ two lanes

// Two doubles processed together: SSE2 registers on x86-64 (part of the baseline, no -march needed), a pair of
// scalars elsewhere. Masks are all-ones / all-zeros lanes, as the SSE2 comparisons give them.
#if defined(__SSE2__)
struct D2 {
  static constexpr int lanes = 2;
  __m128d v;
};
inline D2 splat(double a) { return {_mm_set1_pd(a)}; }
inline D2 loadu(const double* p) { return {_mm_loadu_pd(p)}; }
inline void storeu(D2 a, double* out) { _mm_storeu_pd(out, a.v); }
inline D2 operator+(D2 a, D2 b) { return {_mm_add_pd(a.v, b.v)}; }
inline D2 operator-(D2 a, D2 b) { return {_mm_sub_pd(a.v, b.v)}; }
inline D2 operator*(D2 a, D2 b) { return {_mm_mul_pd(a.v, b.v)}; }
inline D2 operator/(D2 a, D2 b) { return {_mm_div_pd(a.v, b.v)}; }
inline D2 vsqrt(D2 a) { return {_mm_sqrt_pd(a.v)}; }
inline D2 vmax(D2 a, D2 b) { return {_mm_max_pd(a.v, b.v)}; }
inline D2 vabs(D2 a) { return {_mm_andnot_pd(_mm_set1_pd(-0.0), a.v)}; }
inline D2 gt(D2 a, D2 b) { return {_mm_cmpgt_pd(a.v, b.v)}; }
inline D2 lt(D2 a, D2 b) { return {_mm_cmplt_pd(a.v, b.v)}; }
inline D2 ge(D2 a, D2 b) { return {_mm_cmpge_pd(a.v, b.v)}; }
inline D2 eq(D2 a, D2 b) { return {_mm_cmpeq_pd(a.v, b.v)}; }
inline D2 notLe(D2 a, D2 b) { return {_mm_cmpnle_pd(a.v, b.v)}; }  // a > b or either NaN
inline D2 operator&(D2 a, D2 b) { return {_mm_and_pd(a.v, b.v)}; }
inline D2 operator|(D2 a, D2 b) { return {_mm_or_pd(a.v, b.v)}; }
inline D2 operator~(D2 m) { return {_mm_xor_pd(m.v, _mm_castsi128_pd(_mm_set1_epi32(-1)))}; }
/// m ? a : b per lane.
inline D2 select(D2 m, D2 a, D2 b) { return {_mm_or_pd(_mm_and_pd(m.v, a.v), _mm_andnot_pd(m.v, b.v))}; }
/// a with its sign flipped where s is negative (a·sgn s).
inline D2 flipSign(D2 a, D2 s) { return {_mm_xor_pd(a.v, _mm_and_pd(s.v, _mm_set1_pd(-0.0)))}; }
/// Bit k: lane k's mask.
inline int bits(D2 m) { return _mm_movemask_pd(m.v); }
#else
struct D2 {
  static constexpr int lanes = 2;
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
inline D2 splat(double a) { return {{a, a}}; }
inline D2 loadu(const double* p) { return {{p[0], p[1]}}; }
inline void storeu(D2 a, double* out) {
  out[0] = a.v[0];
  out[1] = a.v[1];
}
inline D2 operator+(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return x + y; });
}
inline D2 operator-(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return x - y; });
}
inline D2 operator*(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return x * y; });
}
inline D2 operator/(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return x / y; });
}
inline D2 vsqrt(D2 a) { return {{std::sqrt(a.v[0]), std::sqrt(a.v[1])}}; }
inline D2 vmax(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return x > y ? x : y; });
}
inline D2 vabs(D2 a) { return {{std::fabs(a.v[0]), std::fabs(a.v[1])}}; }
inline D2 gt(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(x > y); });
}
inline D2 lt(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(x < y); });
}
inline D2 ge(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(x >= y); });
}
inline D2 eq(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(x == y); });
}
inline D2 notLe(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(!(x <= y)); });
}
inline D2 operator&(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(isSet(x) && isSet(y)); });
}
inline D2 operator|(D2 a, D2 b) {
  return map2(a, b, [](double x, double y) { return maskOf(isSet(x) || isSet(y)); });
}
inline D2 operator~(D2 m) { return {{maskOf(!isSet(m.v[0])), maskOf(!isSet(m.v[1]))}}; }
inline D2 select(D2 m, D2 a, D2 b) { return {{isSet(m.v[0]) ? a.v[0] : b.v[0], isSet(m.v[1]) ? a.v[1] : b.v[1]}}; }
inline D2 flipSign(D2 a, D2 s) {
  return map2(a, s, [](double x, double y) { return std::signbit(y) ? -x : x; });
}
inline int bits(D2 m) { return (isSet(m.v[0]) ? 1 : 0) | (isSet(m.v[1]) ? 2 : 0); }
#endif

// One particle's packed x, y, z, w (Q) and the moves between packed particles and packs of 2 rows.
#if defined(__SSE2__)
struct Q2 {
  __m128d xy, zw;
};
inline Q2 loadQ(const double* p) { return {_mm_load_pd(p), _mm_load_pd(p + 2)}; }
inline void storeQ(Q2 q, double* p) {
  _mm_store_pd(p, q.xy);
  _mm_store_pd(p + 2, q.zw);
}
inline Q2 splatQ(double a) { return {_mm_set1_pd(a), _mm_set1_pd(a)}; }
inline Q2 operator+(Q2 a, Q2 b) { return {_mm_add_pd(a.xy, b.xy), _mm_add_pd(a.zw, b.zw)}; }
inline Q2 operator*(Q2 a, Q2 b) { return {_mm_mul_pd(a.xy, b.xy), _mm_mul_pd(a.zw, b.zw)}; }
/// x, y, z of `u`, w of `old`.
inline Q2 keepW(Q2 u, Q2 old) { return {u.xy, _mm_move_sd(old.zw, u.zw)}; }
/// The x, y, z, w packs of the particles idx[0], idx[1] of `pos`.
inline void loadPoints(const double* pos, const int* idx, D2& x, D2& y, D2& z, D2& w) {
  const double* p0 = pos + 4 * static_cast<std::ptrdiff_t>(idx[0]);
  const double* p1 = pos + 4 * static_cast<std::ptrdiff_t>(idx[1]);
  const __m128d a = _mm_load_pd(p0), b = _mm_load_pd(p1), c = _mm_load_pd(p0 + 2), d = _mm_load_pd(p1 + 2);
  x.v = _mm_unpacklo_pd(a, b);
  y.v = _mm_unpackhi_pd(a, b);
  z.v = _mm_unpacklo_pd(c, d);
  w.v = _mm_unpackhi_pd(c, d);
}
/// out[k] = (a, b, c, d) of lane k.
inline void toQ4(D2 a, D2 b, D2 c, D2 d, Q2* out) {
  out[0] = {_mm_unpacklo_pd(a.v, b.v), _mm_unpacklo_pd(c.v, d.v)};
  out[1] = {_mm_unpackhi_pd(a.v, b.v), _mm_unpackhi_pd(c.v, d.v)};
}
/// out[k] = (x, y, z, 0) of lane k.
inline void toQ(D2 x, D2 y, D2 z, Q2* out) { toQ4(x, y, z, D2{_mm_setzero_pd()}, out); }
/// Lane k of x, y, z: in[k]'s.
inline void fromQ(const Q2* in, D2& x, D2& y, D2& z) {
  x.v = _mm_unpacklo_pd(in[0].xy, in[1].xy);
  y.v = _mm_unpackhi_pd(in[0].xy, in[1].xy);
  z.v = _mm_unpacklo_pd(in[0].zw, in[1].zw);
}
#else
struct Q2 {
  double v[4];
};
inline Q2 loadQ(const double* p) { return {{p[0], p[1], p[2], p[3]}}; }
inline void storeQ(Q2 q, double* p) {
  for (int i = 0; i < 4; ++i) p[i] = q.v[i];
}
inline Q2 splatQ(double a) { return {{a, a, a, a}}; }
inline Q2 operator+(Q2 a, Q2 b) { return {{a.v[0] + b.v[0], a.v[1] + b.v[1], a.v[2] + b.v[2], a.v[3] + b.v[3]}}; }
inline Q2 operator*(Q2 a, Q2 b) { return {{a.v[0] * b.v[0], a.v[1] * b.v[1], a.v[2] * b.v[2], a.v[3] * b.v[3]}}; }
inline Q2 keepW(Q2 u, Q2 old) { return {{u.v[0], u.v[1], u.v[2], old.v[3]}}; }
inline void loadPoints(const double* pos, const int* idx, D2& x, D2& y, D2& z, D2& w) {
  for (int k = 0; k < 2; ++k) {
    const double* p = pos + 4 * static_cast<std::ptrdiff_t>(idx[k]);
    x.v[k] = p[0];
    y.v[k] = p[1];
    z.v[k] = p[2];
    w.v[k] = p[3];
  }
}
inline void toQ4(D2 a, D2 b, D2 c, D2 d, Q2* out) {
  for (int k = 0; k < 2; ++k) out[k] = {{a.v[k], b.v[k], c.v[k], d.v[k]}};
}
inline void toQ(D2 x, D2 y, D2 z, Q2* out) { toQ4(x, y, z, splat(0.0), out); }
inline void fromQ(const Q2* in, D2& x, D2& y, D2& z) {
  for (int k = 0; k < 2; ++k) {
    x.v[k] = in[k].v[0];
    y.v[k] = in[k].v[1];
    z.v[k] = in[k].v[2];
  }
}
#endif

namespace lanes2 {
using Pack = D2;
using Mask = D2;
using Q = Q2;
#include "simplex_batch_kernel.inc"
}  // namespace lanes2

// ------------------------------------------------------------------------------------------------ four lanes (AVX2)

#if MSK_BATCH_AVX
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif
namespace lanes4 {
struct D4 {
  __m256d v;
};
inline D4 splat(double a) { return {_mm256_set1_pd(a)}; }
inline D4 loadu(const double* p) { return {_mm256_loadu_pd(p)}; }
inline void storeu(D4 a, double* out) { _mm256_storeu_pd(out, a.v); }
inline D4 operator+(D4 a, D4 b) { return {_mm256_add_pd(a.v, b.v)}; }
inline D4 operator-(D4 a, D4 b) { return {_mm256_sub_pd(a.v, b.v)}; }
inline D4 operator*(D4 a, D4 b) { return {_mm256_mul_pd(a.v, b.v)}; }
inline D4 operator/(D4 a, D4 b) { return {_mm256_div_pd(a.v, b.v)}; }
inline D4 vsqrt(D4 a) { return {_mm256_sqrt_pd(a.v)}; }
inline D4 vmax(D4 a, D4 b) { return {_mm256_max_pd(a.v, b.v)}; }
inline D4 vabs(D4 a) { return {_mm256_andnot_pd(_mm256_set1_pd(-0.0), a.v)}; }
inline D4 gt(D4 a, D4 b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_GT_OQ)}; }
inline D4 lt(D4 a, D4 b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_LT_OQ)}; }
inline D4 ge(D4 a, D4 b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_GE_OQ)}; }
inline D4 eq(D4 a, D4 b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_EQ_OQ)}; }
inline D4 notLe(D4 a, D4 b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_NLE_UQ)}; }
inline D4 operator&(D4 a, D4 b) { return {_mm256_and_pd(a.v, b.v)}; }
inline D4 operator|(D4 a, D4 b) { return {_mm256_or_pd(a.v, b.v)}; }
inline D4 operator~(D4 m) { return {_mm256_xor_pd(m.v, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)))}; }
inline D4 select(D4 m, D4 a, D4 b) { return {_mm256_blendv_pd(b.v, a.v, m.v)}; }
inline D4 flipSign(D4 a, D4 s) { return {_mm256_xor_pd(a.v, _mm256_and_pd(s.v, _mm256_set1_pd(-0.0)))}; }
inline int bits(D4 m) { return _mm256_movemask_pd(m.v); }
/// What the comparisons give: all-ones / all-zeros lanes.
using Mask = D4;
/// One particle's packed x, y, z, w (+ and · are the compilers' own vector arithmetic on __m256d).
using Q = __m256d;
inline Q loadQ(const double* p) { return _mm256_load_pd(p); }
inline void storeQ(Q q, double* p) { _mm256_store_pd(p, q); }
inline Q splatQ(double a) { return _mm256_set1_pd(a); }
/// x, y, z of `u`, w of `old`.
inline Q keepW(Q u, Q old) { return _mm256_blend_pd(u, old, 0x8); }
/// The x, y, z, w packs of the particles idx[0..3] of `pos` (four 32-byte rows transposed: loads of halves, unpacks).
inline void loadPoints(const double* pos, const int* idx, D4& x, D4& y, D4& z, D4& w) {
  const double* p0 = pos + 4 * static_cast<std::ptrdiff_t>(idx[0]);
  const double* p1 = pos + 4 * static_cast<std::ptrdiff_t>(idx[1]);
  const double* p2 = pos + 4 * static_cast<std::ptrdiff_t>(idx[2]);
  const double* p3 = pos + 4 * static_cast<std::ptrdiff_t>(idx[3]);
  const __m256d a = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p0)), _mm_load_pd(p2), 1);  // x0 y0 x2 y2
  const __m256d b = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p1)), _mm_load_pd(p3), 1);  // x1 y1 x3 y3
  const __m256d c = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p0 + 2)), _mm_load_pd(p2 + 2), 1);
  const __m256d d = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(p1 + 2)), _mm_load_pd(p3 + 2), 1);
  x.v = _mm256_unpacklo_pd(a, b);
  y.v = _mm256_unpackhi_pd(a, b);
  z.v = _mm256_unpacklo_pd(c, d);
  w.v = _mm256_unpackhi_pd(c, d);
}
/// out[k] = (a, b, c, d) of lane k.
inline void toQ4(D4 a, D4 b, D4 c, D4 d, Q* out) {
  const __m256d t0 = _mm256_unpacklo_pd(a.v, b.v), t1 = _mm256_unpackhi_pd(a.v, b.v);  // a0 b0 a2 b2, a1 b1 a3 b3
  const __m256d t2 = _mm256_unpacklo_pd(c.v, d.v), t3 = _mm256_unpackhi_pd(c.v, d.v);  // c0 d0 c2 d2, c1 d1 c3 d3
  out[0] = _mm256_permute2f128_pd(t0, t2, 0x20);
  out[1] = _mm256_permute2f128_pd(t1, t3, 0x20);
  out[2] = _mm256_permute2f128_pd(t0, t2, 0x31);
  out[3] = _mm256_permute2f128_pd(t1, t3, 0x31);
}
/// out[k] = (x, y, z, 0) of lane k.
inline void toQ(D4 x, D4 y, D4 z, Q* out) { toQ4(x, y, z, D4{_mm256_setzero_pd()}, out); }
/// Lane k of x, y, z: in[k]'s.
inline void fromQ(const Q* in, D4& x, D4& y, D4& z) {
  const __m256d a = _mm256_permute2f128_pd(in[0], in[2], 0x20), b = _mm256_permute2f128_pd(in[1], in[3], 0x20);
  const __m256d c = _mm256_permute2f128_pd(in[0], in[2], 0x31), d = _mm256_permute2f128_pd(in[1], in[3], 0x31);
  x.v = _mm256_unpacklo_pd(a, b);
  y.v = _mm256_unpackhi_pd(a, b);
  z.v = _mm256_unpacklo_pd(c, d);
}
/// How many particles ahead packParticles() and unpackParticles() prefetch their scattered places.
constexpr int kScatterAhead = 128;
/// Particles [begin, end) of the column arrays x, y, z, w into the packed copy `pos` (particle v's x, y, z, w at
/// 4 place[v], or 4v when not Scattered), four at a time; returns the first particle not done.
template <bool Scattered>
int packParticles(const double* x, const double* y, const double* z, const double* w, const int* place, double* pos,
                  int begin, int end) {
  int v = begin;
  for (; v + 4 <= end; v += 4) {
    if (Scattered && v + kScatterAhead + 4 <= end)  // ask for the scattered places' cache lines early
      for (int k = 0; k < 4; ++k)
        _mm_prefetch(reinterpret_cast<const char*>(pos + 4 * place[v + kScatterAhead + k]), _MM_HINT_T0);
    const __m256d X = _mm256_loadu_pd(x + v), Y = _mm256_loadu_pd(y + v), Z = _mm256_loadu_pd(z + v),
                  W = _mm256_loadu_pd(w + v);
    const __m256d t0 = _mm256_unpacklo_pd(X, Y), t1 = _mm256_unpackhi_pd(X, Y);  // x0 y0 x2 y2, x1 y1 x3 y3
    const __m256d t2 = _mm256_unpacklo_pd(Z, W), t3 = _mm256_unpackhi_pd(Z, W);  // z0 w0 z2 w2, z1 w1 z3 w3
    const int at[4] = {Scattered ? place[v] : v, Scattered ? place[v + 1] : v + 1, Scattered ? place[v + 2] : v + 2,
                       Scattered ? place[v + 3] : v + 3};
    _mm256_store_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[0]), _mm256_permute2f128_pd(t0, t2, 0x20));
    _mm256_store_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[1]), _mm256_permute2f128_pd(t1, t3, 0x20));
    _mm256_store_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[2]), _mm256_permute2f128_pd(t0, t2, 0x31));
    _mm256_store_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[3]), _mm256_permute2f128_pd(t1, t3, 0x31));
  }
  return v;
}
/// The packed copy's x, y, z of particles [begin, end) (at places place[v], or v when not Scattered) back into the
/// column arrays, four at a time; returns the first particle not done.
template <bool Scattered>
int unpackParticles(const double* pos, const int* place, double* x, double* y, double* z, int begin, int end) {
  int v = begin;
  for (; v + 4 <= end; v += 4) {
    if (Scattered && v + kScatterAhead + 4 <= end)
      for (int k = 0; k < 4; ++k)
        _mm_prefetch(reinterpret_cast<const char*>(pos + 4 * place[v + kScatterAhead + k]), _MM_HINT_T0);
    const int at[4] = {Scattered ? place[v] : v, Scattered ? place[v + 1] : v + 1, Scattered ? place[v + 2] : v + 2,
                       Scattered ? place[v + 3] : v + 3};
    const __m256d q0 = _mm256_load_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[0])),
                  q1 = _mm256_load_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[1])),
                  q2 = _mm256_load_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[2])),
                  q3 = _mm256_load_pd(pos + 4 * static_cast<std::ptrdiff_t>(at[3]));
    const __m256d a = _mm256_permute2f128_pd(q0, q2, 0x20), b = _mm256_permute2f128_pd(q1, q3, 0x20);
    const __m256d c = _mm256_permute2f128_pd(q0, q2, 0x31), d = _mm256_permute2f128_pd(q1, q3, 0x31);
    _mm256_storeu_pd(x + v, _mm256_unpacklo_pd(a, b));
    _mm256_storeu_pd(y + v, _mm256_unpackhi_pd(a, b));
    _mm256_storeu_pd(z + v, _mm256_unpacklo_pd(c, d));
  }
  return v;
}
}  // namespace lanes4

namespace lanes8 {
// Eight rows as two 4-lane (AVX2) packs in lockstep.
namespace half = lanes4;
using Half = lanes4::D4;
constexpr int kHalfLanes = 4;
// The pack of two halves (twin) comes before the kernel that runs on it.
// clang-format off
#include "simplex_batch_twin.inc"
#include "simplex_batch_kernel.inc"
// clang-format on
}  // namespace lanes8
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

// ---------------------------------------------------------------------------------------- eight lanes (AVX-512)

// Eight rows in one 512-bit pack, 32 vector registers (AVX-512 F, DQ, VL), chosen at run time like AVX2. Masks are
// kept in mask registers (one bit per lane; they only choose between values), and the same arithmetic runs lane by
// lane: no fused multiply-add (contraction off), so the results are bitwise those of the SSE2 and AVX2 paths.
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2,avx512f,avx512dq,avx512vl"))), apply_to = function)
#pragma clang fp contract(off)
#else
#pragma GCC push_options
#pragma GCC target("avx2,avx512f,avx512dq,avx512vl")
#pragma GCC optimize("fp-contract=off")
// GCC 12's AVX-512 intrinsics start from _mm512_undefined_pd(), which -Wmaybe-uninitialized reports at every use.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
namespace lanes16 {
struct D8 {
  [[maybe_unused]] static constexpr int lanes = 8;
  __m512d v;
};
inline __m512i bitsOf(D8 a) { return _mm512_castpd_si512(a.v); }
inline D8 fromBits(__m512i a) { return {_mm512_castsi512_pd(a)}; }
/// What the comparisons give: one bit per lane in a mask register (no move into a vector and back per test).
struct M8 {
  __mmask8 k;
};
using Mask = M8;
inline M8 operator&(M8 a, M8 b) { return {static_cast<__mmask8>(a.k & b.k)}; }
inline M8 operator|(M8 a, M8 b) { return {static_cast<__mmask8>(a.k | b.k)}; }
inline M8 operator~(M8 m) { return {static_cast<__mmask8>(~m.k)}; }
inline D8 splat(double a) { return {_mm512_set1_pd(a)}; }
inline D8 loadu(const double* p) { return {_mm512_loadu_pd(p)}; }
inline void storeu(D8 a, double* out) { _mm512_storeu_pd(out, a.v); }
inline D8 operator+(D8 a, D8 b) { return {_mm512_add_pd(a.v, b.v)}; }
inline D8 operator-(D8 a, D8 b) { return {_mm512_sub_pd(a.v, b.v)}; }
inline D8 operator*(D8 a, D8 b) { return {_mm512_mul_pd(a.v, b.v)}; }
inline D8 operator/(D8 a, D8 b) { return {_mm512_div_pd(a.v, b.v)}; }
inline D8 vsqrt(D8 a) { return {_mm512_sqrt_pd(a.v)}; }
inline D8 vmax(D8 a, D8 b) { return {_mm512_max_pd(a.v, b.v)}; }
inline D8 vabs(D8 a) { return fromBits(_mm512_andnot_si512(_mm512_set1_epi64(INT64_MIN), bitsOf(a))); }
inline M8 gt(D8 a, D8 b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_GT_OQ)}; }
inline M8 lt(D8 a, D8 b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_LT_OQ)}; }
inline M8 ge(D8 a, D8 b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_GE_OQ)}; }
inline M8 eq(D8 a, D8 b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_EQ_OQ)}; }
inline M8 notLe(D8 a, D8 b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_NLE_UQ)}; }
inline D8 select(M8 m, D8 a, D8 b) { return {_mm512_mask_blend_pd(m.k, b.v, a.v)}; }
inline D8 flipSign(D8 a, D8 s) {
  return fromBits(_mm512_xor_si512(bitsOf(a), _mm512_and_si512(bitsOf(s), _mm512_set1_epi64(INT64_MIN))));
}
inline int bits(M8 m) { return m.k; }
/// A pack from two 4-lane halves.
inline D8 join(lanes4::D4 l, lanes4::D4 h) {
  return {_mm512_shuffle_f64x2(_mm512_zextpd256_pd512(l.v), _mm512_zextpd256_pd512(h.v), 0x44)};
}
using lanes4::keepW;
using lanes4::loadQ;
using lanes4::Q;
using lanes4::splatQ;
using lanes4::storeQ;
/// The x, y, z, w packs of the particles idx[0..7] of `pos`: one 32-byte load per particle, two particles per
/// register (k and k + 2 of each group of four), then unpacks within 128-bit lanes and 128-bit lane shuffles (12
/// shuffles and 8 loads for 8 particles, half the loads of two 4-particle transposes).
inline void loadPoints(const double* pos, const int* idx, D8& x, D8& y, D8& z, D8& w) {
  auto pair = [pos](int a, int b) {  // particle a in the low half, b in the high half
    return _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(pos + 4 * static_cast<std::ptrdiff_t>(a))),
                              _mm256_load_pd(pos + 4 * static_cast<std::ptrdiff_t>(b)), 1);
  };
  const __m512d a = pair(idx[0], idx[2]), b = pair(idx[1], idx[3]);  // x0 y0 z0 w0 x2 y2 z2 w2, the same of 1, 3
  const __m512d c = pair(idx[4], idx[6]), d = pair(idx[5], idx[7]);
  const __m512d t0 = _mm512_unpacklo_pd(a, b), t1 = _mm512_unpackhi_pd(a, b);  // x0 x1 z0 z1 x2 x3 z2 z3, y.. w..
  const __m512d t2 = _mm512_unpacklo_pd(c, d), t3 = _mm512_unpackhi_pd(c, d);  // the same of 4 .. 7
  x.v = _mm512_shuffle_f64x2(t0, t2, 0x88);                                    // 128-bit lanes 0, 2 of t0, then of t2
  z.v = _mm512_shuffle_f64x2(t0, t2, 0xDD);                                    // lanes 1, 3
  y.v = _mm512_shuffle_f64x2(t1, t3, 0x88);
  w.v = _mm512_shuffle_f64x2(t1, t3, 0xDD);
}
/// out[k] = (a, b, c, d) of lane k: unpacks within 128-bit lanes, then two-register permutes that put lanes k and
/// k + 2 side by side (12 shuffles for 8 particles).
inline void toQ4(D8 a, D8 b, D8 c, D8 d, Q* out) {
  const __m512d t0 = _mm512_unpacklo_pd(a.v, b.v), t1 = _mm512_unpackhi_pd(a.v, b.v);  // a0 b0 a2 b2 .., a1 b1 ..
  const __m512d t2 = _mm512_unpacklo_pd(c.v, d.v), t3 = _mm512_unpackhi_pd(c.v, d.v);  // c0 d0 c2 d2 .., c1 d1 ..
  const __m512i first = _mm512_setr_epi64(0, 1, 8, 9, 2, 3, 10, 11);     // 128-bit lanes 0 of t0, t2, then lanes 1
  const __m512i second = _mm512_setr_epi64(4, 5, 12, 13, 6, 7, 14, 15);  // lanes 2, then 3
  const __m512d q02 = _mm512_permutex2var_pd(t0, first, t2), q46 = _mm512_permutex2var_pd(t0, second, t2);
  const __m512d q13 = _mm512_permutex2var_pd(t1, first, t3), q57 = _mm512_permutex2var_pd(t1, second, t3);
  out[0] = _mm512_castpd512_pd256(q02);
  out[1] = _mm512_castpd512_pd256(q13);
  out[2] = _mm512_extractf64x4_pd(q02, 1);
  out[3] = _mm512_extractf64x4_pd(q13, 1);
  out[4] = _mm512_castpd512_pd256(q46);
  out[5] = _mm512_castpd512_pd256(q57);
  out[6] = _mm512_extractf64x4_pd(q46, 1);
  out[7] = _mm512_extractf64x4_pd(q57, 1);
}
/// out[k] = (x, y, z, 0) of lane k.
inline void toQ(D8 x, D8 y, D8 z, Q* out) { toQ4(x, y, z, D8{_mm512_setzero_pd()}, out); }
inline void fromQ(const Q* in, D8& x, D8& y, D8& z) {
  lanes4::D4 xl, yl, zl, xh, yh, zh;
  lanes4::fromQ(in, xl, yl, zl);
  lanes4::fromQ(in + 4, xh, yh, zh);
  x = join(xl, xh);
  y = join(yl, yh);
  z = join(zl, zh);
}
}  // namespace lanes16

namespace lanes32 {
// Sixteen rows as two 8-lane (AVX-512) packs in lockstep.
namespace half = lanes16;
using Half = lanes16::D8;
constexpr int kHalfLanes = 8;
// The pack of two halves (twin) comes before the kernel that runs on it.
// clang-format off
#include "simplex_batch_twin.inc"
#include "simplex_batch_kernel.inc"
// clang-format on
}  // namespace lanes32
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC diagnostic pop
#pragma GCC pop_options
#endif

/// Whether this processor (and its operating system) runs AVX2.
bool avxAvailable() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
}

/// Whether this processor (and its operating system) runs AVX-512 F, DQ and VL.
bool avx512Available() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl");
}
#else
bool avxAvailable() { return false; }
bool avx512Available() { return false; }
#endif

/// Sets `buffer` to n zeros, asking the kernel (Linux) for 2 MB pages over it before the first touch where it is large:
/// the sweeps' neighbour loads land on random pages, and 4 KB pages miss the TLB beyond a few megabytes.
void zeroFilled(std::vector<double>& buffer, size_t n) {
  buffer.clear();
  buffer.shrink_to_fit();
  buffer.reserve(n);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  const std::uintptr_t huge = std::uintptr_t(2) << 20, at = reinterpret_cast<std::uintptr_t>(buffer.data());
  const std::uintptr_t lo = (at + huge - 1) & ~(huge - 1), hi = (at + n * sizeof(double)) & ~(huge - 1);
  if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);  // advice only: failure is harmless
#endif
  buffer.assign(n, 0.0);
}

/// Rows from which projectColours() and jacobiEqualSharesPacked() go chunk by chunk: below, the working copy (32 bytes
/// a particle) and the Jacobi records (64 bytes a row) fit in the L2 cache of current processors anyway.
constexpr int kChunkedFrom = 32768;

/// A breadth-first (Cuthill–McKee; every degree is 3) order of the graph of `nb`, component by component, each from a
/// pseudo-peripheral vertex (the last one reached from the component's lowest vertex): place → vertex. Neighbours end
/// up at most about two breadth-first rings apart, O(√n) places on a closed surface, whatever the input numbering.
std::vector<int> breadthFirstOrder(const NeighborTable& nb) {
  const int n = static_cast<int>(nb.rows());
  std::vector<int> order;
  order.reserve(static_cast<size_t>(n));
  std::vector<std::uint8_t> seen(static_cast<size_t>(n), 0);
  auto reach = [&](int start) {  // appends the component of `start`
    size_t head = order.size();
    order.push_back(start);
    seen[static_cast<size_t>(start)] = 1;
    for (; head < order.size(); ++head) {
      const int v = order[head];
      for (int j = 0; j < 3; ++j) {
        const int u = nb(v, j);
        if (!seen[static_cast<size_t>(u)]) {
          seen[static_cast<size_t>(u)] = 1;
          order.push_back(u);
        }
      }
    }
  };
  for (int v = 0; v < n; ++v) {
    if (seen[static_cast<size_t>(v)]) continue;
    const size_t mark = order.size();
    reach(v);
    const int far = order.back();
    for (size_t i = mark; i < order.size(); ++i) seen[static_cast<size_t>(order[i])] = 0;
    order.resize(mark);
    reach(far);
  }
  return order;
}

}  // namespace

SimplexInternalBatch::SimplexInternalBatch(const SimplexMesh& reference, double gamma, BatchOrder order)
    : gamma_(gamma) {
  checkUnitInterval("internal stiffness", gamma);
  Eigen::MatrixX3d eps;
  Eigen::VectorXd hOverR;
  simplexReferenceParameters(reference, eps, hOverR);
  build(reference.neighbors, eps, hOverR, order);
}

SimplexInternalBatch::SimplexInternalBatch(const NeighborTable& nb, const Eigen::MatrixX3d& eps,
                                           const Eigen::VectorXd& hOverR, double gamma, BatchOrder order)
    : gamma_(gamma) {
  checkUnitInterval("internal stiffness", gamma);
  build(nb, eps, hOverR, order);
}

void SimplexInternalBatch::build(const NeighborTable& nb, const Eigen::MatrixX3d& eps, const Eigen::VectorXd& hOverR,
                                 BatchOrder order) {
  const int n = static_cast<int>(nb.rows());
  MSK_ASSERT(nb.cols() == 3 && eps.rows() == n && hOverR.size() == n, "simplex internal batch: size mismatch");
  for (int v = 0; v < n; ++v)
    for (int j = 0; j < 3; ++j) MSK_ASSERT(nb(v, j) >= 0 && nb(v, j) < n, "neighbour index out of range");
  const size_t un = static_cast<size_t>(n);
  orderKind_ = order;
  if (order == BatchOrder::Locality && n >= kChunkedFrom) {  // smaller sets fit in L2 in any order
    vertexAt_ = breadthFirstOrder(nb);
  } else {
    vertexAt_.resize(un);
    for (int v = 0; v < n; ++v) vertexAt_[static_cast<size_t>(v)] = v;
  }
  placeOf_.resize(un);
  scattered_ = false;
  for (size_t i = 0; i < un; ++i) {
    placeOf_[static_cast<size_t>(vertexAt_[i])] = static_cast<int>(i);
    scattered_ = scattered_ || vertexAt_[i] != static_cast<int>(i);
  }
  // The Solver's colouring of the same rows (its particles: the vertex, then its neighbours), each colour's rows
  // then taken in the batch's order (they share no particle, so their order changes nothing).
  const Colouring col = colourConstraints(n, 4, [&nb](int r, int* out) {
    out[0] = r;
    for (int j = 0; j < 3; ++j) out[j + 1] = nb(r, j);
    return 4;
  });
  colourStart_ = col.start;
  if (colourStart_.empty()) colourStart_.push_back(0);
  corder_.resize(un);
  for (size_t i = 0; i < un; ++i) corder_[i] = placeOf_[static_cast<size_t>(col.order[i])];
  for (size_t k = 0; k + 1 < colourStart_.size(); ++k)
    std::sort(corder_.begin() + colourStart_[k], corder_.begin() + colourStart_[k + 1]);
  order_.resize(un);
  for (size_t i = 0; i < un; ++i) order_[i] = vertexAt_[static_cast<size_t>(corder_[i])];
  // Wavefront chunks (projectColours()): longer than twice the largest place distance between a row and one of its
  // particles (so rows sharing a particle are at most one chunk apart), and at least 4096 places (fewer part-filled
  // packs at the chunks' ends).
  int reach = 0;
  for (int v = 0; v < n; ++v)
    for (int j = 0; j < 3; ++j)
      reach = std::max(reach, std::abs(placeOf_[static_cast<size_t>(v)] - placeOf_[static_cast<size_t>(nb(v, j))]));
  waveChunk_ = std::max(2 * reach + 1, 4096);
  const int chunks = (n + waveChunk_ - 1) / waveChunk_;
  waveStart_.clear();
  for (size_t k = 0; k + 1 < colourStart_.size(); ++k)
    for (int j = 0; j <= chunks; ++j) {
      const auto first = corder_.begin() + colourStart_[k], last = corder_.begin() + colourStart_[k + 1];
      waveStart_.push_back(static_cast<int>(std::lower_bound(first, last, j * waveChunk_) - corder_.begin()));
    }
  nb0_.resize(un);
  nb1_.resize(un);
  nb2_.resize(un);
  eps0_.resize(un);
  eps1_.resize(un);
  eps2_.resize(un);
  hr_.resize(un);
  for (size_t i = 0; i < un; ++i) {
    const int v = vertexAt_[i];
    nb0_[i] = placeOf_[static_cast<size_t>(nb(v, 0))];
    nb1_[i] = placeOf_[static_cast<size_t>(nb(v, 1))];
    nb2_[i] = placeOf_[static_cast<size_t>(nb(v, 2))];
    eps0_[i] = eps(v, 0);
    eps1_[i] = eps(v, 1);
    eps2_[i] = eps(v, 2);
    hr_[i] = hOverR[v];
  }
  // The same rows in colour order, for the Gauss–Seidel sweeps (contiguous loads there too).
  for (auto* a : {&cnb0_, &cnb1_, &cnb2_}) a->resize(un);
  for (auto* a : {&ceps0_, &ceps1_, &ceps2_, &chr_}) a->resize(un);
  for (size_t i = 0; i < un; ++i) {
    const size_t r = static_cast<size_t>(corder_[i]);
    cnb0_[i] = nb0_[r];
    cnb1_[i] = nb1_[r];
    cnb2_[i] = nb2_[r];
    ceps0_[i] = eps0_[r];
    ceps1_[i] = eps1_[r];
    ceps2_[i] = eps2_[r];
    chr_[i] = hr_[r];
  }
  zeroFilled(pos_, 4 * un + 8);
  zeroFilled(d_, 8 * un + 8);
  // Rows touching each particle (CSR), in mesh order first: for each particle, its rows (own row slot 0, rows naming
  // it as a neighbour slot j + 1) by ascending row vertex. Then the same lists at the particles' places, rows as
  // places: the terms of every particle's sum keep the mesh order whatever the batch's order.
  std::vector<int> meshStart(un + 1, 0), meshCode;
  for (int v = 0; v < n; ++v) {
    ++meshStart[static_cast<size_t>(v) + 1];
    for (int j = 0; j < 3; ++j) ++meshStart[static_cast<size_t>(nb(v, j)) + 1];
  }
  for (size_t v = 0; v < un; ++v) meshStart[v + 1] += meshStart[v];
  meshCode.resize(static_cast<size_t>(meshStart[un]));
  {
    std::vector<int> fill(meshStart.begin(), meshStart.end() - 1);
    for (int v = 0; v < n; ++v)
      for (int slot = 0; slot < 4; ++slot) {
        const int j = slot == 0 ? v : nb(v, slot - 1);
        meshCode[static_cast<size_t>(fill[static_cast<size_t>(j)]++)] = 4 * v + slot;
      }
  }
  revStart_.assign(un + 1, 0);
  revFlat_.resize(meshCode.size());
  revRow_.resize(meshCode.size());
  for (size_t i = 0; i < un; ++i) {
    const size_t v = static_cast<size_t>(vertexAt_[i]);
    int at = revStart_[i];
    for (int e = meshStart[v]; e < meshStart[v + 1]; ++e, ++at) {
      const int code = meshCode[static_cast<size_t>(e)], row = placeOf_[static_cast<size_t>(code >> 2)];
      revRow_[static_cast<size_t>(at)] = row;
      revFlat_[static_cast<size_t>(at)] = 8 * row + 4 + (code & 3);
    }
    revStart_[i + 1] = at;
  }
  uniform4_ = true;
  for (size_t i = 0; i < un; ++i) uniform4_ = uniform4_ && revStart_[i + 1] - revStart_[i] == 4;
  if (uniform4_) {  // entry-major copies: entry e of places i .. i + 3 contiguous
    tFlat_.resize(4 * un);
    for (size_t i = 0; i < un; ++i)
      for (size_t e = 0; e < 4; ++e) tFlat_[e * un + i] = revFlat_[static_cast<size_t>(revStart_[i]) + e];
  }
  // Fused Jacobi (jacobiEqualSharesPacked()): chunks of a power of two ≥ the largest row-particle place distance, so a
  // particle's rows lie in its chunk or the next one either side; their records in a ring of 4 chunks.
  ringChunk_ = 512;
  while (ringChunk_ < reach) ringChunk_ *= 2;
  ring_.clear();
  next_.clear();
  if (uniform4_) {
    tRing_.resize(4 * un);
    const int mask = 4 * ringChunk_ - 1;
    for (size_t i = 0; i < 4 * un; ++i) tRing_[i] = ((tFlat_[i] >> 3) & mask) * 8 + (tFlat_[i] & 7);
  }
  kept_.assign(un, 0);
  useLanes(BatchLanes::Avx512);
}

void SimplexInternalBatch::useWideLanes(bool on) { useLanes(on ? BatchLanes::Avx512 : BatchLanes::Sse2); }

void SimplexInternalBatch::useLanes(BatchLanes widest) {
  lanes_ = BatchLanes::Sse2;
  if (widest != BatchLanes::Sse2 && avxAvailable()) lanes_ = BatchLanes::Avx2;
  if (widest == BatchLanes::Avx512 && avx512Available()) lanes_ = BatchLanes::Avx512;
}

void SimplexInternalBatch::checkSizes(const Points& p, const Eigen::VectorXd& w) const {
  MSK_ASSERT(first_ >= 0 && p.rows() >= first_ + size() && w.size() == p.rows(),
             "simplex internal batch: size mismatch");
}

void SimplexInternalBatch::checkRange(int begin, int end) const {
  MSK_ASSERT(begin >= 0 && begin <= end && end <= size(), "simplex internal batch: bad row range");
}

double* SimplexInternalBatch::aligned(std::vector<double>& buffer) {
  const auto at = reinterpret_cast<std::uintptr_t>(buffer.data());
  return buffer.data() + ((64 - at % 64) % 64) / sizeof(double);
}

const double* SimplexInternalBatch::aligned(const std::vector<double>& buffer) {
  return aligned(const_cast<std::vector<double>&>(buffer));
}

void SimplexInternalBatch::loadRange(const Points& p, const Eigen::VectorXd& w, int begin, int end) {
  checkSizes(p, w);
  checkRange(begin, end);
  const double* x = p.data() + first_;
  const double* y = x + p.rows();
  const double* z = y + p.rows();
  const double* wv = w.data() + first_;
  double* q = aligned(pos_);
  const int* place = placeOf_.data();
  int v = begin;
#if MSK_BATCH_AVX
  if (lanes_ != BatchLanes::Sse2)
    v = scattered_ ? lanes4::packParticles<true>(x, y, z, wv, place, q, begin, end)
                   : lanes4::packParticles<false>(x, y, z, wv, place, q, begin, end);
#endif
  for (; v < end; ++v) {
    double* at = q + 4 * static_cast<std::ptrdiff_t>(place[v]);
    at[0] = x[v];
    at[1] = y[v];
    at[2] = z[v];
    at[3] = wv[v];
  }
}

void SimplexInternalBatch::storeRange(Points& p, int begin, int end) const {
  MSK_ASSERT(first_ >= 0 && p.rows() >= first_ + size(), "simplex internal batch: size mismatch");
  checkRange(begin, end);
  double* x = p.data() + first_;
  double* y = x + p.rows();
  double* z = y + p.rows();
  const double* q = aligned(pos_);
  const int* place = placeOf_.data();
  int v = begin;
#if MSK_BATCH_AVX
  if (lanes_ != BatchLanes::Sse2)
    v = scattered_ ? lanes4::unpackParticles<true>(q, place, x, y, z, begin, end)
                   : lanes4::unpackParticles<false>(q, place, x, y, z, begin, end);
#endif
  for (; v < end; ++v) {
    const double* at = q + 4 * static_cast<std::ptrdiff_t>(place[v]);
    x[v] = at[0];
    y[v] = at[1];
    z[v] = at[2];
  }
}

namespace {
BatchArrays arraysOf(double* pos, const std::vector<int>& order, const std::vector<int>& n0, const std::vector<int>& n1,
                     const std::vector<int>& n2, const std::vector<double>& e0, const std::vector<double>& e1,
                     const std::vector<double>& e2, const std::vector<double>& hr) {
  return BatchArrays{pos, order.data(), n0.data(), n1.data(), n2.data(), e0.data(), e1.data(), e2.data(), hr.data()};
}
}  // namespace

int SimplexInternalBatch::projectRange(int begin, int end) {
  checkRange(begin, end);
  const BatchArrays a = arraysOf(aligned(pos_), corder_, cnb0_, cnb1_, cnb2_, ceps0_, ceps1_, ceps2_, chr_);
#if MSK_BATCH_AVX
  if (lanes_ == BatchLanes::Avx512) return lanes32::projectRows(a, gamma_, begin, end);
  if (lanes_ == BatchLanes::Avx2) return lanes8::projectRows(a, gamma_, begin, end);
#endif
  return lanes2::projectRows(a, gamma_, begin, end);
}

int SimplexInternalBatch::projectColours() {
  if (size() < kChunkedFrom) {  // the working copy stays in cache anyway: whole colours, no part-filled packs
    int skipped = 0;
    for (int k = 0; k < colours(); ++k) skipped += projectRange(colourBegin(k), colourBegin(k + 1));
    return skipped;
  }
  const int chunks = (size() + waveChunk_ - 1) / waveChunk_, k1 = colours();
  const int* start = waveStart_.data();
  int skipped = 0;
  for (int step = 0; step < chunks + k1 - 1; ++step)
    for (int k = std::max(0, step - chunks + 1); k < k1 && k <= step; ++k) {
      const int* at = start + static_cast<std::ptrdiff_t>(k) * (chunks + 1) + (step - k);
      if (at[1] > at[0]) skipped += projectRange(at[0], at[1]);
    }
  return skipped;
}

int SimplexInternalBatch::colouredSweep(Points& p, const Eigen::VectorXd& w) {
  loadRange(p, w, 0, size());
  const int skipped = projectColours();
  storeRange(p, 0, size());
  return skipped;
}

int SimplexInternalBatch::computeRange(int begin, int end) {
  checkRange(begin, end);
  const BatchArrays a = arraysOf(aligned(pos_), corder_, nb0_, nb1_, nb2_, eps0_, eps1_, eps2_, hr_);
  const JacobiOut o{aligned(d_), kept_.data()};
#if MSK_BATCH_AVX
  if (lanes_ == BatchLanes::Avx512) return lanes32::computeRows(a, gamma_, begin, end, o);
  if (lanes_ == BatchLanes::Avx2) return lanes8::computeRows(a, gamma_, begin, end, o);
#endif
  return lanes2::computeRows(a, gamma_, begin, end, o);
}

void SimplexInternalBatch::addCounts(const Eigen::VectorXd& w, Eigen::VectorXi& counts) const {
  MSK_ASSERT(counts.size() == w.size() && first_ >= 0 && w.size() >= first_ + size(),
             "simplex internal batch: size mismatch");
  const double* wv = w.data() + first_;
  int* cnt = counts.data() + first_;
  const std::uint8_t* kept = kept_.data();
  const int* row = revRow_.data();
  const int* vertex = vertexAt_.data();
  if (uniform4_) {
    const int* t = tFlat_.data();  // row = flat / 8
    const int n = size();
    for (int i = 0; i < n; ++i) {
      const int k = kept[t[i] >> 3] + kept[t[n + i] >> 3] + kept[t[2 * n + i] >> 3] + kept[t[3 * n + i] >> 3];
      const int v = vertex[i];
      cnt[v] += wv[v] > 0 ? k : 0;
    }
    return;
  }
  for (int i = 0; i < size(); ++i) {
    const int v = vertex[i];
    if (!(wv[v] > 0)) continue;
    int k = 0;
    for (int e = revStart_[static_cast<size_t>(i)]; e < revStart_[static_cast<size_t>(i) + 1]; ++e) k += kept[row[e]];
    cnt[v] += k;
  }
}

void SimplexInternalBatch::scaleRange(const Eigen::VectorXi& counts, double omega, int begin, int end) {
  MSK_ASSERT(first_ >= 0 && counts.size() >= first_ + size(), "simplex internal batch: size mismatch");
  MSK_ASSERT(begin >= 0 && begin <= end && end <= size(), "simplex internal batch: bad row range");
  const int* cnt = counts.data() + first_;
  // ω / m for the usual counts m (a closed 2-simplex mesh alone gives 4), a division beyond.
  double share[9];
  for (int m = 0; m < 9; ++m) share[m] = omega / std::max(m, 1);
  double* d = aligned(d_);
  const int* vertex = vertexAt_.data();
  for (int i = begin; i < end; ++i) {
    const size_t r = static_cast<size_t>(i);
    const int most =
        std::max(std::max(cnt[vertex[i]], cnt[vertex[nb0_[r]]]), std::max(cnt[vertex[nb1_[r]]], cnt[vertex[nb2_[r]]]));
    const double scale = most < 9 ? share[most] : omega / most;  // skipped rows carry zero corrections
    d[8 * r] *= scale;
    d[8 * r + 1] *= scale;
    d[8 * r + 2] *= scale;
  }
}

void SimplexInternalBatch::applyScaled(Points& p, int begin, int end, double post) const {
  MSK_ASSERT(first_ >= 0 && p.rows() >= first_ + size(), "simplex internal batch: size mismatch");
  MSK_ASSERT(begin >= 0 && begin <= end && end <= size(), "simplex internal batch: bad particle range");
  double* x = p.data() + first_;
  double* y = x + p.rows();
  double* z = y + p.rows();
  const double* d = aligned(d_);
  const JacobiView j{static_cast<std::ptrdiff_t>(size()), tFlat_.data(), d, post,
                     scattered_ ? vertexAt_.data() : nullptr};
  int v = begin;
  if (uniform4_) {
#if MSK_BATCH_AVX
    v = lanes_ == BatchLanes::Avx512 ? lanes32::applyParticles(j, x, y, z, begin, end)
        : lanes_ == BatchLanes::Avx2 ? lanes8::applyParticles(j, x, y, z, begin, end)
                                     : lanes2::applyParticles(j, x, y, z, begin, end);
#else
    v = lanes2::applyParticles(j, x, y, z, begin, end);
#endif
  }
  for (; v < end; ++v) {
    double ax = 0, ay = 0, az = 0;
    for (int e = revStart_[static_cast<size_t>(v)]; e < revStart_[static_cast<size_t>(v) + 1]; ++e) {
      const size_t r = static_cast<size_t>(revRow_[static_cast<size_t>(e)]);
      const double c = d[revFlat_[static_cast<size_t>(e)]];
      ax += c * d[8 * r];
      ay += c * d[8 * r + 1];
      az += c * d[8 * r + 2];
    }
    const int at = vertexAt_[static_cast<size_t>(v)];
    x[at] += post * ax;
    y[at] += post * ay;
    z[at] += post * az;
  }
}

void SimplexInternalBatch::applyRange(Points& p, int begin, int end) const { applyScaled(p, begin, end, 1.0); }

bool SimplexInternalBatch::equalShares(const Eigen::VectorXd& w) const {
  MSK_ASSERT(first_ >= 0 && w.size() >= first_ + size(), "simplex internal batch: size mismatch");
  if (!uniform4_) return false;
  // Called once per Jacobi iteration: blocks of branch-free (vectorisable) tests, leaving at the first failing block.
  const double* wv = w.data() + first_;
  const int n = size();
  for (int b = 0; b < n; b += 1024) {
    bool all = true;
    for (int v = b, e = std::min(n, b + 1024); v < e; ++v) all &= wv[v] > 0;
    if (!all) return false;
  }
  return true;
}

void SimplexInternalBatch::applyEqualShares(Points& p, double omega, int begin, int end) const {
  applyScaled(p, begin, end, omega / 4);
}

void SimplexInternalBatch::applyEqualSharesPacked(double omega, int begin, int end) {
  MSK_ASSERT(uniform4_, "simplex internal batch: equal shares need every particle in 4 rows");
  checkRange(begin, end);
  const JacobiView j{static_cast<std::ptrdiff_t>(size()), tFlat_.data(), aligned(d_), omega / 4, vertexAt_.data()};
  double* pos = aligned(pos_);
#if MSK_BATCH_AVX
  if (lanes_ == BatchLanes::Avx512) return lanes32::applyParticlesPacked(j, pos, pos, begin, end);
  if (lanes_ == BatchLanes::Avx2) return lanes8::applyParticlesPacked(j, pos, pos, begin, end);
#endif
  lanes2::applyParticlesPacked(j, pos, pos, begin, end);
}

int SimplexInternalBatch::jacobiEqualSharesPacked(double omega) {
  MSK_ASSERT(uniform4_, "simplex internal batch: equal shares need every particle in 4 rows");
  const int n = size(), chunk = ringChunk_, chunks = (n + chunk - 1) / chunk;
  if (n < kChunkedFrom) {  // the records stay in cache anyway: the two passes, in place
    const int skipped = computeRange(0, n);
    if (skipped == 0) applyEqualSharesPacked(omega, 0, n);
    return skipped;
  }
  // Row r's record at r mod 4·chunk: min(4·chunk, n) records.
  if (ring_.empty()) zeroFilled(ring_, 8 * static_cast<size_t>(std::min(4 * chunk, n)) + 8);
  if (next_.size() != pos_.size()) zeroFilled(next_, pos_.size());
  double* ring = aligned(ring_);
  const double* src = aligned(pos_);
  double* dst = aligned(next_);
  const BatchArrays a = arraysOf(aligned(pos_), corder_, nb0_, nb1_, nb2_, eps0_, eps1_, eps2_, hr_);
  const JacobiView view{static_cast<std::ptrdiff_t>(n), tRing_.data(), ring, omega / 4, vertexAt_.data()};
  const BatchLanes lanes = lanes_;
  for (int c = 0; c <= chunks; ++c) {
    if (c < chunks) {  // the rows of chunk c into ring slot c mod 4
      const int lo = c * chunk, hi = std::min(n, lo + chunk);
      const JacobiOut o{ring + 8 * static_cast<std::ptrdiff_t>(c % 4) * chunk, kept_.data(), lo};
      int skipped;
#if MSK_BATCH_AVX
      if (lanes == BatchLanes::Avx512)
        skipped = lanes32::computeRows(a, gamma_, lo, hi, o);
      else if (lanes == BatchLanes::Avx2)
        skipped = lanes8::computeRows(a, gamma_, lo, hi, o);
      else
        skipped = lanes2::computeRows(a, gamma_, lo, hi, o);
#else
      skipped = lanes2::computeRows(a, gamma_, lo, hi, o);
#endif
      if (skipped > 0) return computeRange(0, n);  // counts needed: nothing applied, every row as computeRange()
    }
    if (c > 0) {  // the particles of chunk c − 1: their rows lie in chunks c − 2 .. c
      const int lo = (c - 1) * chunk, hi = std::min(n, lo + chunk);
#if MSK_BATCH_AVX
      if (lanes == BatchLanes::Avx512)
        lanes32::applyParticlesPacked(view, src, dst, lo, hi);
      else if (lanes == BatchLanes::Avx2)
        lanes8::applyParticlesPacked(view, src, dst, lo, hi);
      else
        lanes2::applyParticlesPacked(view, src, dst, lo, hi);
#else
      lanes2::applyParticlesPacked(view, src, dst, lo, hi);
#endif
    }
  }
  pos_.swap(next_);
  return 0;
}

int SimplexInternalBatch::jacobiSweep(Points& p, const Eigen::VectorXd& w, double omega) {
  loadRange(p, w, 0, size());
  // Every row kept and every particle free: each particle is counted in exactly its 4 rows, so every share is ω/4
  // (large sets: computed and applied in the packed copy, bitwise as applyEqualShares() into p).
  const bool equal = equalShares(w), fused = equal && size() >= kChunkedFrom;
  const int skipped = fused ? jacobiEqualSharesPacked(omega) : computeRange(0, size());
  if (skipped == 0 && fused) {
    storeRange(p, 0, size());
  } else if (skipped == 0 && equal) {
    applyEqualShares(p, omega, 0, size());
  } else {
    ownCounts_.setZero(w.size());
    addCounts(w, ownCounts_);
    scaleRange(ownCounts_, omega, 0, size());
    applyRange(p, 0, size());
  }
  return skipped;
}

}  // namespace msk
