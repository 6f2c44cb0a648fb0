#pragma once
/// Volume filters in world units: sampling, Gaussian smoothing (sigma in mm), resampling, robust intensity
/// normalisation.
#include <optional>
#include <vector>

#include "msk/imaging/volume.h"

namespace msk {

/// Trilinear interpolation at a world point (RAS mm); std::nullopt outside the grid's voxel-centre hull
/// (never reads out of bounds).
std::optional<double> sampleTrilinear(const ImageF& image, const Eigen::Vector3d& worldMm);

/// Nearest-voxel value at a world point; std::nullopt outside.
std::optional<int32_t> sampleNearest(const LabelMap& labels, const Eigen::Vector3d& worldMm);

/// sampleTrilinear() at continuous voxel coordinates `ijk` (Grid::toVoxel() of the world point): the same inside test
/// and interpolation, for callers that step through voxel coordinates themselves.
std::optional<double> sampleTrilinearAtVoxel(const ImageF& image, const Eigen::Vector3d& ijk);
/// sampleNearest() at continuous voxel coordinates `ijk`.
std::optional<int32_t> sampleNearestAtVoxel(const LabelMap& labels, const Eigen::Vector3d& ijk);

/// Separable Gaussian smoothing, sigma in mm (converted per axis with the spacing; sigma ≤ 0: copy).
ImageF gaussianSmooth(const ImageF& image, double sigmaMm);

/// Linear resampling of `image` onto `target` (world-space correspondence); `outside` where undefined.
ImageF resample(const ImageF& image, const Grid& target, float outside = 0.f);

/// Robust normalisation: maps the `lowPercent` and `highPercent` percentiles of finite values to 0 and 1.
ImageF normalizeIntensity(const ImageF& image, double lowPercent = 1.0, double highPercent = 99.0);

/// The p-th percentile (0..100) of finite voxel values.
double percentile(const ImageF& image, double p);

/// The p-th percentile (0..100) of the finite entries of `values`: linear interpolation between the order
/// statistics at rank p/100·(n−1). Throws ParameterError for p outside [0, 100], Error if no entry is finite.
double percentile(const std::vector<double>& values, double p);
/// The percentiles `ps` (each 0..100) of the finite entries of `values`, as percentile() gives each, from two passes
/// over them (OrderStatistics, no copy). Throws as percentile() does.
std::vector<double> percentiles(const std::vector<double>& values, const std::vector<double>& ps);
/// The percentiles `ps` of an image's finite voxel values (two passes over the voxels, no copy).
std::vector<double> percentiles(const ImageF& image, const std::vector<double>& ps);

}  // namespace msk
