#include "msk/imaging/filters.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "msk/core/error.h"
#include "msk/core/order_statistics.h"

namespace msk {
namespace {

/// Tolerance (voxels) by which a sample may lie beyond the first/last voxel centre and still count as inside.
constexpr double kInsideTolVoxels = 1e-9;

/// `ijk` (continuous voxel coordinates) clamped into [0, dims−1]; false if outside (beyond the tolerance) or not
/// finite.
bool insideVoxel(const Grid& grid, Eigen::Vector3d& ijk) {
  for (int a = 0; a < 3; ++a) {
    const double hi = grid.dims[a] - 1;
    if (!std::isfinite(ijk[a]) || ijk[a] < -kInsideTolVoxels || ijk[a] > hi + kInsideTolVoxels) return false;
    ijk[a] = std::clamp(ijk[a], 0.0, hi);
  }
  return true;
}

/// Normalised 1-D Gaussian kernel of standard deviation `sigmaVoxels`, truncated at 4 sigma (radius = size/2).
std::vector<double> gaussianKernel(double sigmaVoxels) {
  const int radius = std::max(1, static_cast<int>(std::ceil(4.0 * sigmaVoxels)));
  std::vector<double> k(2 * radius + 1);
  double sum = 0;
  for (int t = -radius; t <= radius; ++t) sum += k[t + radius] = std::exp(-0.5 * t * t / (sigmaVoxels * sigmaVoxels));
  for (double& v : k) v /= sum;
  return k;
}

/// out[i] = Σ_t kernel[t]·taps[t][i] for i < m, summed in doubles in the order of t, as floats: eight outputs at a
/// time held in registers over all taps (vectorised across the outputs, each output's sum in the same order).
void tapSums(const std::vector<double>& kernel, const double* const* taps, size_t m, float* out) {
  constexpr size_t kBlock = 8;
  const size_t nt = kernel.size();
  size_t i = 0;
  for (; i + kBlock <= m; i += kBlock) {
    double a[kBlock] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t t = 0; t < nt; ++t) {
      const double k = kernel[t];
      const double* x = taps[t] + i;
      for (size_t q = 0; q < kBlock; ++q) a[q] += k * x[q];
    }
    for (size_t q = 0; q < kBlock; ++q) out[i + q] = static_cast<float>(a[q]);
  }
  for (; i < m; ++i) {
    double a = 0;
    for (size_t t = 0; t < nt; ++t) a += kernel[t] * taps[t][i];
    out[i] = static_cast<float>(a);
  }
}

/// Convolves every line of `data` along `axis` with `kernel` (odd length), replicating edge values. Each output is
/// Σ_t kernel[t]·x[p − radius + t] summed in doubles in the order of t (tapSums()): along axis 0 over a line padded
/// with its edge values, along axes 1 and 2 a whole row of axis 0 at a time (a plane of the image copied into a
/// buffer).
void convolveAxis(LargeVector<float>& data, const Grid& grid, int axis, const std::vector<double>& kernel) {
  const int n = grid.dims[axis];
  const int radius = static_cast<int>(kernel.size() / 2);
  std::vector<const double*> taps(kernel.size());
  if (axis == 0) {  // lines are contiguous (stride 1)
    std::vector<double> padded(static_cast<size_t>(n + 2 * radius));
    for (size_t t = 0; t < taps.size(); ++t) taps[t] = padded.data() + t;
    grid.forEachLine(axis, [&](size_t base, size_t) {
      for (int p = -radius; p < n + radius; ++p)
        padded[static_cast<size_t>(p + radius)] = data[base + static_cast<size_t>(std::clamp(p, 0, n - 1))];
      tapSums(kernel, taps.data(), static_cast<size_t>(n), data.data() + base);
    });
    return;
  }
  const size_t ni = static_cast<size_t>(grid.dims[0]);
  const size_t stride = axis == 1 ? ni : ni * static_cast<size_t>(grid.dims[1]);
  const int planes = axis == 1 ? grid.dims[2] : grid.dims[1];
  const size_t planeStride = axis == 1 ? ni * static_cast<size_t>(grid.dims[1]) : ni;
  std::vector<double> plane(static_cast<size_t>(n) * ni);
  for (int o = 0; o < planes; ++o) {
    const size_t base = static_cast<size_t>(o) * planeStride;
    for (int p = 0; p < n; ++p) {
      const float* from = data.data() + base + static_cast<size_t>(p) * stride;
      double* to = plane.data() + static_cast<size_t>(p) * ni;
      for (size_t i = 0; i < ni; ++i) to[i] = from[i];
    }
    for (int p = 0; p < n; ++p) {
      for (int t = -radius; t <= radius; ++t)
        taps[static_cast<size_t>(t + radius)] = plane.data() + static_cast<size_t>(std::clamp(p + t, 0, n - 1)) * ni;
      tapSums(kernel, taps.data(), ni, data.data() + base + static_cast<size_t>(p) * stride);
    }
  }
}

}  // namespace

std::optional<double> sampleTrilinear(const ImageF& image, const Eigen::Vector3d& worldMm) {
  return sampleTrilinearAtVoxel(image, image.grid.toVoxel(worldMm));
}

std::optional<int32_t> sampleNearest(const LabelMap& labels, const Eigen::Vector3d& worldMm) {
  return sampleNearestAtVoxel(labels, labels.grid.toVoxel(worldMm));
}

std::optional<double> sampleTrilinearAtVoxel(const ImageF& image, const Eigen::Vector3d& ijk) {
  const Grid& g = image.grid;
  Eigen::Vector3d v = ijk;
  if (!insideVoxel(g, v)) return std::nullopt;
  int i0[3], i1[3];
  double t[3];
  for (int a = 0; a < 3; ++a) {
    // Lower corner in [0, dims−2] (0 for a single voxel), so i1 = i0 + 1 never leaves the grid.
    i0[a] = std::clamp(static_cast<int>(std::floor(v[a])), 0, std::max(g.dims[a] - 2, 0));
    i1[a] = std::min(i0[a] + 1, g.dims[a] - 1);
    t[a] = v[a] - i0[a];
  }
  double result = 0;
  for (int c = 0; c < 8; ++c) {
    const bool bi = c & 1, bj = c & 2, bk = c & 4;
    const double wgt = (bi ? t[0] : 1 - t[0]) * (bj ? t[1] : 1 - t[1]) * (bk ? t[2] : 1 - t[2]);
    if (wgt == 0) continue;
    result += wgt * image.at(bi ? i1[0] : i0[0], bj ? i1[1] : i0[1], bk ? i1[2] : i0[2]);
  }
  return result;
}

std::optional<int32_t> sampleNearestAtVoxel(const LabelMap& labels, const Eigen::Vector3d& ijk) {
  const Grid& g = labels.grid;
  Eigen::Vector3d v = ijk;
  if (!insideVoxel(g, v)) return std::nullopt;
  int idx[3];
  for (int a = 0; a < 3; ++a) idx[a] = std::clamp(static_cast<int>(std::lround(v[a])), 0, g.dims[a] - 1);
  return labels.at(idx[0], idx[1], idx[2]);
}

ImageF gaussianSmooth(const ImageF& image, double sigmaMm) {
  ImageF out = image;
  if (!(sigmaMm > 0)) return out;
  for (int a = 0; a < 3; ++a) {
    const double sigmaVoxels = sigmaMm / image.grid.spacing[a];
    if (sigmaVoxels < 0.1 || image.grid.dims[a] < 2) continue;  // kernel would be a delta (or nothing to blur)
    convolveAxis(out.data, out.grid, a, gaussianKernel(sigmaVoxels));
  }
  return out;
}

ImageF resample(const ImageF& image, const Grid& target, float outside) {
  ImageF out(target, outside);
  for (int k = 0; k < target.dims[2]; ++k)
    for (int j = 0; j < target.dims[1]; ++j)
      for (int i = 0; i < target.dims[0]; ++i)
        if (auto v = sampleTrilinear(image, target.toWorld(Eigen::Vector3d(i, j, k))))
          out.at(i, j, k) = static_cast<float>(*v);
  return out;
}

namespace {

/// percentiles() of the `n` values at `data` (float or double; the order statistics and so the results are the same),
/// the non-finite ones left out. Linear interpolation between the order statistics at ⌊rank⌋ and ⌊rank⌋ + 1.
template <typename T>
std::vector<double> selectPercentiles(const T* data, size_t n, const std::vector<double>& ps) {
  for (double p : ps)
    if (!(p >= 0 && p <= 100)) throw ParameterError("percentile", std::to_string(p), "must lie in [0, 100]");
  const auto visit = [data, n](const auto& f) {
    for (size_t i = 0; i < n; ++i)
      if (std::isfinite(data[i])) f(static_cast<double>(data[i]));
  };
  const OrderStatistics stats(visit);
  const size_t count = stats.count();
  if (count == 0) throw Error("percentile: no finite values");
  std::vector<size_t> lo(ps.size());
  std::vector<double> frac(ps.size());
  std::vector<size_t> ranks;
  for (size_t i = 0; i < ps.size(); ++i) {
    const double rank = ps[i] / 100.0 * static_cast<double>(count - 1);
    lo[i] = std::min(static_cast<size_t>(std::floor(rank)), count - 1);
    frac[i] = rank - static_cast<double>(lo[i]);
    ranks.push_back(lo[i]);
    if (frac[i] > 0 && lo[i] + 1 < count) ranks.push_back(lo[i] + 1);
  }
  std::sort(ranks.begin(), ranks.end());
  ranks.erase(std::unique(ranks.begin(), ranks.end()), ranks.end());
  const std::vector<double> values = stats.select(visit, ranks);
  const auto valueAt = [&](size_t rank) {
    return values[static_cast<size_t>(std::lower_bound(ranks.begin(), ranks.end(), rank) - ranks.begin())];
  };
  std::vector<double> out(ps.size());
  for (size_t i = 0; i < ps.size(); ++i) {
    const double vLo = valueAt(lo[i]);
    out[i] = frac[i] > 0 && lo[i] + 1 < count ? vLo + frac[i] * (valueAt(lo[i] + 1) - vLo) : vLo;
  }
  return out;
}

}  // namespace

std::vector<double> percentiles(const std::vector<double>& values, const std::vector<double>& ps) {
  return selectPercentiles(values.data(), values.size(), ps);
}

std::vector<double> percentiles(const ImageF& image, const std::vector<double>& ps) {
  return selectPercentiles(image.data.data(), image.data.size(), ps);
}

double percentile(const std::vector<double>& values, double p) { return percentiles(values, {p}).front(); }

double percentile(const ImageF& image, double p) { return percentiles(image, {p}).front(); }

ImageF normalizeIntensity(const ImageF& image, double lowPercent, double highPercent) {
  if (!(lowPercent >= 0 && lowPercent < highPercent && highPercent <= 100))
    throw ParameterError("percentiles", std::to_string(lowPercent) + ", " + std::to_string(highPercent),
                         "need 0 ≤ low < high ≤ 100");
  const std::vector<double> range = percentiles(image, {lowPercent, highPercent});
  const double lo = range[0], hi = range[1];
  if (!(hi > lo))
    throw Error("normalizeIntensity: image is constant between the " + std::to_string(lowPercent) + " and " +
                std::to_string(highPercent) + " percentiles (value " + std::to_string(lo) + ")");
  ImageF out = image;
  const double scale = 1.0 / (hi - lo);
  // No clipping: values outside [lo, hi] map outside [0, 1]; non-finite values stay non-finite.
  for (float& v : out.data) v = static_cast<float>((v - lo) * scale);
  return out;
}

}  // namespace msk
