// End-to-end tests of `mskseg bench`: subcommand dispatch, one-line usage errors with exit code 2, a small fast
// `bench scene` run (the thigh scene on a coarse grid) that prints its figures and writes them atomically, and a
// small `bench tradeoff` run (one phantom, two schemes and one preset) writing the CSV with its header and rows and a
// PNG that decodes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "msk/imaging/json.h"
#include "msk/segmentation/qc_pictures.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

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
  for (const char* word : {"time per stage", "generation", "features", "evolution", "rasterise", "peak memory", "femur",
                           "adductors", "overlap voxels", "penetration"})
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

TEST(TradeoffCli, HelpAndBadArguments) {
  const CliResult h = runCli({"bench", "tradeoff", "--help"});
  ASSERT_EQ(h.exitCode, 0) << h.err;
  EXPECT_NE(h.out.find("--phantoms"), std::string::npos) << h.out;
  EXPECT_NE(runCli({"bench", "--help"}).out.find("tradeoff"), std::string::npos);
  ScratchDir dir;
  const std::string out = dir.file("t");
  expectOneLineError(runCli({"bench", "tradeoff", "--out", out}), 2, "", "--phantoms");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "2"}), 2, "", "--out");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "0", "--out", out}), 2, "", "--phantoms");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "x", "--out", out}), 2, "", "phantoms");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "1", "--seed", "-1", "--out", out}), 2, "", "--seed");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "1", "--threads", "-2", "--out", out}), 2, "",
                     "--threads");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "1", "--schemes", "magic", "--out", out}), 2, "",
                     "magic");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "1", "--presets", "best", "--out", out}), 2, "",
                     "best");
  expectOneLineError(runCli({"bench", "tradeoff", "--phantoms", "1", "--bogus", "1", "--out", out}), 2, "", "bogus");
  expectOneLineError(runCli({"bench", "tradeoff", "extra", "--phantoms", "1", "--out", out}), 2, "", "extra");
  EXPECT_FALSE(fs::exists(out));
}

TEST(TradeoffCli, SmallRunWritesTheCsvAndAPlot) {
  ScratchDir dir;
  const std::string out = dir.file("trade");
  const CliResult r = runCli({"bench", "tradeoff", "--phantoms", "1", "--seed", "2", "--schemes", "gauss-seidel,xpbd",
                              "--presets", "fast", "--out", out, "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const char* word : {"gauss-seidel 1x1", "xpbd 2x2", "preset fast", "Dice", "ASSD", "check"})
    EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
  std::ifstream csv(out + "/tradeoff.csv");
  ASSERT_TRUE(csv.good());
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(csv, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), 1u + 3u + 3u);  // header, one run per setting, one mean per setting
  EXPECT_EQ(lines[0],
            "phantom,seed,setting,scheme,preset,levels,max_steps_per_level,tolerance_mm,substeps,iterations,steps,"
            "seconds,cpu_seconds,dice,assd_mm,peak_rss_mib,ok");
  EXPECT_EQ(lines[1].rfind("2,2,gauss-seidel 1x1,gauss-seidel,balanced,2,50,", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("2,2,xpbd 2x2,xpbd,balanced,2,50,", 0), 0u) << lines[2];
  EXPECT_EQ(lines[3].rfind("2,2,preset fast,xpbd,fast,", 0), 0u) << lines[3];
  for (size_t k = 1; k < lines.size(); ++k) {
    EXPECT_EQ(lines[k].substr(lines[k].size() - 2), ",1") << lines[k];  // every run succeeded
    std::vector<std::string> f;
    size_t a = 0;
    for (size_t b; (b = lines[k].find(',', a)) != std::string::npos; a = b + 1) f.push_back(lines[k].substr(a, b - a));
    f.push_back(lines[k].substr(a));
    ASSERT_EQ(f.size(), 17u) << lines[k];
    EXPECT_GT(std::stod(f[11]), 0.0) << lines[k];  // seconds
    EXPECT_GT(std::stod(f[12]), 0.0) << lines[k];  // CPU seconds
    EXPECT_GT(std::stod(f[13]), 0.9) << lines[k];  // Dice: a plausible femur result
    EXPECT_GT(std::stod(f[14]), 0.0) << lines[k];  // ASSD
    EXPECT_GT(std::stod(f[15]), 0.0) << lines[k];  // peak RSS
  }
  EXPECT_EQ(lines[4].rfind("mean,,gauss-seidel 1x1,", 0), 0u) << lines[4];
  const msk::RgbPicture pic = msk::readRgbPicture(out + "/tradeoff.png");
  EXPECT_GE(pic.width, 600);
  EXPECT_GE(pic.height, 400);
}

// `bench scaling`: the same thigh at two resolutions (templates subdivided 0 and 1 times, x4 vertices), each run
// twice: one CSV row each with the vertices growing about fourfold, every stage's time per vertex-step positive, the
// fastest of the two runs kept (the slowest beside it, no faster), the same anatomy found at both (Dice within 0.03),
// and a PNG that decodes.
TEST(ScalingCli, TwoResolutionsWriteTheCsvAndAPlot) {
  ScratchDir dir;
  const std::string out = dir.file("scaling");
  const CliResult r = runCli(
      {"bench", "scaling", "--subdivisions", "1", "--vertices", "400", "--repeat", "2", "--out", out, "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("evolution per vertex-step at"), std::string::npos) << r.out;
  std::ifstream csv(out + "/scaling.csv");
  std::string line;
  std::vector<std::vector<std::string>> rows;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    size_t a = 0;
    for (size_t b; (b = line.find(',', a)) != std::string::npos; a = b + 1) f.push_back(line.substr(a, b - a));
    f.push_back(line.substr(a));
    rows.push_back(f);
  }
  ASSERT_EQ(rows.size(), 3u);
  ASSERT_EQ(rows[0].size(), 19u);
  EXPECT_EQ(rows[0][17], "runs");
  EXPECT_NE(r.out.find("the fastest of 2 runs at each size"), std::string::npos) << r.out;
  EXPECT_EQ(rows[0][1], "simplex_vertices");
  EXPECT_EQ(rows[0][6], "evolution_us_per_vertex_step");
  const double v0 = std::stod(rows[1][1]), v1 = std::stod(rows[2][1]);
  EXPECT_GT(v1 / v0, 3.0) << v0 << " " << v1;
  EXPECT_LT(v1 / v0, 5.0) << v0 << " " << v1;
  for (size_t k = 1; k < 3; ++k) {
    for (size_t c = 3; c <= 14; ++c) EXPECT_GT(std::stod(rows[k][c]), 0.0) << rows[0][c] << " row " << k;
    EXPECT_GT(std::stod(rows[k][16]), 0.8) << "Dice row " << k;
    EXPECT_EQ(rows[k][17], "2") << "row " << k;
    EXPECT_GE(std::stod(rows[k][18]), std::stod(rows[k][3])) << "the slowest run against the kept one, row " << k;
  }
  EXPECT_NEAR(std::stod(rows[1][16]), std::stod(rows[2][16]), 0.03);
  const msk::RgbPicture pic = msk::readRgbPicture(out + "/scaling.png");
  EXPECT_GE(pic.width, 600);
  expectOneLineError(runCli({"bench", "scaling", "--subdivisions", "9"}), 2, "", "--subdivisions");
  expectOneLineError(runCli({"bench", "scaling", "--repeat", "0"}), 2, "", "--repeat");
}
