// Volume models on anatomy: "volume preserved within 2 % under the image forces unless the image demands otherwise".
// A muscle as a 3-simplex volume model, its template its true surface (a) moved rigidly, so the image asks for no
// change of volume, and (b) also scaled, so the image does ask for one: the object in the image keeps the volume of
// the true surface, and the model must reach it rather than keep the template's. "The image demands otherwise" is
// therefore decided by the ground truth: whether the true volume differs from the template's. The muscles: the bundled
// phantom's hamstrings and, when the shared data are there, the left autochthon muscle of totalseg-mr from its own
// label. The scenarios are shared with bench/volume_model_bench.cpp, which reports their figures (and those of the
// other phantom muscles, other scales and the tetrahedralisation's cost).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "msk/test/files.h"
#include "msk/test/volume_model_scenarios.h"

// Each template the true surface moved rigidly by 3.5 mm and 4° (the image asks for no volume change: the model keeps
// its volume within 2 %, Dice ≥ 0.95) and the same also scaled by 0.92 (the image asks for +30 % of volume: the model
// must follow, ending at least 10 % from the template's volume and where the image forces take a plain surface model
// from the same start, within 3.5 % of its volume). The true volume is not the bound of the second case: the image
// force alone stops 3–5 % short of it (blur and partial volume, a surface model as much), and within the preset's 60
// steps a level the volume model is still creeping outwards on the autochthon, so where it stops depends on rounding:
// −4.6 % of the true volume with GCC, −5.95 % with clang (given 120 / 240 steps: GCC −4.0 / −4.0 %, clang −3.9 /
// −4.6 %). Measured,
// hamstrings / autochthon: kept +0.00 % / −0.00 % (Dice 0.841 → 0.972 / 0.867 → 0.967); scaled +23.4 % / +23.2 %,
// against the surface model +1.2 % / −1.4 % (clang −2.8 %), Dice 0.971 / 0.953 (clang 0.949). No inverted tet at the
// end, of about 15 600 (phantom) and 11 200 (real), the tet boundary on the surface's vertices (0 mm off).
TEST(VolumeModel, KeepsItsVolumeUnlessTheImageDemandsOtherwise) {
  std::vector<msk::test::VolumeCase> cases;
  cases.push_back(msk::test::phantomMuscleCase("hamstrings"));
  const std::string data = msk::test::sharedData();
  if (!data.empty()) cases.push_back(msk::test::realAutochthonCase(data));
  for (const msk::test::VolumeCase& c : cases) {
    SCOPED_TRACE(c.name);
    for (double scale : {1.0, 0.92}) {
      const msk::test::VolumeRun r = msk::test::runMovedTruth(c, 4.0, scale, msk::test::RestQuality::Skip);
      EXPECT_GT(r.dice, r.templateDice + 0.05);
      EXPECT_GE(r.dice, scale == 1.0 ? 0.95 : 0.94);
      if (scale == 1.0) {
        EXPECT_LT(std::fabs(r.changePercent()), 2.0);  // kept
        EXPECT_EQ(r.decision, "holding");
      } else {
        EXPECT_EQ(r.decision, "following");
        EXPECT_GT(r.changePercent(), 10.0);  // followed the image
        const double surfaceMm3 = msk::test::surfaceModelMovedTruthMm3(c, 4.0, scale);
        EXPECT_LT(std::fabs(r.modelMm3 / surfaceMm3 - 1.0), 0.035) << "surface model " << surfaceMm3 << " mm³";
        EXPECT_LT(std::fabs(r.errorPercent()), 8.0);  // and near the true volume
      }
      // None inverted (every tet has an interior node, tetrahedralize's interiorNodes; the recovered mesh untangled).
      EXPECT_EQ(r.inverted, 0);
    }
  }
}
