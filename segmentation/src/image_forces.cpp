#include "msk/segmentation/image_forces.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>

#include "msk/core/error.h"
#include "msk/imaging/filters.h"
#include "parallel_each.h"

namespace msk {

const char* polarityName(Polarity p) {
  switch (p) {
    case Polarity::Auto:
      return "auto";
    case Polarity::DarkInside:
      return "dark-inside";
    case Polarity::BrightInside:
      return "bright-inside";
  }
  return "?";
}

namespace {

/// A gradient lobe ends at a dip once the derivative climbs again by this fraction of the peak.
constexpr double kLobeDip = 0.1;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Tolerance (voxels) by which a sample may lie beyond the first/last voxel centre (as sampleTrilinear).
constexpr double kInsideTolVoxels = 1e-9;
/// Upper bound on samples per search line (guards against absurd range/step ratios).
constexpr int kMaxHalfSamples = 100000;
/// Profiles (normalised intensities) whose centred norm is below this per sample count as flat.
constexpr double kFlatTol = 1e-6;

/// Trilinear sampling along straight lines p + s·n, equivalent to sampleTrilinear but with the world→voxel map
/// applied once per line: voxel coordinates are affine in s, so each sample costs one interpolation.
class LineSampler {
 public:
  /// Binds the sampler to `image` (kept by reference).
  explicit LineSampler(const ImageF& image) : image_(image) {
    const Grid& g = image.grid;
    worldToVoxel_ = g.spacing.cwiseInverse().asDiagonal() * g.direction.transpose();
    for (int a = 0; a < 3; ++a) upper_[a] = g.dims[a] - 1;
  }
  /// Starts the line through `pointMm` along `directionMm` (world, per mm of s).
  void setLine(const Eigen::Vector3d& pointMm, const Eigen::Vector3d& directionMm) {
    start_ = worldToVoxel_ * (pointMm - image_.grid.origin);
    delta_ = worldToVoxel_ * directionMm;
    // The interval of s inside the voxel-centre hull, so the per-sample test is one comparison.
    sLow_ = -std::numeric_limits<double>::infinity();
    sHigh_ = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      const double lo = -kInsideTolVoxels - start_[a], hi = upper_[a] + kInsideTolVoxels - start_[a];
      if (delta_[a] == 0) {
        if (!(lo <= 0 && hi >= 0)) sLow_ = std::numeric_limits<double>::infinity();
        continue;
      }
      const double s0 = lo / delta_[a], s1 = hi / delta_[a];
      sLow_ = std::max(sLow_, std::min(s0, s1));
      sHigh_ = std::min(sHigh_, std::max(s0, s1));
    }
    if (!start_.allFinite() || !delta_.allFinite()) sLow_ = std::numeric_limits<double>::infinity();
  }
  /// Intensity at p + s·n; NaN outside the grid's voxel-centre hull or where the image is not finite.
  double at(double s) const {
    const Grid& g = image_.grid;
    int i0[3], i1[3];
    double t[3];
    if (!(s >= sLow_ && s <= sHigh_)) return kNaN;
    for (int a = 0; a < 3; ++a) {
      const double v = std::clamp(start_[a] + s * delta_[a], 0.0, upper_[a]);
      i0[a] = std::min(static_cast<int>(v), std::max(g.dims[a] - 2, 0));
      i1[a] = std::min(i0[a] + 1, g.dims[a] - 1);
      t[a] = v - i0[a];
    }
    const size_t sx = static_cast<size_t>(i1[0] - i0[0]);
    const size_t sy = static_cast<size_t>(g.dims[0]) * static_cast<size_t>(i1[1] - i0[1]);
    const size_t sz =
        static_cast<size_t>(g.dims[0]) * static_cast<size_t>(g.dims[1]) * static_cast<size_t>(i1[2] - i0[2]);
    const float* c = image_.data.data() + g.index(i0[0], i0[1], i0[2]);
    const double c00 = c[0] + t[0] * (double(c[sx]) - c[0]);
    const double c10 = c[sy] + t[0] * (double(c[sy + sx]) - c[sy]);
    const double c01 = c[sz] + t[0] * (double(c[sz + sx]) - c[sz]);
    const double c11 = c[sz + sy] + t[0] * (double(c[sz + sy + sx]) - c[sz + sy]);
    const double c0 = c00 + t[1] * (c10 - c00), c1 = c01 + t[1] * (c11 - c01);
    const double value = c0 + t[2] * (c1 - c0);
    return std::isfinite(value) ? value : kNaN;
  }

 private:
  const ImageF& image_;
  Eigen::Matrix3d worldToVoxel_;
  Eigen::Vector3d start_ = Eigen::Vector3d::Zero(), delta_ = Eigen::Vector3d::Zero();
  double upper_[3] = {0, 0, 0};
  double sLow_ = 0, sHigh_ = -1;  // empty until setLine
};

/// Search lengths resolved against the voxel size (user input kept apart from derived values).
struct ResolvedSearch {
  double rangeMm = 0;  ///< ±range along the normal
  double stepMm = 0;   ///< sample spacing along the normal
  int halfSearch = 0;  ///< offsets −halfSearch..halfSearch (× step)
};

/// Throws ParameterError unless `value` is finite and ≥ 0.
void requireNonNegative(const char* name, double value) {
  if (!(std::isfinite(value) && value >= 0))
    throw ParameterError(name, std::to_string(value), "must be finite and ≥ 0");
}

/// Number of steps of `stepMm` in `lengthMm` (at least 1), bounded.
int stepsIn(const char* name, double lengthMm, double stepMm) {
  const double n = std::round(lengthMm / stepMm);
  if (!(n <= kMaxHalfSamples))
    throw ParameterError(name, std::to_string(lengthMm), "is more than " + std::to_string(kMaxHalfSamples) + " steps");
  return std::max(1, static_cast<int>(n));
}

/// Default step: 0.25 × the smallest voxel spacing of `grid`.
double resolveStep(const TargetSearchOptions& opts, const Grid& grid) {
  requireNonNegative("stepMm", opts.stepMm);
  const double step = opts.stepMm > 0 ? opts.stepMm : 0.25 * grid.spacing.minCoeff();
  if (!(std::isfinite(step) && step > 0)) throw ParameterError("grid.spacing", std::to_string(step), "must be > 0");
  return step;
}

/// Validates the options and resolves range and step against the voxel size of `grid`.
ResolvedSearch resolveSearch(const TargetSearchOptions& opts, const Grid& grid, double stepMm) {
  requireNonNegative("rangeMm", opts.rangeMm);
  requireNonNegative("distancePenalty", opts.distancePenalty);
  if (opts.regularisationRings < 0)
    throw ParameterError("regularisationRings", std::to_string(opts.regularisationRings), "must be ≥ 0");
  ResolvedSearch r;
  r.stepMm = stepMm;
  r.rangeMm = opts.rangeMm > 0 ? opts.rangeMm : 4.0 * grid.spacing.maxCoeff();
  r.halfSearch = stepsIn("rangeMm", r.rangeMm, r.stepMm);
  return r;
}

/// Unit normal of row `v`, or false if the normal is zero or not finite.
bool unitNormal(const Points& normals, Eigen::Index v, Eigen::Vector3d& n) {
  n = normals.row(v).transpose();
  const double len = n.norm();
  if (!(std::isfinite(len) && len > 0)) return false;
  n /= len;
  return true;
}

/// Sub-sample position of the maximum of a parabola through (−1, ym), (0, y0), (+1, yp), in samples, and its value.
/// No shift when the three points are not strictly concave.
void parabolicPeak(double ym, double y0, double yp, double& shift, double& value) {
  shift = 0;
  value = y0;
  const double denom = ym - 2 * y0 + yp;
  if (!(denom < 0)) return;
  shift = std::clamp(0.5 * (ym - yp) / denom, -0.5, 0.5);
  value = y0 - 0.25 * (ym - yp) * shift;
}

/// How far along the search line (in sampling steps, 4 of the smallest voxel spacing by default) leaving the image
/// counts: a range set from the largest spacing of a very anisotropic grid (8 mm slices) would otherwise reach out of
/// a small in-plane field of view from every vertex.
constexpr int kLeaveCheckSteps = 16;

/// Whether the search line leaves the image: a candidate position at either end (±`reachMm` along the normal) has no
/// value (the image is a box, so the ends decide). Such a line gets no target: the true edge may lie beyond the image
/// (a scan or crop that cuts the object), and an edge found on the part inside would pull the surface to the wrong
/// place (a real CT femur cut by the field of view gains Dice by ignoring such lines). Samples a profile window or a
/// central difference needs beyond the ends do not count.
bool leavesImage(const LineSampler& sampler, double reachMm) {
  return !std::isfinite(sampler.at(-reachMm)) || !std::isfinite(sampler.at(reachMm));
}

/// One vertex's search outcome.
struct VertexTarget {
  double offsetMm = 0;  ///< along the normal
  double score = 0;     ///< ≥ 0
};

/// Working buffers of the per-vertex search (one set per thread once the loop is parallel).
struct SearchScratch {
  std::vector<double> line, value, profile, prefix, prefix2;
  std::vector<int> outside;
};

/// Picks the sample maximising value − penalty·|s|·max(value) among positive values (s = (i − half)·step), then
/// climbs to the nearest local maximum of the unpenalised value; returns −1 if no value is positive.
int penalisedArgmax(const std::vector<double>& value, int half, double stepMm, double penalty) {
  double best = 0;
  for (double v : value)
    if (v > best) best = v;
  if (!(best > 0)) return -1;
  int arg = -1;
  double bestScore = -std::numeric_limits<double>::infinity();
  const int n = static_cast<int>(value.size());
  for (int i = 0; i < n; ++i) {
    if (!(value[i] > 0)) continue;
    const double score = value[i] - penalty * std::abs(i - half) * stepMm * best;
    if (score > bestScore) bestScore = score, arg = i;
  }
  // The penalty tilts the curve: move uphill to the true local maximum so the refinement is unbiased.
  for (;;) {
    if (arg + 1 < n && value[arg + 1] > value[arg])
      ++arg;
    else if (arg > 0 && value[arg - 1] > value[arg])
      --arg;
    else
      break;
  }
  return arg;
}

/// Refines the maximum at index `arg` of `value` by a parabola through its neighbours (NaN neighbours: no shift);
/// returns the target offset (mm) and value.
VertexTarget refineAt(const std::vector<double>& value, int arg, int half, double stepMm) {
  const int n = static_cast<int>(value.size());
  double shift = 0, peak = value[arg];
  if (arg > 0 && arg + 1 < n && std::isfinite(value[arg - 1]) && std::isfinite(value[arg + 1]))
    parabolicPeak(value[arg - 1], value[arg], value[arg + 1], shift, peak);
  return {(arg - half + shift) * stepMm, std::max(peak, 0.0)};
}

/// Centre of mass (in samples) of the positive lobe of `value` around its local maximum `arg`, within ±`window`
/// samples of the centre (iterated to a fixed point, so the window ends up symmetric about the edge).
double lobeCentroid(const std::vector<double>& value, int arg, double window) {
  const int n = static_cast<int>(value.size());
  // The peak's lobe: positive samples around it, cut at a dip once the profile climbs again by more than
  // kLobeDip × the peak (a neighbouring edge of the same polarity must not drag the centre; interpolation kinks may).
  const double climb = kLobeDip * value[arg];
  auto extend = [&](int from, int dir) {
    int end = from, dip = from;
    for (int i = from + dir; i >= 0 && i < n && value[i] > 0; i += dir) {
      if (value[i] < value[dip]) dip = i;
      if (value[i] > value[dip] + climb) return dip;
      end = i;
    }
    return end;
  };
  const int lo = extend(arg, -1), hi = extend(arg, +1);
  double c = arg;
  for (int it = 0; it < 20; ++it) {
    const int a = std::max(lo, static_cast<int>(std::ceil(c - window)));
    const int b = std::min(hi, static_cast<int>(std::floor(c + window)));
    double sw = 0, swi = 0;
    for (int i = a; i <= b; ++i) sw += value[i], swi += value[i] * i;
    if (!(sw > 0)) break;
    const double next = swi / sw;
    const bool done = std::abs(next - c) < 1e-3;
    c = next;
    if (done) break;
  }
  return c;
}

/// Gradient mode for one vertex: the strongest directional derivative of sign `sign` along the line.
/// Zeroes the lobes of `value` across which the intensity `line` does not cross `level` from the inside's side to the
/// outside's. A lobe is a run of positive values, split where the values climb again by more than kLobeDip × the
/// lobe's peak after a dip (two edges close together, e.g. bone–muscle then muscle–fat under the blur, make one
/// positive run). value[i] is the derivative centred on line[i + 1], so the lobe [a, b] spans line[a] (inner end) to
/// line[b + 2] (outer end); `sign` > 0 when the intensity rises outward. A NaN end never crosses.
void keepLevelCrossingLobes(const std::vector<double>& line, std::vector<double>& value, double sign, double level) {
  const int n = static_cast<int>(value.size());
  auto settle = [&](int a, int b) {
    const bool crosses = sign * (line[a] - level) <= 0 && sign * (line[b + 2] - level) >= 0;
    if (!crosses)
      for (int i = a; i <= b; ++i) value[i] = 0;
  };
  for (int a = 0; a < n;) {
    if (!(value[a] > 0)) {
      ++a;
      continue;
    }
    int start = a, dip = -1, i = a + 1;
    double peak = value[a];
    for (; i < n && value[i] > 0; ++i) {
      if (dip < 0) {
        if (value[i] >= peak)
          peak = value[i];
        else
          dip = i;
      } else if (value[i] < value[dip]) {
        dip = i;
      } else if (value[i] > value[dip] + kLobeDip * peak) {
        settle(start, dip);  // the lobes share the dip sample
        start = dip;
        peak = value[i];
        dip = -1;
      }
    }
    settle(start, i - 1);
    a = i;
  }
}

VertexTarget gradientSearch(const LineSampler& sampler, const ResolvedSearch& r, double sign, double penalty,
                            double lobeHalfWidthMm, double level, SearchScratch& buf) {
  const int half = r.halfSearch, n = 2 * half + 1;
  // One extra sample each side so the central difference exists over the whole ±range.
  buf.line.resize(static_cast<size_t>(n + 2));
  if (leavesImage(sampler, std::min(half, kLeaveCheckSteps) * r.stepMm)) return {};
  for (int i = 0; i < n + 2; ++i) buf.line[i] = sampler.at((i - half - 1) * r.stepMm);
  buf.value.assign(static_cast<size_t>(n), kNaN);
  const double scale = sign / (2 * r.stepMm);
  bool any = false;
  for (int i = 0; i < n; ++i) {
    const double d = (buf.line[i + 2] - buf.line[i]) * scale;  // NaN if a sample is outside
    buf.value[i] = d;
    any = any || d > 0;
  }
  if (!any) return {};
  if (std::isfinite(level)) keepLevelCrossingLobes(buf.line, buf.value, sign, level);
  const int arg = penalisedArgmax(buf.value, half, r.stepMm, penalty);
  if (arg < 0) return {};
  // Score: the parabolic peak value. Position: the centre of mass of the lobe, exact for a partial-volume edge
  // under linear interpolation (where the peak itself is a plateau one slice wide and a parabola is arbitrary).
  VertexTarget t = refineAt(buf.value, arg, half, r.stepMm);
  t.offsetMm = (lobeCentroid(buf.value, arg, lobeHalfWidthMm / r.stepMm) - half) * r.stepMm;
  return t;
}

/// Edge focusing for one vertex: the strongest derivative of sign `sign` on the fine-scale line `fine` within
/// ±`windowMm` of the coarse target `coarse` (penalised by distance from it as the search is from the vertex), located
/// by its lobe's centre of mass. Returns `coarse` unchanged where the fine line has no such edge there.
VertexTarget focusEdge(const LineSampler& fine, const VertexTarget& coarse, const ResolvedSearch& r, double sign,
                       double penalty, double windowMm, double lobeHalfWidthMm, double level, SearchScratch& buf) {
  const int half = std::max(1, static_cast<int>(std::ceil(windowMm / r.stepMm))), n = 2 * half + 1;
  buf.line.resize(static_cast<size_t>(n + 2));
  for (int i = 0; i < n + 2; ++i) buf.line[i] = fine.at(coarse.offsetMm + (i - half - 1) * r.stepMm);
  buf.value.assign(static_cast<size_t>(n), kNaN);
  const double scale = sign / (2 * r.stepMm);
  for (int i = 0; i < n; ++i) buf.value[i] = (buf.line[i + 2] - buf.line[i]) * scale;  // NaN if a sample is outside
  if (std::isfinite(level)) keepLevelCrossingLobes(buf.line, buf.value, sign, level);
  const int arg = penalisedArgmax(buf.value, half, r.stepMm, penalty);
  if (arg < 0) return coarse;
  VertexTarget t = coarse;
  t.offsetMm = coarse.offsetMm + (lobeCentroid(buf.value, arg, lobeHalfWidthMm / r.stepMm) - half) * r.stepMm;
  return t;
}

/// Profile mode for one vertex: the offset whose window best correlates (NCC) with the learned `profile`.
VertexTarget profileSearch(const LineSampler& sampler, const ResolvedSearch& r, const double* profile, int profileHalf,
                           double penalty, SearchScratch& buf) {
  const int half = r.halfSearch, n = 2 * half + 1, len = 2 * profileHalf + 1;
  double profileNorm = 0;
  for (int i = 0; i < len; ++i) profileNorm += profile[i] * profile[i];
  if (!(profileNorm > 0)) return {};
  const int lineLen = n + len - 1;  // samples at (j − half − profileHalf)·step
  buf.line.resize(static_cast<size_t>(lineLen));
  if (leavesImage(sampler, std::min(half, kLeaveCheckSteps) * r.stepMm)) return {};
  for (int j = 0; j < lineLen; ++j) buf.line[j] = sampler.at((j - half - profileHalf) * r.stepMm);
  buf.value.assign(static_cast<size_t>(n), kNaN);
  // Running sums of the samples, their squares and the samples outside the image (set to 0), so that each window's
  // mean and spread cost two subtractions; only the dot product with the profile is per window.
  buf.prefix.resize(static_cast<size_t>(lineLen + 1));
  buf.prefix2.resize(static_cast<size_t>(lineLen + 1));
  buf.outside.resize(static_cast<size_t>(lineLen + 1));
  buf.prefix[0] = buf.prefix2[0] = 0;
  buf.outside[0] = 0;
  for (int j = 0; j < lineLen; ++j) {
    const double x = buf.line[j];
    const bool in = std::isfinite(x);
    if (!in) buf.line[j] = 0;
    buf.prefix[j + 1] = buf.prefix[j] + (in ? x : 0);
    buf.prefix2[j + 1] = buf.prefix2[j] + (in ? x * x : 0);
    buf.outside[j + 1] = buf.outside[j] + (in ? 0 : 1);
  }
  const Eigen::Map<const Eigen::VectorXd> p(profile, len);
  bool any = false;
  for (int o = 0; o < n; ++o) {
    if (buf.outside[o + len] != buf.outside[o]) continue;  // part of the window is outside the image
    const double sum = buf.prefix[o + len] - buf.prefix[o], sum2 = buf.prefix2[o + len] - buf.prefix2[o];
    const double dot = Eigen::Map<const Eigen::VectorXd>(buf.line.data() + o, len).dot(p);
    // The profile has zero mean, so Σ p·(w − mean w) = Σ p·w.
    const double centred = sum2 - sum * sum / len;
    const double norm = centred > 0 ? std::sqrt(centred) : 0;
    const double ncc = norm > kFlatTol * std::sqrt(len) ? dot / (norm * std::sqrt(profileNorm)) : 0;
    buf.value[o] = ncc;
    any = any || ncc > 0;
  }
  if (!any) return {};
  const int arg = penalisedArgmax(buf.value, half, r.stepMm, penalty);
  if (arg < 0) return {};
  VertexTarget t = refineAt(buf.value, arg, half, r.stepMm);
  t.score = std::min(t.score, 1.0);
  return t;
}

/// Whether a vertex at `p` with unit normal `n` lies beyond the voxel centres of `g` on the side of a structure that
/// goes on past the scan: outside along some axis, with its normal at least 60° from that axis (a side of a
/// continued shaft, not the cap a cut structure gets on the scan's voxel boundary, nor its rounded rim).
bool beyondImageSideways(const Grid& g, const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
  const Eigen::Vector3d v = g.toVoxel(p);
  bool beyond = false;
  for (int a = 0; a < 3; ++a)
    if (v[a] < 0 || v[a] > g.dims[a] - 1) {
      if (std::abs(n.dot(g.direction.col(a))) > 0.5) return false;
      beyond = true;
    }
  return beyond;
}

/// Cube size (mm) of the donor buckets of borrowProfiles().
constexpr double kBorrowCellMm = 8;

/// Gives each vertex of `borrowers` (no profile of its own) the profile of the nearest vertex with one, within
/// kProfileBorrowMm and with a normal within kProfileBorrowDegrees (learnProfiles()). Donors are bucketed in cubes of
/// kBorrowCellMm; a borrower scans shells of cubes outward until no nearer donor can remain.
void borrowProfiles(Eigen::MatrixXd& profiles, const Points& positions, const Points& normals,
                    const std::vector<Eigen::Index>& borrowers) {
  if (borrowers.empty()) return;
  const double minCos = std::cos(kProfileBorrowDegrees * M_PI / 180.0);
  std::unordered_map<uint64_t, std::vector<Eigen::Index>> cells;
  auto cellOf = [](const Eigen::Vector3d& p) -> Eigen::Vector3i {
    return Eigen::Vector3i((p / kBorrowCellMm).array().floor().cast<int>());
  };
  auto key = [](const Eigen::Vector3i& c) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(c[0]) & 0x1fffff) << 42) |
           (static_cast<uint64_t>(static_cast<uint32_t>(c[1]) & 0x1fffff) << 21) |
           static_cast<uint64_t>(static_cast<uint32_t>(c[2]) & 0x1fffff);
  };
  for (Eigen::Index v = 0; v < profiles.rows(); ++v)
    if (profiles.row(v).squaredNorm() > 0 && positions.row(v).allFinite())
      cells[key(cellOf(positions.row(v).transpose()))].push_back(v);
  if (cells.empty()) return;
  const int maxShell = static_cast<int>(std::ceil(kProfileBorrowMm / kBorrowCellMm)) + 1;
  Eigen::Vector3d n, m;
  for (Eigen::Index v : borrowers) {
    if (!unitNormal(normals, v, n)) continue;
    const Eigen::Vector3d p = positions.row(v).transpose();
    const Eigen::Vector3i c = cellOf(p);
    double best = kProfileBorrowMm * kProfileBorrowMm;
    Eigen::Index donor = -1;
    for (int shell = 0; shell <= maxShell; ++shell) {
      // Every point of shell `shell` is at least (shell − 1) cells away.
      if (shell > 1 && std::pow((shell - 1) * kBorrowCellMm, 2) > best) break;
      for (int dz = -shell; dz <= shell; ++dz)
        for (int dy = -shell; dy <= shell; ++dy)
          for (int dx = -shell; dx <= shell; ++dx) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != shell) continue;
            const auto it = cells.find(key(c + Eigen::Vector3i(dx, dy, dz)));
            if (it == cells.end()) continue;
            for (Eigen::Index u : it->second) {
              const double d2 = (positions.row(u).transpose() - p).squaredNorm();
              if (d2 > best || (d2 == best && u > donor)) continue;
              if (!unitNormal(normals, u, m) || m.dot(n) < minCos) continue;
              best = d2, donor = u;
            }
          }
    }
    if (donor >= 0) profiles.row(v) = profiles.row(donor);
  }
}

/// Score-weighted smoothing of `offsets` over the neighbour graph, `passes` times; vertices with score 0 keep their
/// (zero) offset. Each pass: o_v ← Σ_{u ∈ {v} ∪ N(v)} w_u o_u / Σ w_u.
void regulariseOffsets(Eigen::VectorXd& offsets, const Eigen::VectorXd& scores, const NeighborTable& neighbors,
                       int passes) {
  const Eigen::Index nv = offsets.size();
  Eigen::VectorXd next(nv);
  for (int pass = 0; pass < passes; ++pass) {
    for (Eigen::Index v = 0; v < nv; ++v) {
      next[v] = offsets[v];
      if (!(scores[v] > 0)) continue;
      double wsum = scores[v], osum = scores[v] * offsets[v];
      for (Eigen::Index c = 0; c < neighbors.cols(); ++c) {
        const int u = neighbors(v, c);
        if (u < 0 || !(scores[u] > 0)) continue;
        wsum += scores[u];
        osum += scores[u] * offsets[u];
      }
      next[v] = osum / wsum;
    }
    offsets.swap(next);
  }
}

/// Throws ParameterError unless positions and normals are #V×3 of the same size.
void requireSameRows(const Points& positions, const Points& normals) {
  if (positions.rows() != normals.rows())
    throw ParameterError("normals.rows", std::to_string(normals.rows()),
                         "must equal positions.rows = " + std::to_string(positions.rows()));
}

}  // namespace

std::optional<double> ImageFeatures::sample(const Eigen::Vector3d& worldMm) const {
  return sampleTrilinear(smoothed, worldMm);
}

ImageFeatures computeImageFeatures(const ImageF& image, double sigmaMm) {
  requireNonNegative("sigmaMm", sigmaMm);
  return featuresOfNormalised(normalisedForFeatures(image), sigmaMm);
}

ImageF normalisedForFeatures(const ImageF& image) {
  // Robust normalisation (1–99 %) so scores compare across MRI and CT. Images that are constant between those
  // percentiles (tiny objects) fall back to min–max; a constant image becomes all zeros (no edges, no forces).
  // (normalizeIntensity()'s mapping, each percentile computed once.)
  const std::vector<double> range = percentiles(image, {1.0, 99.0});
  double lo = range[0], hi = range[1];
  if (!(hi > lo)) {
    lo = percentile(image, 0.0);
    hi = percentile(image, 100.0);
  }
  ImageF normalised = image;
  if (hi > lo) {
    const double scale = 1.0 / (hi - lo);
    for (float& v : normalised.data) v = static_cast<float>((v - lo) * scale);
  } else {
    for (float& v : normalised.data)
      if (std::isfinite(v)) v = 0.f;
  }
  return normalised;
}

ImageFeatures featuresOfNormalised(const ImageF& normalised, double sigmaMm) {
  requireNonNegative("sigmaMm", sigmaMm);
  ImageFeatures f;
  f.sigmaMm = sigmaMm;
  f.smoothed = gaussianSmooth(normalised, sigmaMm);
  return f;
}

Polarity estimatePolarity(const ImageFeatures& features, const Points& positions, const Points& normals) {
  requireSameRows(positions, normals);
  LineSampler sampler(features.smoothed);
  double inside = 0, outside = 0;
  long nIn = 0, nOut = 0;
  Eigen::Vector3d n;
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    if (!unitNormal(normals, v, n)) continue;
    sampler.setLine(positions.row(v).transpose(), n);
    for (int k = 1; k <= 6; ++k) {  // 0.5, 1.0, ..., 3.0 mm
      const double d = 0.5 * k;
      const double in = sampler.at(-d), out = sampler.at(d);
      if (std::isfinite(in)) inside += in, ++nIn;
      if (std::isfinite(out)) outside += out, ++nOut;
    }
  }
  if (nIn == 0 || nOut == 0) return Polarity::BrightInside;
  return outside / nOut > inside / nIn ? Polarity::DarkInside : Polarity::BrightInside;
}

double estimateEdgeLevel(const ImageFeatures& features, const Points& positions, const Points& normals) {
  requireSameRows(positions, normals);
  LineSampler sampler(features.smoothed);
  std::vector<double> inside, outside;
  Eigen::Vector3d n;
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    if (!unitNormal(normals, v, n) || !positions.row(v).allFinite()) continue;
    sampler.setLine(positions.row(v).transpose(), n);
    for (int k = 1; k <= 6; ++k) {  // 0.5, 1.0, ..., 3.0 mm
      const double in = sampler.at(-0.5 * k), out = sampler.at(0.5 * k);
      if (std::isfinite(in)) inside.push_back(in);
      if (std::isfinite(out)) outside.push_back(out);
    }
  }
  if (inside.empty() || outside.empty()) return kNaN;
  auto median = [](std::vector<double>& x) {
    std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2), x.end());
    return x[x.size() / 2];
  };
  return 0.5 * (median(inside) + median(outside));
}

LearnedProfiles learnProfiles(const ImageFeatures& features, const Points& positions, const Points& normals,
                              const TargetSearchOptions& opts, const Grid& grid, bool borrow) {
  requireSameRows(positions, normals);
  requireNonNegative("profileHalfLengthMm", opts.profileHalfLengthMm);
  LearnedProfiles lp;
  lp.stepMm = resolveStep(opts, grid);
  const double halfMm = opts.profileHalfLengthMm > 0 ? opts.profileHalfLengthMm : 2.0 * grid.spacing.maxCoeff();
  lp.halfSamples = stepsIn("profileHalfLengthMm", halfMm, lp.stepMm);
  const int len = 2 * lp.halfSamples + 1;
  lp.profiles = Eigen::MatrixXd::Zero(positions.rows(), len);
  LineSampler sampler(features.smoothed);
  Eigen::VectorXd row(len);
  Eigen::Vector3d n;
  std::vector<Eigen::Index> outside;  // vertices whose line leaves the image
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    if (!unitNormal(normals, v, n) || !positions.row(v).allFinite()) continue;
    sampler.setLine(positions.row(v).transpose(), n);
    for (int i = 0; i < len; ++i) row[i] = sampler.at((i - lp.halfSamples) * lp.stepMm);
    if (!row.allFinite()) {  // partly outside the image: no profile; borrowed below beside a continued structure
      if (beyondImageSideways(features.smoothed.grid, positions.row(v).transpose(), n)) outside.push_back(v);
      continue;
    }
    row.array() -= row.mean();
    const double norm = row.norm();
    if (norm > kFlatTol * std::sqrt(len)) lp.profiles.row(v) = row / norm;
  }
  if (borrow) borrowProfiles(lp.profiles, positions, normals, outside);
  return lp;
}

TargetSearchResult searchTargets(const ImageFeatures& features, const Points& positions, const Points& normals,
                                 const NeighborTable& neighbors, const TargetSearchOptions& opts, Polarity polarity,
                                 const Grid& grid, const LearnedProfiles* profiles, const ImageFeatures* focus,
                                 SearchReuse* reuse) {
  requireSameRows(positions, normals);
  const Eigen::Index nv = positions.rows();
  if (polarity == Polarity::Auto)
    throw ParameterError("polarity", "Auto", "must be resolved (estimatePolarity) before searchTargets");
  const bool profileMode = opts.mode == TargetMode::Profile;
  if (profileMode) {
    if (!profiles) throw ParameterError("profiles", "null", "are required in Profile mode (learnProfiles)");
    if (profiles->profiles.rows() != nv || profiles->profiles.cols() != 2 * profiles->halfSamples + 1 ||
        !(profiles->stepMm > 0))
      throw ParameterError("profiles.rows", std::to_string(profiles->profiles.rows()),
                           "must be #V = " + std::to_string(nv) + " with 2·halfSamples+1 columns and a step > 0");
  }
  const bool regularise = opts.regularisationRings > 0 && neighbors.rows() > 0;
  if (regularise) {
    if (neighbors.rows() != nv)
      throw ParameterError("neighbors.rows", std::to_string(neighbors.rows()), "must be #V = " + std::to_string(nv));
    if (neighbors.size() > 0 && neighbors.maxCoeff() >= nv)
      throw ParameterError("neighbors", std::to_string(neighbors.maxCoeff()), "index out of range");
  }
  // Profiles fix the step they were learned at; the search must slide them on the same lattice.
  const ResolvedSearch r = resolveSearch(opts, grid, profileMode ? profiles->stepMm : resolveStep(opts, grid));
  const double sign = polarity == Polarity::DarkInside ? 1.0 : -1.0;

  TargetSearchResult out;
  out.offsets = Eigen::VectorXd::Zero(nv);
  out.scores = Eigen::VectorXd::Zero(nv);
  const bool focusing = focus && !profileMode && focus->sigmaMm < features.sigmaMm;
  if (reuse && !(reuse->moveMm > 0)) reuse = nullptr;
  if (reuse && reuse->positions.rows() != nv) {
    reuse->positions.setConstant(nv, 3, kNaN);
    reuse->normals.setZero(nv, 3);
    reuse->offsets.setZero(nv);
    reuse->scores.setZero(nv);
  }
  const double reuseCos = reuse ? std::cos(reuse->turnDegrees * M_PI / 180.0) : 1.0;
  std::vector<char> wasReused(reuse ? static_cast<size_t>(nv) : 0, 0);
  // The vertices in one contiguous range per thread, each with its own samplers and scratch.
  const size_t ranges = std::max<size_t>(
      1, std::min<size_t>(static_cast<size_t>(detail::threadCount(opts.threads)), static_cast<size_t>(nv) / 256));
  detail::parallelEach(ranges, static_cast<int>(ranges), [&](size_t k) {
    LineSampler sampler(features.smoothed);
    LineSampler fineSampler(focusing ? focus->smoothed : features.smoothed);
    SearchScratch scratch;
    Eigen::Vector3d n;
    const Eigen::Index begin = static_cast<Eigen::Index>(k) * nv / static_cast<Eigen::Index>(ranges);
    const Eigen::Index end = static_cast<Eigen::Index>(k + 1) * nv / static_cast<Eigen::Index>(ranges);
    for (Eigen::Index v = begin; v < end; ++v) {
      if (!unitNormal(normals, v, n) || !positions.row(v).allFinite()) continue;
      const Eigen::Vector3d x = positions.row(v).transpose();
      if (reuse) {
        const Eigen::Vector3d x0 = reuse->positions.row(v).transpose(), n0 = reuse->normals.row(v).transpose();
        // (A NaN row, never searched, fails the test.)
        if ((x - x0).norm() <= reuse->moveMm && n.dot(n0) >= reuseCos) {
          const double score = reuse->scores[v];
          if (score > 0) {
            out.offsets[v] = (x0 + reuse->offsets[v] * n0 - x).dot(n);
            out.scores[v] = score;
          }
          wasReused[static_cast<size_t>(v)] = 1;
          continue;
        }
      }
      sampler.setLine(x, n);
      VertexTarget t;
      if (profileMode) {
        const Eigen::Index len = profiles->profiles.cols();
        scratch.profile.resize(static_cast<size_t>(len));
        for (Eigen::Index i = 0; i < len; ++i) scratch.profile[i] = profiles->profiles(v, i);  // rows not contiguous
        t = profileSearch(sampler, r, scratch.profile.data(), profiles->halfSamples, opts.distancePenalty, scratch);
      } else {
        // Lobe half-width: the voxel's extent along n (support of the interpolated partial-volume edge) plus the
        // smoothing's ±2σ.
        const Eigen::Vector3d nVoxel = features.smoothed.grid.direction.transpose() * n;
        const double footprintMm = features.smoothed.grid.spacing.dot(nVoxel.cwiseAbs());
        const double lobeMm = std::max(footprintMm + 2 * features.sigmaMm, 2 * r.stepMm);
        t = gradientSearch(sampler, r, sign, opts.distancePenalty, lobeMm, opts.edgeLevel, scratch);
        if (focusing && t.score > 0) {
          fineSampler.setLine(positions.row(v).transpose(), n);
          const double fineLobeMm = std::max(footprintMm + 2 * focus->sigmaMm, 2 * r.stepMm);
          t = focusEdge(fineSampler, t, r, sign, opts.distancePenalty, features.sigmaMm + footprintMm, fineLobeMm,
                        opts.edgeLevel, scratch);
        }
      }
      const bool found = t.score > 0 && std::isfinite(t.offsetMm);
      if (found) {
        out.offsets[v] = t.offsetMm;
        out.scores[v] = t.score;
      }
      if (reuse) {
        reuse->positions.row(v) = x.transpose();
        reuse->normals.row(v) = n.transpose();
        reuse->offsets[v] = found ? t.offsetMm : 0.0;
        reuse->scores[v] = found ? t.score : 0.0;
      }
    }
  });
  if (reuse) {
    const long kept = std::count(wasReused.begin(), wasReused.end(), 1);
    reuse->reused += kept;
    reuse->searched += static_cast<long>(nv) - kept;
  }
  out.residual = out.offsets.cwiseAbs();
  if (regularise) regulariseOffsets(out.offsets, out.scores, neighbors, opts.regularisationRings);
  out.targets = positions;
  Eigen::Vector3d n;
  for (Eigen::Index v = 0; v < nv; ++v)
    if (out.scores[v] > 0 && unitNormal(normals, v, n)) out.targets.row(v) += out.offsets[v] * n.transpose();
  return out;
}

}  // namespace msk
