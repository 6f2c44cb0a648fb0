// The acceptance check for single objects: the femur of phantoms (the bundled seed and five others, oblique and
// anisotropic grids included) segmented from the mean template: ASSD ≤ 0.6 mm and Dice ≥ 0.95. The scenarios are shared
// with bench/phantom_bench.cpp, which reports the figures (BM_FemurPhantom, BM_FemurPresets).
#include <gtest/gtest.h>

#include <string>
#include <utility>

#include "msk/test/phantom_scenarios.h"
#include "msk/test/shapes.h"

namespace {

void checkFemur(const msk::test::FemurCase& c, const msk::TriangleMesh* templ = nullptr, const std::string& how = "") {
  const msk::test::FemurScore s =
      msk::test::segmentFemur(c, msk::SegmentOptions{}, templ, msk::test::TemplateScores::Skip);
  EXPECT_GE(s.labels.dice, 0.95) << c.name << how;
  EXPECT_LE(s.labels.assd, 0.6) << c.name << how;
  EXPECT_LE(s.mesh.assd, 0.6) << c.name << how;
  EXPECT_EQ(s.quality.status, msk::QualityStatus::Ok)
      << c.name << how << ": " << (s.quality.reasons.empty() ? "" : s.quality.reasons[0]);
}

// Seeds 2–6, anisotropic and oblique grids included: one test per seed (FemurPhantom/FiveOtherSeeds.*/seed<k>).
class FiveOtherSeeds : public ::testing::TestWithParam<msk::test::PhantomCase> {};

}  // namespace

TEST(FemurPhantom, BundledSampleFromTheMeanTemplate) { checkFemur(msk::test::bundledFemur()); }

TEST_P(FiveOtherSeeds, IncludingObliqueAndAnisotropicGrids) { checkFemur(msk::test::phantomFemur(GetParam())); }

INSTANTIATE_TEST_SUITE_P(FemurPhantom, FiveOtherSeeds, ::testing::ValuesIn(msk::test::otherPhantomCases()),
                         [](const ::testing::TestParamInfo<msk::test::PhantomCase>& info) {
                           return "seed" + std::to_string(info.param.seed);
                         });

// Convergence: accuracy rises from the fast preset to the accurate one on these six phantoms. Per phantom the
// differences between neighbouring presets are a few hundredths of a millimetre either way where the template starts
// close (docs/measurements.md: where a level stops sets the prior weight a result carries), so the test asserts the
// mean order and that accurate beats fast on every phantom. Measured (mesh ASSD, mm, fast / balanced / accurate): mean
// 0.394 / 0.342 / 0.292; balanced behind fast on the bundled seed (0.282 / 0.305) and seed 3 (0.500 / 0.509), accurate
// ahead of both on every phantom (0.172–0.445).
TEST(FemurPhantom, PresetsGainAccuracyFromFastToAccurate) {
  const msk::Quality presets[] = {msk::Quality::Fast, msk::Quality::Balanced, msk::Quality::Accurate};
  double mean[3] = {0, 0, 0};
  int cases = 0;
  auto run = [&](const msk::test::FemurCase& c) {
    double assd[3];
    for (int q = 0; q < 3; ++q) {
      msk::SegmentOptions o;
      o.evolution.quality = presets[q];
      assd[q] = msk::test::segmentFemur(c, o, nullptr, msk::test::TemplateScores::Skip).mesh.assd;
      mean[q] += assd[q];
    }
    ++cases;
    EXPECT_LT(assd[2], assd[0]) << c.name << ": accurate no better than fast";
  };
  run(msk::test::bundledFemur());
  for (const msk::test::PhantomCase& c : msk::test::otherPhantomCases()) run(msk::test::phantomFemur(c));
  for (double& m : mean) m /= cases;
  EXPECT_GT(mean[0], mean[1]);
  EXPECT_GT(mean[1], mean[2]);
}

// A template is never exactly in place: displaced by several mm and scaled by ±5 %, the femur still converges.
TEST(FemurPhantom, DisplacedAndScaledTemplate) {
  const msk::test::FemurCase c = msk::test::bundledFemur();
  for (auto [shift, scale] :
       {std::pair{Eigen::Vector3d(5, -3, 4), 1.05}, std::pair{Eigen::Vector3d(-3, 3, -4), 0.95}}) {
    const msk::TriangleMesh t = msk::test::displacedScaled(c.templ, shift, scale);
    checkFemur(c, &t, ", shifted " + std::to_string(shift.norm()) + " mm, scale " + std::to_string(scale));
  }
}
