// End-to-end tests of `mskseg bench`: subcommand dispatch, one-line usage errors with exit code 2, and a small fast
// `bench scene` run (the thigh scene on a coarse grid) that prints its figures and writes them atomically.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "msk/imaging/json.h"
#include "msk/test/files.h"
#include "msk/test/cli.h"

namespace fs = std::filesystem;
using msk::test::CliResult;
using msk::test::expectOneLineError;
using msk::test::runCli;
using msk::test::ScratchDir;

TEST(BenchCli, HelpListsTheBenchmarks) {
  const CliResult r = runCli({"bench", "--help"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("scene"), std::string::npos) << r.out;
  const CliResult s = runCli({"bench", "scene", "--help"});
  ASSERT_EQ(s.exitCode, 0) << s.err;
  EXPECT_NE(s.out.find("--structures"), std::string::npos) << s.out;
  EXPECT_NE(runCli({"--help"}).out.find("bench"), std::string::npos);
}

TEST(BenchCli, BadArgumentsAreOneLineUsageErrors) {
  expectOneLineError(runCli({"bench"}), 2, "", "missing benchmark");
  expectOneLineError(runCli({"bench", "nosuch"}), 2, "", "unknown benchmark 'nosuch'");
  expectOneLineError(runCli({"bench", "scene", "--structures", "7"}), 2, "", "--structures");
  expectOneLineError(runCli({"bench", "scene", "--structures", "many"}), 2, "", "structures");
  expectOneLineError(runCli({"bench", "scene", "--quality", "best"}), 2, "", "best");
  expectOneLineError(runCli({"bench", "scene", "--seed", "-3"}), 2, "", "--seed");
  expectOneLineError(runCli({"bench", "scene", "--spacing", "0,1,1"}), 2, "", "spacing");
  expectOneLineError(runCli({"bench", "scene", "--bogus", "1"}), 2, "", "bogus");
  expectOneLineError(runCli({"bench", "scene", "extra"}), 2, "", "extra");
}

TEST(BenchCli, PhantomRejectsOtherStructureCounts) {
  ScratchDir dir;
  expectOneLineError(runCli({"phantom", "--structures", "12", "--out", dir.file("p")}), 2, "", "--structures");
  EXPECT_FALSE(fs::exists(dir.file("p")));
}

TEST(BenchCli, SmallSceneRunPrintsStagesAndWritesFigures) {
  ScratchDir dir;
  const std::string out = dir.file("figures");
  const CliResult r = runCli({"bench", "scene", "--structures", "4", "--quality", "fast", "--spacing", "2.4,2.4,4",
                              "--vertices", "500", "--out", out, "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const char* word : {"time per stage", "generation", "features", "evolution", "rasterise", "peak memory",
                           "femur", "adductors", "overlap voxels", "penetration"})
    EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
  ASSERT_TRUE(fs::exists(out + "/bench.json"));
  ASSERT_TRUE(fs::exists(out + "/objects.csv"));
  const msk::Json j = msk::readJsonFile(out + "/bench.json");
  EXPECT_EQ(j.at("structures").get<int>(), 4);
  EXPECT_EQ(j.at("collision_pairs").get<int>(), 6);
  ASSERT_EQ(j.at("objects").size(), 4u);
  for (const msk::Json& o : j.at("objects")) EXPECT_GT(o.at("dice").get<double>(), 0.8) << o.dump();
  EXPECT_GT(j.at("seconds_per_stage").at("whole").get<double>(), 0.0);
  EXPECT_GT(j.at("peak_rss_mib").get<double>(), 0.0);
  EXPECT_EQ(j.at("pairs").size(), 6u);
  // No staging folder left beside the output.
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
}
