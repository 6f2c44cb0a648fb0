// scripts/ct-example.sh, the real CT scene from the command line alone, runs and gives the CT test's accuracy.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "msk/imaging/json.h"
#include "msk/test/files.h"

// The figures are in docs/measurements.md (Real scans); the guards are those of
// RealScenes.CtFemurHipAndGlutealMusclesOfOneSide, whose templates are also displaced.
TEST(CtExample, RunsFromTheCommandLineAlone) {
  const std::string data = msk::test::sharedData();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  msk::test::ScratchDir dir;
  const std::string cmd = "MSKSEG='" + std::string(MSKSEG_EXE) + "' MSK_OUT_DIR='" + dir.file("ct") + "' bash '" +
                          std::string(MSK_SOURCE_DIR) + "/scripts/ct-example.sh' '" + data + "' > '" +
                          dir.file("log.txt") + "' 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << msk::test::readBytes(dir.file("log.txt"));
  const msk::Json metrics = msk::readJsonFile(dir.file("ct/metrics.json"));
  const msk::Json report = msk::readJsonFile(dir.file("ct/result/report.json"));
  EXPECT_EQ(report.at("overlap_voxels").get<int>(), 0);
  const std::string log = msk::test::readBytes(dir.file("log.txt"));
  EXPECT_NE(log.find("== result"), std::string::npos) << log;  // the script's own table of the figures
  const struct {
    int label;
    const char* name;
    double guard;
  } objects[] = {{76, "femur_right", 0.90},
                 {78, "hip_right", 0.93},
                 {81, "gluteus_maximus_right", 0.87},
                 {83, "gluteus_medius_right", 0.85}};
  for (const auto& o : objects) {
    bool found = false;
    for (const msk::Json& m : metrics.at("metrics"))
      if (m.at("label").get<int>() == o.label) {
        EXPECT_EQ(m.at("object").get<std::string>(), o.name) << "named from the result's label table";
        found = true;
        EXPECT_GE(m.at("dice").get<double>(), o.guard) << "label " << o.label;
      }
    EXPECT_TRUE(found) << "label " << o.label << " in metrics.json";
  }
}
