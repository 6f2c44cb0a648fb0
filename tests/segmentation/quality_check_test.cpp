// The quality check: its figures on a ball in an image and on images without structure, the status its limits give,
// and the status of the bundled thigh scene when it is run where it cannot succeed (template moved 30 mm, pure noise,
// a constant image, the abdominal MR) against the same scene run correctly.
#include "msk/segmentation/quality_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/segmenter.h"
#include "msk/test/ball_scenarios.h"
#include "msk/test/files.h"
#include "msk/test/phantom_scenarios.h"
#include "msk/test/volumes.h"

namespace {

using msk::ObjectQuality;
using msk::QualityStatus;

/// Every object's figures, for the failure messages.
std::string figures(const msk::SegmentationResult& res) {
  std::string s;
  for (const msk::ObjectResult& o : res.objects) {
    const ObjectQuality& q = o.quality;
    s += o.name + ": " + msk::qualityStatusName(q.status) + ", in image " + std::to_string(q.inImageShare) +
         ", edge share " + std::to_string(q.edgeShare) + ", contrast-to-noise " + std::to_string(q.contrastToNoise) +
         (q.contrastJudged ? "" : " (not judged)") + "\n";
  }
  return s;
}

/// A ball of radius 10 mm (200 inside, 800 outside) on a 1 mm grid of ±16 mm.
msk::Grid ballGrid() { return msk::test::boxGrid({1.0, 1.0, 1.0}, {16, 16, 16}); }

/// The figures of `mesh` (dark inside) in `image` at σ = 0.5 mm, for an object whose last pass used `force`.
ObjectQuality measured(const msk::ImageF& image, const msk::TriangleMesh& mesh,
                       msk::TargetMode force = msk::TargetMode::Gradient) {
  const msk::ImageFeatures f = msk::computeImageFeatures(image, 0.5);
  return msk::measureQuality(f, mesh, msk::Polarity::DarkInside, force, msk::imageNoiseSigma(f.smoothed));
}

/// Uniform noise 0..1000 on `g`.
msk::ImageF noiseImage(const msk::Grid& g, unsigned seed) {
  msk::ImageF noise(g, 0.f);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1000.f);
  for (float& x : noise.data) x = u(rng);
  return noise;
}

// The figures of a surface wholly in the image with most of its vertices on an edge: ok by themselves.
ObjectQuality onAnEdge() {
  ObjectQuality q;
  q.inImageShare = 1;
  q.edgeShare = 0.8;
  return q;
}

/// Judges `q` and expects it doubtful for one reason, which names `word`.
void expectDoubtfulFor(ObjectQuality& q, const std::string& word) {
  msk::judgeQuality(q);
  EXPECT_EQ(q.status, QualityStatus::Doubtful);
  ASSERT_EQ(q.reasons.size(), 1u);
  EXPECT_NE(q.reasons[0].find(word), std::string::npos) << q.reasons[0];
}

}  // namespace

// A surface on the ball's boundary is on an edge of its polarity everywhere, with a strong contrast; the same surface
// on a constant image or on pure noise finds no edge standing out of the noise and fails.
TEST(QualityCheck, BallBoundaryIsOkNoiseAndConstantFail) {
  const msk::Grid g = ballGrid();
  const msk::TriangleMesh on = msk::makeIcosphere(10.0, 3);
  const ObjectQuality good = measured(msk::test::ballImage(g, Eigen::Vector3d::Zero(), 10.0, 200.f, 800.f), on);
  EXPECT_EQ(good.status, QualityStatus::Ok) << (good.reasons.empty() ? "" : good.reasons[0]);
  EXPECT_DOUBLE_EQ(good.inImageShare, 1.0);
  EXPECT_GT(good.edgeShare, 0.99);
  EXPECT_GT(good.contrastToNoise, 3.0);

  const ObjectQuality flat = measured(msk::ImageF(g, 500.f), on);
  EXPECT_EQ(flat.status, QualityStatus::Failed);
  EXPECT_EQ(flat.edgeShare, 0.0);
  EXPECT_EQ(flat.contrastToNoise, 0.0);

  const ObjectQuality noise = measured(noiseImage(g, 17), on);
  EXPECT_EQ(noise.status, QualityStatus::Failed);
  EXPECT_LT(noise.edgeShare, 0.05);
  EXPECT_LT(std::abs(noise.contrastToNoise), 0.5);
}

// The noise level of an image: that of the noise added to a ball, not of the ball's edge.
TEST(QualityCheck, NoiseSigmaIsTheNoiseNotTheEdges) {
  const msk::Grid g = ballGrid();
  msk::ImageF img = msk::test::ballImage(g, Eigen::Vector3d::Zero(), 10.0, 200.f, 800.f);
  EXPECT_EQ(msk::imageNoiseSigma(msk::ImageF(g, 3.f)), 0.0);
  std::mt19937 rng(3);
  std::normal_distribution<float> gauss(0.f, 20.f);
  for (float& v : img.data) v += gauss(rng);
  EXPECT_NEAR(msk::imageNoiseSigma(img), 20.0, 2.0);
}

// A surface lying outside the grid fails on that alone. A surface in a region of the wrong contrast (the ball's
// boundary seen by a bright-inside object) fails; one of little contrast is doubtful under the gradient force and not
// judged on contrast under the profile force.
TEST(QualityCheck, OutsideTheImageFailsAndContrastIsJudgedForTheGradientForce) {
  const msk::Grid g = ballGrid();
  const msk::ImageF ball = msk::test::ballImage(g, Eigen::Vector3d::Zero(), 10.0, 200.f, 800.f);
  msk::TriangleMesh away = msk::makeIcosphere(10.0, 3);
  away.vertices.col(0).array() += 100.0;
  const ObjectQuality out = measured(ball, away);
  EXPECT_EQ(out.status, QualityStatus::Failed);
  EXPECT_EQ(out.inImageShare, 0.0);
  ASSERT_EQ(out.reasons.size(), 1u);
  EXPECT_NE(out.reasons[0].find("inside the image"), std::string::npos) << out.reasons[0];

  // A surface running out of the image: its vertices outside count against it, unless the source of its profiles did
  // not show them either (a structure an atlas's scan cut, continued beyond it).
  msk::TriangleMesh through = msk::makeIcosphere(10.0, 3);
  through.vertices.col(0).array() *= 3.0;  // an ellipsoid 60 mm long across the 32 mm image
  const ObjectQuality counted = measured(ball, through);
  EXPECT_LT(counted.inImageShare, 0.7);
  const msk::ImageFeatures f = msk::computeImageFeatures(ball, 0.5);
  const ObjectQuality excused = msk::measureQuality(f, through, msk::Polarity::DarkInside, msk::TargetMode::Gradient,
                                                    msk::imageNoiseSigma(f.smoothed), {},
                                                    [](const Eigen::Vector3d& p) { return std::abs(p.x()) > 12; });
  EXPECT_GT(excused.inImageShare, counted.inImageShare + 0.2);
  EXPECT_LE(excused.inImageShare, 1.0);
  // A vertex outside the image that the source did show still counts.
  const ObjectQuality seen =
      msk::measureQuality(f, through, msk::Polarity::DarkInside, msk::TargetMode::Gradient,
                          msk::imageNoiseSigma(f.smoothed), {}, [](const Eigen::Vector3d& p) { return p.x() > 12; });
  EXPECT_GT(seen.inImageShare, counted.inImageShare);
  EXPECT_LT(seen.inImageShare, excused.inImageShare);

  const ObjectQuality wrong = msk::measureQuality(f, msk::makeIcosphere(10.0, 3), msk::Polarity::BrightInside,
                                                  msk::TargetMode::Gradient, msk::imageNoiseSigma(f.smoothed));
  EXPECT_EQ(wrong.status, QualityStatus::Failed);
  EXPECT_LT(wrong.contrastToNoise, 0.0);

  ObjectQuality weak;
  weak.inImageShare = 1;
  weak.edgeShare = 0.5;
  weak.contrastToNoise = 0.3;
  weak.contrastJudged = true;
  msk::judgeQuality(weak);
  EXPECT_EQ(weak.status, QualityStatus::Doubtful);
  ASSERT_EQ(weak.reasons.size(), 1u);
  EXPECT_NE(weak.reasons[0].find("contrast"), std::string::npos);
  weak.contrastJudged = false;
  msk::judgeQuality(weak);
  EXPECT_EQ(weak.status, QualityStatus::Ok);
  EXPECT_EQ(msk::worseStatus(QualityStatus::Doubtful, QualityStatus::Ok), QualityStatus::Doubtful);
  EXPECT_STREQ(msk::qualityStatusName(QualityStatus::Failed), "failed");
}

// The bundled thigh scene, fast preset: ok where it belongs; flagged with its templates moved 30 mm across the thigh,
// on pure noise of the image's mean and spread on its grid, on a constant image, and on the abdominal MR.
class ThighQuality : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { thigh_ = new msk::test::BundledThigh(msk::test::loadBundledThigh()); }
  static void TearDownTestSuite() {
    delete thigh_;
    thigh_ = nullptr;
  }
  static msk::SegmentOptions fast() {
    msk::SegmentOptions o;
    o.evolution.quality = msk::Quality::Fast;
    return o;
  }
  static msk::SegmentationResult run(const msk::ImageF& image, const msk::Scene& scene) {
    return msk::segmentScene(image, scene, fast());
  }
  static msk::test::BundledThigh* thigh_;
};
msk::test::BundledThigh* ThighQuality::thigh_ = nullptr;

TEST_F(ThighQuality, CorrectRunIsOk) {
  const msk::SegmentationResult res = run(thigh_->image, thigh_->scene);
  EXPECT_EQ(res.status, QualityStatus::Ok) << figures(res);
}

TEST_F(ThighQuality, TemplatesMovedThirtyMillimetresAreFlagged) {
  msk::Scene moved = thigh_->scene;
  for (msk::SceneObject& o : moved.objects) o.templ.vertices.col(0).array() -= 30.0;  // 30 mm along x
  const msk::SegmentationResult res = run(thigh_->image, moved);
  EXPECT_NE(res.status, QualityStatus::Ok) << figures(res);
}

TEST_F(ThighQuality, PureNoiseFails) {
  const msk::ImageF& image = thigh_->image;
  double mean = 0, sq = 0;
  for (float v : image.data) mean += v, sq += double(v) * v;
  mean /= static_cast<double>(image.data.size());
  const double sd = std::sqrt(sq / static_cast<double>(image.data.size()) - mean * mean);
  msk::ImageF noise(image.grid, 0.f);
  std::mt19937 rng(7);
  std::normal_distribution<float> gauss(static_cast<float>(mean), static_cast<float>(sd));
  for (float& v : noise.data) v = gauss(rng);
  const msk::SegmentationResult res = run(noise, thigh_->scene);
  EXPECT_EQ(res.status, QualityStatus::Failed) << figures(res);
}

// Flat but for one corner voxel (a constant image is refused before any work): no edge anywhere near the objects.
TEST_F(ThighQuality, FlatImageFails) {
  msk::ImageF flat(thigh_->image.grid, 300.f);
  flat.at(0, 0, 0) = 0.f;
  const msk::SegmentationResult res = run(flat, thigh_->scene);
  EXPECT_EQ(res.status, QualityStatus::Failed) << figures(res);
  for (const msk::ObjectResult& o : res.objects) EXPECT_EQ(o.quality.status, QualityStatus::Failed) << o.name;
}

TEST_F(ThighQuality, WrongBodyPartIsFlagged) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const msk::SegmentationResult res = run(msk::readNifti<float>(data + "/totalseg-mr/mr.nii.gz"), thigh_->scene);
  EXPECT_NE(res.status, QualityStatus::Ok) << figures(res);
}

// The profile match is judged where it was measured (objects on the profile force) and only there.
TEST(QualityCheck, ProfileMatchIsJudgedWhereMeasured) {
  ObjectQuality q = onAnEdge();
  msk::judgeQuality(q);
  EXPECT_EQ(q.status, QualityStatus::Ok);  // not measured (NaN)
  q.profileMatch = 0.58;                   // the lowest of the correct real-scan runs (an MR vertebra)
  msk::judgeQuality(q);
  EXPECT_EQ(q.status, QualityStatus::Ok);
  q.profileMatch = 0.1;
  ASSERT_NO_FATAL_FAILURE(expectDoubtfulFor(q, "profiles"));
}

// A written surface whose faces cross each other is not a valid closed surface: doubtful, whatever its other figures.
TEST(QualityCheck, CrossingFacesAreDoubtful) {
  ObjectQuality q = onAnEdge();
  q.profileMatch = 0.9;
  msk::judgeQuality(q);
  EXPECT_EQ(q.status, QualityStatus::Ok);
  q.crossingFacePairs = 15;
  ASSERT_NO_FATAL_FAILURE(expectDoubtfulFor(q, "crossing"));
  EXPECT_NE(q.reasons[0].find("15"), std::string::npos) << q.reasons[0];
}
