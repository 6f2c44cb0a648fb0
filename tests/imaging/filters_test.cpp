#include "msk/imaging/filters.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "msk/core/error.h"

namespace {

/// An oblique, anisotropic, left-handed grid.
msk::Grid obliqueGrid() {
  msk::Grid g;
  g.dims = {24, 20, 9};
  g.spacing = {0.8, 1.1, 3.0};
  g.direction = msk::Grid::rotationXYZ({25, -30, 40});
  g.direction.col(1) *= -1;
  g.origin = {-10.5, 4.25, 7.0};
  return g;
}

/// The ramp f = a·x + b·y + c·z + d in world RAS mm.
struct Ramp {
  Eigen::Vector3d abc{0.7, -1.3, 0.4};
  double d = 2.5;
  double operator()(const Eigen::Vector3d& x) const { return abc.dot(x) + d; }
};

/// The ramp sampled at the voxel centres of `g`.
msk::ImageF rampImage(const msk::Grid& g, const Ramp& f) {
  msk::ImageF img(g);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) img.at(i, j, k) = static_cast<float>(f(g.toWorld(Eigen::Vector3d(i, j, k))));
  return img;
}

/// A uniformly random continuous voxel position in [0, dims−1].
Eigen::Vector3d randomInterior(const msk::Grid& g, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::Vector3d v;
  for (int a = 0; a < 3; ++a) v[a] = u(rng) * (g.dims[a] - 1);
  return v;
}

}  // namespace

TEST(Filters, TrilinearIsExactOnWorldRampOnObliqueAnisotropicGrid) {
  const msk::Grid g = obliqueGrid();
  const Ramp f;
  const msk::ImageF img = rampImage(g, f);
  std::mt19937 rng(7);
  for (int t = 0; t < 500; ++t) {
    const Eigen::Vector3d w = g.toWorld(randomInterior(g, rng));
    const auto v = msk::sampleTrilinear(img, w);
    ASSERT_TRUE(v.has_value());
    EXPECT_NEAR(*v, f(w), 1e-4);
  }
  // The corner voxel centres themselves are inside.
  const Eigen::Vector3d last = (g.dims.cast<double>().array() - 1).matrix();
  ASSERT_TRUE(msk::sampleTrilinear(img, g.toWorld(last)).has_value());
  EXPECT_NEAR(*msk::sampleTrilinear(img, g.toWorld(last)), f(g.toWorld(last)), 1e-4);
  ASSERT_TRUE(msk::sampleTrilinear(img, g.origin).has_value());
}

TEST(Filters, SamplingOutsideTheVoxelCentreHullGivesNullopt) {
  const msk::Grid g = obliqueGrid();
  const msk::ImageF img = rampImage(g, Ramp{});
  msk::LabelMap labels(g, 3);
  const Eigen::Vector3d last = (g.dims.cast<double>().array() - 1).matrix();
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d beyond = last, before = Eigen::Vector3d::Zero();
    beyond[a] += 1e-3;  // just beyond the last voxel centre
    before[a] -= 1e-3;
    EXPECT_FALSE(msk::sampleTrilinear(img, g.toWorld(beyond)).has_value()) << "axis " << a;
    EXPECT_FALSE(msk::sampleTrilinear(img, g.toWorld(before)).has_value()) << "axis " << a;
    EXPECT_FALSE(msk::sampleNearest(labels, g.toWorld(beyond)).has_value()) << "axis " << a;
    EXPECT_FALSE(msk::sampleNearest(labels, g.toWorld(before)).has_value()) << "axis " << a;
  }
  EXPECT_FALSE(msk::sampleTrilinear(img, Eigen::Vector3d(1e6, 0, 0)).has_value());
  EXPECT_FALSE(msk::sampleTrilinear(img, Eigen::Vector3d(NAN, 0, 0)).has_value());
  EXPECT_EQ(msk::sampleNearest(labels, g.toWorld(Eigen::Vector3d(3.4, 2.6, 1.2))).value_or(-1), 3);
}

TEST(Filters, SingleVoxelAxisOnlyAcceptsCoordinateZero) {
  msk::Grid g;
  g.dims = {4, 3, 1};
  g.spacing = {1.0, 1.0, 2.0};
  msk::ImageF img(g, 5.f);
  EXPECT_NEAR(msk::sampleTrilinear(img, g.toWorld({1.5, 0.5, 0.0})).value_or(-1), 5.0, 1e-12);
  EXPECT_FALSE(msk::sampleTrilinear(img, g.toWorld({1.5, 0.5, 0.1})).has_value());
  EXPECT_FALSE(msk::sampleTrilinear(img, g.toWorld({1.5, 0.5, -0.1})).has_value());
}

TEST(Filters, NearestPicksTheClosestVoxel) {
  msk::Grid g;
  g.dims = {5, 4, 3};
  g.spacing = {0.5, 2.0, 1.0};
  g.direction = msk::Grid::rotationXYZ({0, 0, 30});
  msk::LabelMap labels(g);
  for (size_t n = 0; n < labels.data.size(); ++n) labels.data[n] = static_cast<int32_t>(n);
  EXPECT_EQ(*msk::sampleNearest(labels, g.toWorld({2.4, 0.6, 1.9})), static_cast<int32_t>(g.index(2, 1, 2)));
  EXPECT_EQ(*msk::sampleNearest(labels, g.toWorld({4.0, 3.0, 0.0})), static_cast<int32_t>(g.index(4, 3, 0)));
}

TEST(Filters, GaussianOfDeltaHasSigmaSquaredSecondMomentsInMmOnAnisotropicGrid) {
  msk::Grid g;
  g.dims = {61, 41, 15};
  g.spacing = {0.5, 1.0, 3.0};
  g.direction = msk::Grid::rotationXYZ({10, 20, 30});  // direction must not matter
  msk::ImageF img(g, 0.f);
  const Eigen::Vector3i c(30, 20, 7);
  img.at(c[0], c[1], c[2]) = 1000.f;
  const double sigma = 3.0;
  const msk::ImageF s = msk::gaussianSmooth(img, sigma);
  double total = 0;
  Eigen::Vector3d second = Eigen::Vector3d::Zero(), first = Eigen::Vector3d::Zero();
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double v = s.at(i, j, k);
        const Eigen::Vector3d dMm = (Eigen::Vector3i(i, j, k) - c).cast<double>().cwiseProduct(g.spacing);
        total += v;
        first += v * dMm;
        second += v * dMm.cwiseProduct(dMm);
      }
  EXPECT_NEAR(total, 1000.0, 1e-2);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(first[a] / total, 0.0, 1e-6) << "axis " << a;
    EXPECT_NEAR(second[a] / total, sigma * sigma, 0.05 * sigma * sigma) << "axis " << a;
  }
}

TEST(Filters, GaussianKeepsConstantsAndCopiesForZeroSigma) {
  const msk::Grid g = obliqueGrid();
  msk::ImageF img(g, 4.25f);
  const msk::ImageF s = msk::gaussianSmooth(img, 2.0);
  for (float v : s.data) ASSERT_NEAR(v, 4.25f, 1e-5);
  const msk::ImageF ramp = rampImage(g, Ramp{});
  EXPECT_EQ(msk::gaussianSmooth(ramp, 0.0).data, ramp.data);
  // A sigma far below the voxel size leaves the image untouched.
  EXPECT_EQ(msk::gaussianSmooth(ramp, 0.01).data, ramp.data);
}

// The smoothing equals, bit for bit, the plain definition: along each axis in turn, every voxel the sum over the
// truncated kernel (4 σ) of kernel weight × the line's value at the clamped position, in doubles in the kernel's
// order, stored as float. Random values on an anisotropic grid with short axes (every voxel near an end).
TEST(Filters, GaussianEqualsTheClampedSumOfItsDefinition) {
  msk::Grid g;
  g.dims = {11, 6, 9};
  g.spacing = {0.7, 1.3, 2.1};
  msk::ImageF image(g, 0.0f);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-5, 5);
  for (float& v : image.data) v = u(rng);
  const double sigma = 1.9;
  std::vector<float> ref(image.data.begin(), image.data.end());
  for (int a = 0; a < 3; ++a) {
    const double s = sigma / g.spacing[a];
    const int radius = std::max(1, static_cast<int>(std::ceil(4.0 * s)));
    std::vector<double> k(2 * radius + 1);
    double sum = 0;
    for (int t = -radius; t <= radius; ++t) sum += k[t + radius] = std::exp(-0.5 * t * t / (s * s));
    for (double& w : k) w /= sum;
    const std::vector<float> in = ref;
    for (int z = 0; z < g.dims[2]; ++z)
      for (int y = 0; y < g.dims[1]; ++y)
        for (int x = 0; x < g.dims[0]; ++x) {
          int ijk[3] = {x, y, z};
          double acc = 0;
          for (int t = -radius; t <= radius; ++t) {
            int at[3] = {x, y, z};
            at[a] = std::clamp(ijk[a] + t, 0, g.dims[a] - 1);
            acc += k[t + radius] * in[g.index(at[0], at[1], at[2])];
          }
          ref[g.index(x, y, z)] = static_cast<float>(acc);
        }
  }
  const msk::ImageF smoothed = msk::gaussianSmooth(image, sigma);
  ASSERT_EQ(smoothed.data.size(), ref.size());
  for (size_t i = 0; i < ref.size(); ++i) ASSERT_EQ(smoothed.data[i], ref[i]) << "voxel " << i;
}

TEST(Filters, ResampleOfRampOntoRotatedGridReproducesIt) {
  const msk::Grid src = obliqueGrid();
  const Ramp f;
  const msk::ImageF img = rampImage(src, f);
  msk::Grid dst;
  dst.dims = {30, 30, 30};
  dst.spacing = {0.7, 0.9, 1.3};
  dst.direction = msk::Grid::rotationXYZ({-15, 50, 5});
  // Centre the target on the source so that part of it is inside, part outside.
  const Eigen::Vector3d srcCentre = src.toWorld((src.dims.cast<double>().array() - 1).matrix() / 2);
  dst.origin = srcCentre - dst.direction * dst.spacing.cwiseProduct((dst.dims.cast<double>().array() - 1).matrix() / 2);
  const float outside = -999.f;
  const msk::ImageF r = msk::resample(img, dst, outside);
  int inside = 0, out = 0;
  for (int k = 0; k < dst.dims[2]; ++k)
    for (int j = 0; j < dst.dims[1]; ++j)
      for (int i = 0; i < dst.dims[0]; ++i) {
        const Eigen::Vector3d w = dst.toWorld(Eigen::Vector3d(i, j, k));
        if (msk::sampleTrilinear(img, w)) {
          ++inside;
          EXPECT_NEAR(r.at(i, j, k), f(w), 1e-4);
        } else {
          ++out;
          EXPECT_EQ(r.at(i, j, k), outside);
        }
      }
  EXPECT_GT(inside, 1000);
  EXPECT_GT(out, 1000);
}

TEST(Filters, PercentileInterpolatesBetweenOrderStatistics) {
  msk::Grid g;
  g.dims = {11, 1, 1};
  msk::ImageF img(g);
  for (int i = 0; i < 11; ++i) img.data[i] = static_cast<float>((i * 7) % 11);  // 0..10 shuffled
  EXPECT_DOUBLE_EQ(msk::percentile(img, 0), 0.0);
  EXPECT_DOUBLE_EQ(msk::percentile(img, 100), 10.0);
  EXPECT_DOUBLE_EQ(msk::percentile(img, 50), 5.0);
  EXPECT_NEAR(msk::percentile(img, 25), 2.5, 1e-12);
  EXPECT_NEAR(msk::percentile(img, 99), 9.9, 1e-12);
  // Non-finite values are ignored: with the 10 (data[3]) and the 6 (data[4]) made NaN and ∞, the largest is 9.
  img.data[3] = NAN;
  img.data[4] = INFINITY;
  EXPECT_DOUBLE_EQ(msk::percentile(img, 100), 9.0);
  EXPECT_NEAR(msk::percentile(std::vector<double>{4, 1, 3, 2}, 50), 2.5, 1e-12);
  EXPECT_THROW(msk::percentile(img, 101), msk::ParameterError);
  EXPECT_THROW(msk::percentile(std::vector<double>{NAN}, 50), msk::Error);
}

// Several percentiles in one selection, asked for in any order, are exactly those of sorting the finite values and
// interpolating between neighbouring order statistics; the image's (float) values give the same.
TEST(Filters, PercentilesInOneSelectionEqualSortedOrderStatistics) {
  msk::Grid g;
  g.dims = {1001, 1, 1};
  msk::ImageF img(g);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-50.f, 150.f);
  for (float& v : img.data) v = std::floor(u(rng) * 4.f) / 4.f;  // with ties
  img.data[10] = NAN;
  img.data[500] = -INFINITY;
  std::vector<double> finite;
  for (float v : img.data)
    if (std::isfinite(v)) finite.push_back(v);
  std::vector<double> sorted = finite;
  std::sort(sorted.begin(), sorted.end());
  const std::vector<double> ps = {99, 1, 50, 0, 100, 37.5, 1};
  const std::vector<double> fromValues = msk::percentiles(std::vector<double>(img.data.begin(), img.data.end()), ps);
  const std::vector<double> fromImage = msk::percentiles(img, ps);
  ASSERT_EQ(fromValues.size(), ps.size());
  for (size_t i = 0; i < ps.size(); ++i) {
    const double rank = ps[i] / 100.0 * static_cast<double>(sorted.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(rank));
    const double expected = lo + 1 < sorted.size()
                                ? sorted[lo] + (rank - static_cast<double>(lo)) * (sorted[lo + 1] - sorted[lo])
                                : sorted[lo];
    EXPECT_DOUBLE_EQ(fromValues[i], expected) << "p = " << ps[i];
    EXPECT_EQ(fromImage[i], fromValues[i]) << "p = " << ps[i];
    EXPECT_EQ(msk::percentile(finite, ps[i]), fromValues[i]) << "p = " << ps[i];
  }
  EXPECT_THROW(msk::percentiles(img, {50, 100.5}), msk::ParameterError);
}

TEST(Filters, NormalizeMapsPercentilesToZeroAndOneWithoutClipping) {
  msk::Grid g;
  g.dims = {101, 1, 1};
  msk::ImageF img(g);
  for (int i = 0; i <= 100; ++i) img.data[i] = static_cast<float>(10 + 2 * i);  // p-th percentile = 10 + 2p
  const msk::ImageF n = msk::normalizeIntensity(img, 10, 90);                   // 30 → 0, 190 → 1
  EXPECT_NEAR(n.data[10], 0.0, 1e-6);
  EXPECT_NEAR(n.data[90], 1.0, 1e-6);
  EXPECT_NEAR(n.data[50], 0.5, 1e-6);
  EXPECT_NEAR(n.data[0], -0.125, 1e-6);
  EXPECT_NEAR(n.data[100], 1.125, 1e-6);
  EXPECT_THROW(msk::normalizeIntensity(img, 50, 50), msk::ParameterError);
  EXPECT_THROW(msk::normalizeIntensity(img, -1, 50), msk::ParameterError);
  EXPECT_THROW(msk::normalizeIntensity(img, 10, 100.5), msk::ParameterError);
  EXPECT_THROW(msk::normalizeIntensity(msk::ImageF(g, 3.f), 1, 99), msk::Error);
}
