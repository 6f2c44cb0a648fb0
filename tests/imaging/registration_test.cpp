#include "msk/imaging/registration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <random>

#include "msk/core/error.h"
#include "msk/imaging/filters.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/files.h"

namespace {

using msk::Grid;
using msk::ImageF;
using msk::PriorTransform;
using msk::RegistrationMetric;

/// Accuracy every recovered transform must reach (degrees of rotation, mm at the reference's centre and corners).
constexpr double kMaxDegrees = 1.0, kMaxMm = 1.0;

/// A 4×4 transform: linear part `L` about the world origin, then translation `t` (mm).
Eigen::Matrix4d affine(const Eigen::Matrix3d& L, const Eigen::Vector3d& t) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = L;
  T.topRightCorner<3, 1>() = t;
  return T;
}

/// Rotation of `degrees` about `axis`.
Eigen::Matrix3d rotation(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(degrees * M_PI / 180.0, axis.normalized()).toRotationMatrix();
}

/// An asymmetric phantom in world mm about the origin: a body ellipsoid holding three smaller tilted ellipsoids; the
/// region index (0 = background, 1 = body, 2..4 = inclusions) of a point.
int phantomRegion(const Eigen::Vector3d& x) {
  struct Ellipsoid {
    Eigen::Vector3d centre, axes;
    Eigen::Matrix3d frame;  // columns: axes directions
  };
  static const std::array<Ellipsoid, 4> shapes = {Ellipsoid{{0, 0, 0}, {55, 42, 50}, rotation(10, {0, 0, 1})},
                                                  Ellipsoid{{18, 10, -8}, {20, 11, 16}, rotation(30, {1, 1, 0})},
                                                  Ellipsoid{{-24, -14, 14}, {9, 15, 10}, rotation(-20, {0, 1, 1})},
                                                  Ellipsoid{{-5, 20, 25}, {25, 6, 8}, rotation(40, {1, 0, 0})}};
  int region = 0;
  for (int s = 0; s < 4; ++s) {
    const Eigen::Vector3d u = shapes[s].frame.transpose() * (x - shapes[s].centre);
    if (u.cwiseQuotient(shapes[s].axes).squaredNorm() <= 1) region = s + 1;
  }
  return region;
}

/// Intensities of the regions: a CT-like one and a remapped, partly inverted one (another "modality").
constexpr std::array<float, 5> kFirstModality = {0, 100, 180, 40, 140}, kOtherModality = {150, 30, 90, 200, 0};

/// The phantom moved by `truth` (its value at world y is the phantom's at truth⁻¹·y) on `grid`, each voxel the mean
/// of sub-samples about 1 mm apart (at least 2 per axis), plus Gaussian noise of σ = 8.
ImageF phantomImage(const Grid& grid, const Eigen::Matrix4d& truth, const std::array<float, 5>& values, unsigned seed) {
  const Eigen::Matrix4d inv = truth.inverse() * grid.voxelToWorld();  // voxel → phantom coordinates
  Eigen::Vector3i n;
  for (int a = 0; a < 3; ++a) n[a] = std::max(2, static_cast<int>(std::ceil(grid.spacing[a])));
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, 8.f);
  ImageF img(grid);
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        double sum = 0;
        for (int c = 0; c < n[2]; ++c)
          for (int b = 0; b < n[1]; ++b)
            for (int a = 0; a < n[0]; ++a) {
              const Eigen::Vector4d v(i + (a + 0.5) / n[0] - 0.5, j + (b + 0.5) / n[1] - 0.5,
                                      k + (c + 0.5) / n[2] - 0.5, 1);
              sum += values[phantomRegion((inv * v).head<3>())];
            }
        img.at(i, j, k) = static_cast<float>(sum / n.prod()) + noise(rng);
      }
  return img;
}

/// The reference grid: axis-aligned, anisotropic (1.6 × 1.6 × 4 mm), a 126 mm box centred on the origin.
Grid referenceGrid() {
  Grid g;
  g.dims = {80, 80, 32};
  g.spacing = {1.6, 1.6, 4.0};
  g.origin = -0.5 * (g.dims.cast<double>() - Eigen::Vector3d::Ones()).cwiseProduct(g.spacing);
  return g;
}

/// The subject grid: oblique, left-handed, anisotropic (1.5 × 1.5 × 4 mm), a 220 mm field of view about `centre`.
Grid subjectGrid(const Eigen::Vector3d& centre) {
  Grid g;
  g.dims = {148, 148, 50};
  g.spacing = {1.5, 1.5, 4.0};
  g.direction = Grid::rotationXYZ({12, -18, 25});
  g.direction.col(0) *= -1;
  g.origin = centre - g.direction * (0.5 * (g.dims.cast<double>() - Eigen::Vector3d::Ones()).cwiseProduct(g.spacing));
  return g;
}

/// Largest distance (mm) between a·p and b·p over the corners of the ±45 mm cube (the phantom's inner part).
double cornerMm(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) {
  double worst = 0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector4d p((c & 1) ? 45 : -45, (c & 2) ? 45 : -45, (c & 4) ? 45 : -45, 1);
    worst = std::max(worst, ((a - b) * p).head<3>().norm());
  }
  return worst;
}

/// One synthetic case: the truth, the model and metric to register with, the subject's modality.
struct SyntheticCase {
  const char* name;
  Eigen::Matrix4d truth;
  PriorTransform model;
  RegistrationMetric metric;
  bool otherModality;
};

/// Asserts the accuracy of `result` against `truth` (at the reference's centre, the origin).
void expectRecovered(const char* name, const msk::RegistrationResult& result, const Eigen::Matrix4d& truth,
                     const Eigen::Vector3d& centre) {
  const msk::TransformDifference start = msk::transformDifference(Eigen::Matrix4d::Identity(), truth, centre);
  const msk::TransformDifference d = msk::transformDifference(result.transform, truth, centre);
  const double corners = cornerMm(result.transform, truth);
  const std::string figures = std::string(name) + ": start " + std::to_string(start.degrees) + " deg " +
                              std::to_string(start.mm) + " mm; error at the corners " + std::to_string(corners) +
                              " mm (bench/registration_bench prints the timings)";
  ::testing::Test::RecordProperty(
      std::string(name) + "_error_deg_mm_corners",
      std::to_string(d.degrees) + " " + std::to_string(d.mm) + " " + std::to_string(corners));
  EXPECT_LT(d.degrees, kMaxDegrees) << figures;
  EXPECT_LT(d.mm, kMaxMm) << figures;
  EXPECT_GT(result.metric, result.startMetric) << figures;
  EXPECT_GT(result.overlap, 0.9) << figures;
}

class SyntheticRegistration : public ::testing::TestWithParam<SyntheticCase> {};

TEST_P(SyntheticRegistration, RecoversKnownTransformFromFarStart) {
  const SyntheticCase& c = GetParam();
  const Grid rg = referenceGrid();
  const ImageF reference = phantomImage(rg, Eigen::Matrix4d::Identity(), kFirstModality, 1);
  const ImageF subject = phantomImage(subjectGrid(c.truth.topRightCorner<3, 1>()), c.truth,
                                      c.otherModality ? kOtherModality : kFirstModality, 2);
  msk::RegistrationOptions opts;
  opts.model = c.model;
  opts.metric = c.metric;
  const msk::RegistrationResult r = msk::registerImages(reference, subject, opts);
  expectRecovered(c.name, r, c.truth, Eigen::Vector3d::Zero());
  if (c.model == PriorTransform::Affine) {
    EXPECT_LT(cornerMm(r.transform, c.truth), kMaxMm);
  }
  ASSERT_FALSE(r.stages.empty());
  EXPECT_EQ(r.stages.front().name, "search");
}

/// Starts 25° and about 40 mm away (the start is the identity), rigid, similarity and affine truths, both metrics.
const SyntheticCase kSyntheticCases[] = {
    {"rigid_ncc", affine(rotation(25, {1, 2, -1}), {30, -20, 20}), PriorTransform::Rigid, RegistrationMetric::Ncc,
     false},
    {"rigid_ncc_negative", affine(rotation(-25, {-2, 1, 1}), {-25, 28, -18}), PriorTransform::Rigid,
     RegistrationMetric::Ncc, false},
    {"similarity_ncc", affine(1.08 * rotation(-20, {0, 1, 2}), {-28, 25, -15}), PriorTransform::Similarity,
     RegistrationMetric::Ncc, false},
    {"affine_ncc",
     affine(
         rotation(18, {2, -1, 1}) * (Eigen::Matrix3d() << 1.06, 0.04, 0, -0.03, 0.95, 0.05, 0, 0.02, 1.03).finished(),
         {20, 30, -20}),
     PriorTransform::Affine, RegistrationMetric::Ncc, false},
    {"rigid_mi_other_modality", affine(rotation(25, {1, -1, 2}), {-30, -25, 15}), PriorTransform::Rigid,
     RegistrationMetric::MattesMi, true},
    {"similarity_mi_other_modality", affine(0.94 * rotation(-22, {1, 1, 1}), {25, -20, 28}), PriorTransform::Similarity,
     RegistrationMetric::MattesMi, true},
};
INSTANTIATE_TEST_SUITE_P(Cases, SyntheticRegistration, ::testing::ValuesIn(kSyntheticCases),
                         [](const auto& info) { return std::string(info.param.name); });

/// Turned far beyond the search grid's ±30° (a subject scanned prone, or on its side): found from the principal axes
/// of both images' bright parts.
const SyntheticCase kTurnedCases[] = {
    {"rigid_ncc_turned_90", affine(rotation(90, {0, 0, 1}), {20, -15, 10}), PriorTransform::Rigid,
     RegistrationMetric::Ncc, false},
    {"rigid_ncc_turned_150", affine(rotation(150, {1, 1, 0}), {-10, 25, -20}), PriorTransform::Rigid,
     RegistrationMetric::Ncc, false},
    {"similarity_mi_turned_120", affine(1.05 * rotation(120, {-1, 2, 1}), {15, 10, -25}), PriorTransform::Similarity,
     RegistrationMetric::MattesMi, true},
};
INSTANTIATE_TEST_SUITE_P(Turned, SyntheticRegistration, ::testing::ValuesIn(kTurnedCases),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace

namespace {

/// `image` with its header moved by the world transform `W` (rigid): the same voxels, now at W·x.
ImageF movedHeader(const ImageF& image, const Eigen::Matrix4d& W) {
  ImageF out = image;
  out.grid.direction = W.topLeftCorner<3, 3>() * image.grid.direction;
  out.grid.origin = W.topLeftCorner<3, 3>() * image.grid.origin + W.topRightCorner<3, 1>();
  return out;
}

/// Registers a 120 mm crop of the scan's middle onto the whole scan moved by 15° and 40 mm (its header only).
void registerMovedScan(const std::string& file, RegistrationMetric metric, const char* name) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const ImageF scan = msk::readNifti<float>(data + file);
  const auto bounds = scan.grid.worldBounds();
  const Eigen::Vector3d middle = 0.5 * (bounds[0] + bounds[1]);
  const ImageF reference =
      msk::cropToWorldBox(scan, middle - Eigen::Vector3d::Constant(60), middle + Eigen::Vector3d::Constant(60));
  const Eigen::Matrix4d truth = affine(rotation(15, {1, -2, 1}), Eigen::Vector3d::Zero()) *
                                affine(Eigen::Matrix3d::Identity(), -middle);  // about the middle ...
  Eigen::Matrix4d W = truth;
  W.topRightCorner<3, 1>() += middle + Eigen::Vector3d(24, -24, 20);  // ... then 40 mm away
  msk::RegistrationOptions opts;
  opts.metric = metric;
  opts.model = PriorTransform::Rigid;
  const msk::RegistrationResult r = msk::registerImages(reference, movedHeader(scan, W), opts);
  expectRecovered(name, r, W, middle);
}

/// The whole scan onto itself turned over (prone for supine: 180° about the body's long axis) and moved 30 mm, its
/// header only: beyond the search grid, found from the principal axes.
void registerTurnedOverScan(const std::string& file, RegistrationMetric metric, const char* name) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const ImageF scan = msk::readNifti<float>(data + file);
  const auto bounds = scan.grid.worldBounds();
  const Eigen::Vector3d middle = 0.5 * (bounds[0] + bounds[1]);
  Eigen::Matrix4d W =
      affine(rotation(180, {0, 0, 1}), Eigen::Vector3d::Zero()) * affine(Eigen::Matrix3d::Identity(), -middle);
  W.topRightCorner<3, 1>() += middle + Eigen::Vector3d(18, -12, 20);
  msk::RegistrationOptions opts;
  opts.metric = metric;
  opts.model = PriorTransform::Rigid;
  const msk::RegistrationResult r = msk::registerImages(scan, movedHeader(scan, W), opts);
  expectRecovered(name, r, W, middle);
}

TEST(RealScanRegistration, CtTurnedOver) {
  registerTurnedOverScan("/totalseg-ct/ct.nii.gz", RegistrationMetric::Ncc, "ct");
}

TEST(RealScanRegistration, MrTurnedOver) {
  registerTurnedOverScan("/totalseg-mr/mr.nii.gz", RegistrationMetric::Ncc, "mr");
}

TEST(RealScanRegistration, CtCropOntoMovedCt) {
  registerMovedScan("/totalseg-ct/ct.nii.gz", RegistrationMetric::Ncc, "ct_ncc");
}

TEST(RealScanRegistration, MrCropOntoMovedMr) {
  registerMovedScan("/totalseg-mr/mr.nii.gz", RegistrationMetric::Ncc, "mr_ncc");
}

TEST(RealScanRegistration, MrCropOntoMovedMrWithMutualInformation) {
  registerMovedScan("/totalseg-mr/mr.nii.gz", RegistrationMetric::MattesMi, "mr_mi");
}

}  // namespace

namespace {

/// A small reference and subject for the input checks: the phantom on coarse grids.
struct SmallPair {
  ImageF reference, subject;
  SmallPair() {
    Grid g;
    g.dims = {30, 30, 12};
    g.spacing = {4, 4, 10};
    g.origin = -0.5 * (g.dims.cast<double>() - Eigen::Vector3d::Ones()).cwiseProduct(g.spacing);
    reference = phantomImage(g, Eigen::Matrix4d::Identity(), kFirstModality, 3);
    subject = phantomImage(g, affine(rotation(5, {0, 0, 1}), {3, 0, 0}), kFirstModality, 4);
  }
};

TEST(RegistrationInput, ConstantImagesThrowError) {
  SmallPair p;
  msk::RegistrationOptions opts;
  ImageF flat = p.reference;
  std::fill(flat.data.begin(), flat.data.end(), 7.f);
  try {
    msk::registerImages(flat, p.subject, opts);
    FAIL() << "no throw";
  } catch (const msk::ParameterError&) {
    FAIL() << "a constant image is not a parameter error";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("reference image is constant"), std::string::npos) << e.what();
  }
  flat.grid = p.subject.grid;
  EXPECT_THROW(msk::registerImages(p.reference, flat, opts), msk::Error);
}

TEST(RegistrationInput, NoOverlapAtStartThrowsError) {
  SmallPair p;
  const Eigen::Matrix4d far = affine(Eigen::Matrix3d::Identity(), {1000, 0, 0});
  for (bool initialise : {true, false}) {
    msk::RegistrationOptions opts;
    opts.initialise = initialise;
    try {
      msk::registerImages(p.reference, p.subject, opts, far);
      FAIL() << "no throw";
    } catch (const msk::Error& e) {
      EXPECT_NE(std::string(e.what()).find("does not overlap"), std::string::npos) << e.what();
    }
  }
}

TEST(RegistrationInput, BadOptionsThrowParameterError) {
  SmallPair p;
  const std::vector<std::function<void(msk::RegistrationOptions&)>> breakers = {
      [](auto& o) { o.searchDegrees = 0; },       [](auto& o) { o.searchDegrees = NAN; },
      [](auto& o) { o.searchScale = -0.1; },      [](auto& o) { o.searchScale = 1; },
      [](auto& o) { o.maxIterations = 0; },       [](auto& o) { o.threads = -1; },
      [](auto& o) { o.maxSamples = 10; },         [](auto& o) { o.levelSpacingMm = {4, 0}; },
      [](auto& o) { o.levelSpacingMm = {2, 4}; }, [](auto& o) { o.levelSpacingMm = {INFINITY}; }};
  for (size_t b = 0; b < breakers.size(); ++b) {
    msk::RegistrationOptions opts;
    breakers[b](opts);
    EXPECT_THROW(msk::registerImages(p.reference, p.subject, opts), msk::ParameterError) << "case " << b;
  }
  Eigen::Matrix4d singular = Eigen::Matrix4d::Identity();
  singular(2, 2) = 0;
  EXPECT_THROW(msk::registerImages(p.reference, p.subject, {}, singular), msk::ParameterError);
}

TEST(RegistrationInput, ResultDoesNotDependOnThreadCount) {
  SmallPair p;
  msk::RegistrationOptions opts;
  opts.model = PriorTransform::Affine;
  opts.maxSamples = 100000;
  opts.levelSpacingMm = {8, 4};
  opts.threads = 1;
  const msk::RegistrationResult one = msk::registerImages(p.reference, p.subject, opts);
  opts.threads = 3;
  const msk::RegistrationResult three = msk::registerImages(p.reference, p.subject, opts);
  EXPECT_TRUE(one.transform == three.transform);
  EXPECT_EQ(one.metric, three.metric);
  ASSERT_EQ(one.stages.size(), 1u + 3u * 2u);  // search, then rigid, similarity, affine at 8 and 4 mm
  EXPECT_EQ(one.stages[1].name, "rigid 8 mm");
  EXPECT_EQ(one.stages.back().name, "affine 4 mm");
}

TEST(RegistrationHelpers, MetricNamesRoundTrip) {
  for (RegistrationMetric m : {RegistrationMetric::Ncc, RegistrationMetric::MattesMi})
    EXPECT_EQ(msk::parseRegistrationMetric(msk::registrationMetricName(m)), m);
  EXPECT_FALSE(msk::parseRegistrationMetric("mutual").has_value());
}

TEST(RegistrationHelpers, GuessModalityFromHounsfieldRange) {
  SmallPair p;
  EXPECT_EQ(msk::guessModality(p.reference), "mr");
  ImageF ct = p.reference;
  for (float& v : ct.data) v = v * 10 - 1000;
  EXPECT_EQ(msk::guessModality(ct), "ct");
}

TEST(RegistrationHelpers, CropKeepsWorldPositionsOnObliqueGrid) {
  const ImageF image = phantomImage(subjectGrid({5, -3, 2}), Eigen::Matrix4d::Identity(), kFirstModality, 5);
  const Eigen::Vector3d lo(-20, -30, -10), hi(25, 15, 30);
  const ImageF crop = msk::cropToWorldBox(image, lo, hi);
  EXPECT_LT(crop.grid.voxelCount(), image.grid.voxelCount());
  EXPECT_TRUE(crop.grid.direction.isApprox(image.grid.direction));
  for (const Eigen::Vector3i& ijk :
       {Eigen::Vector3i(0, 0, 0), Eigen::Vector3i(crop.grid.dims - Eigen::Vector3i::Ones())}) {
    const Eigen::Vector3d x = crop.grid.toWorld(ijk.cast<double>());
    const Eigen::Vector3d v = image.grid.toVoxel(x);
    const Eigen::Vector3i src = v.array().round().cast<int>();
    EXPECT_LT((v - src.cast<double>()).norm(), 1e-6);  // crop voxels are source voxels
    EXPECT_EQ(crop.at(ijk[0], ijk[1], ijk[2]), image.at(src[0], src[1], src[2]));
  }
  EXPECT_THROW(msk::cropToWorldBox(image, {1000, 1000, 1000}, {1010, 1010, 1010}), msk::Error);
}

TEST(RegistrationHelpers, TransformDifferenceOfKnownTransforms) {
  const Eigen::Matrix4d a = affine(1.1 * rotation(12, {1, 1, 0}), {3, 4, 0});
  const msk::TransformDifference same = msk::transformDifference(a, a);
  EXPECT_NEAR(same.degrees, 0, 1e-6);
  EXPECT_NEAR(same.mm, 0, 1e-12);
  const msk::TransformDifference d = msk::transformDifference(a, Eigen::Matrix4d::Identity(), {0, 0, 0});
  EXPECT_NEAR(d.degrees, 12, 1e-6);  // the scale is not a rotation
  EXPECT_NEAR(d.mm, 5, 1e-12);
}

}  // namespace
