// The axis-first coarse stage (DESIGN-NOTES §4): a tubular object whose template is straight and displaced while the
// image shows it bent reaches the image better when its axis is evolved first. The scenarios are shared with
// bench/phantom_bench.cpp, which reports their figures (BM_AxisFirstBentTube, BM_AxisFirstThighMuscle).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "msk/core/error.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segment_report.h"
#include "msk/segmentation/segmenter.h"
#include "msk/test/axis_first_scenarios.h"

namespace {
using msk::test::AxisRun;
using msk::test::BentTube;

class BentTubeIsReached : public ::testing::TestWithParam<msk::test::BentTubeCase> {};
}  // namespace

// A straight template, displaced by 6.7 mm, on a tube bent by up to 12 mm at its ends: with the axis evolved first
// (the object moving as a generalised cylinder of its axis, then the surface) the result is clearly better than
// with the same medial axis and no stage, or with no medial axis; on a straight tube the stage costs nothing. One test
// per case of bentTubeCases() (AxisFirst/BentTubeIsReached.*/straight_moved, bent8, bent12_moved).
TEST_P(BentTubeIsReached, FromADisplacedStraightTemplate) {
  const msk::test::BentTubeCase& c = GetParam();
  SCOPED_TRACE("bend " + std::to_string(c.bendMm));
  const msk::test::BentTubeRuns runs = msk::test::runBentTube(c);
  const AxisRun &plain = runs.plain, &axis = runs.axis, &first = runs.first;
  ASSERT_EQ(first.res.axisFirst.size(), 1u);
  const msk::AxisFirstReport& stage = first.res.axisFirst[0];

  // The stage ran, moved the axis to the image and is reported; the runs without it have no stage.
  EXPECT_EQ(stage.object, "tube");
  EXPECT_GT(stage.steps, 0);
  EXPECT_LE(stage.steps, msk::SegmentOptions().axis.firstSteps);
  EXPECT_GT(stage.seconds, 0.0);
  EXPECT_GT(stage.meanAxisMoveMm, 1.0);
  EXPECT_EQ(first.res.secondsPerStage.count("axis-first"), 1u);
  const msk::Json params = msk::settingsJson(msk::SegmentOptions(), first.res);
  const msk::Json* reported = msk::jsonMember(params, "axis_first_stage");
  ASSERT_NE(reported, nullptr);
  ASSERT_EQ(reported->size(), 1u);
  EXPECT_EQ((*reported)[0].at("steps").get<double>(), stage.steps);
  for (const AxisRun* o : {&plain, &axis}) {
    EXPECT_TRUE(o->res.axisFirst.empty());
    EXPECT_EQ(o->res.secondsPerStage.count("axis-first"), 0u);
    EXPECT_EQ(msk::jsonMember(msk::settingsJson(msk::SegmentOptions(), o->res), "axis_first_stage"), nullptr);
  }

  if (c.bendMm == 0) {  // straight: as good as without the stage
    EXPECT_GE(first.m.dice, 0.98);
    EXPECT_GE(first.m.dice, axis.m.dice - 0.01);
    EXPECT_LE(first.m.assd, axis.m.assd + 0.05);
    return;
  }
  EXPECT_GE(first.m.dice, 0.95);
  EXPECT_LE(first.m.assd, 0.3);
  for (const AxisRun* o : {&plain, &axis}) {
    EXPECT_GE(first.m.dice, o->m.dice + 0.03);
    EXPECT_LE(first.m.assd, 0.5 * o->m.assd);
  }
}

INSTANTIATE_TEST_SUITE_P(AxisFirst, BentTubeIsReached, ::testing::ValuesIn(msk::test::bentTubeCases()),
                         [](const ::testing::TestParamInfo<msk::test::BentTubeCase>& info) {
                           const msk::test::BentTubeCase& c = info.param;
                           std::string name =
                               c.bendMm == 0 ? "straight" : "bent" + std::to_string(std::lround(c.bendMm));
                           if (!c.offsetMm.isZero()) name += "_moved";
                           return name;
                         });

// The run's default (SegmentOptions::axisFirst) applies to objects with a medial axis whose model does not say; a
// model's "axis_first": false overrides it; objects without an axis never run the stage; bad settings are refused.
TEST(AxisFirst, RunDefaultAppliesOnlyToAxisObjectsThatDoNotSay) {
  BentTube tube;
  const msk::ImageF img = msk::test::tubeImage(msk::test::tubeGrid(), tube);
  const msk::TriangleMesh templ = tube.mesh(3);
  msk::SegmentOptions opts;
  EXPECT_FALSE(opts.axis.first);  // off unless asked: existing scenes keep their results
  opts.axis.first = true;
  opts.evolution.levels = 1;
  opts.evolution.maxStepsPerLevel = 3;
  msk::Scene unset = msk::test::tubeScene(templ, true, false);
  unset.objects[0].model.axisFirst.reset();
  EXPECT_EQ(msk::segmentScene(img, unset, opts).axisFirst.size(), 1u);
  EXPECT_TRUE(msk::segmentScene(img, msk::test::tubeScene(templ, true, false), opts).axisFirst.empty());
  EXPECT_TRUE(msk::segmentScene(img, msk::test::tubeScene(templ, false, false), opts).axisFirst.empty());
  EXPECT_TRUE(msk::segmentScene(img, unset, msk::SegmentOptions()).axisFirst.empty());

  msk::SegmentOptions bad = opts;
  bad.axis.firstSteps = -1;
  EXPECT_THROW(msk::segmentScene(img, unset, bad), msk::ParameterError);
  bad = opts;
  bad.axis.firstStage.imageGain = 1.5;
  EXPECT_THROW(msk::segmentScene(img, unset, bad), msk::ParameterError);
  bad = opts;
  bad.axis.firstStage.shapeMemory = -0.5;
  EXPECT_THROW(msk::segmentScene(img, unset, bad), msk::ParameterError);
}

// The phantom thigh's hamstrings and adductors (not tubes around one axis), each alone, their templates moved by
// (8, 4, 0) mm: the stage by itself brings them back to the image. The full runs are measured beside it (bench):
// there the radial constraints of a non-tubular muscle cost accuracy with or without the stage (docs/measurements.md).
TEST(AxisFirst, StageBringsDisplacedThighMusclesBack) {
  for (const char* name : {"hamstrings", "adductors"}) {
    SCOPED_TRACE(name);
    const msk::test::DisplacedMuscleRuns r =
        msk::test::runDisplacedThighMuscle(name, msk::test::FullRuns::AxisFirstOnly);
    EXPECT_GE(r.stage.dice, r.templ.dice + 0.15);
    EXPECT_LE(r.stage.assd, 0.5 * r.templ.assd);
    EXPECT_GE(r.first.dice, 0.85);
  }
}
