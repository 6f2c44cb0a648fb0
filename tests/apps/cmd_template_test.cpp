// End-to-end tests of `mskseg template`: a closed template from the bundled sample labels, mirroring, spaces,
// one-line errors with the right exit codes and no partial output.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::CliResult;
using msk::test::expectOneLineError;
using msk::test::lineCount;
using msk::test::runCli;
using msk::test::ScratchDir;

namespace {

const std::string kSampleLabels = msk::test::bundledSample() + "labels.nii.gz";

}  // namespace

TEST(TemplateCli, SampleFemurTemplateIsClosedWithTheLabelsVolume) {
  ScratchDir dir;
  const std::string out = dir.file("femur.vtk");
  CliResult r = runCli({"template", "--labels", kSampleLabels, "--label", "1", "--out", out});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("vertices"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("volume"), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(out));
  msk::MeshSpace space = msk::MeshSpace::RAS;
  const msk::TriangleMesh m = msk::readMesh(out, &space);  // checks closedness
  EXPECT_EQ(space, msk::MeshSpace::LPS);
  EXPECT_EQ(msk::closedMeshProblem(m), "");
  EXPECT_NEAR(m.vertexCount(), 3000, 300);

  const msk::LabelMap labels = msk::readNifti<int32_t>(kSampleLabels);
  const double voxelVolume =
      static_cast<double>(std::count(labels.data.begin(), labels.data.end(), 1)) * labels.grid.spacing.prod();
  EXPECT_NEAR(msk::enclosedVolume(m), voxelVolume, 0.05 * voxelVolume);
  EXPECT_EQ(dir.list(), std::vector<std::string>{"femur.vtk"});

  // Mirrored across x = 10 mm, written in RAS: the same surface reflected.
  const std::string mirrored = dir.file("femur_mirrored.ply");
  CliResult mr = runCli({"template", "--labels", kSampleLabels, "--label", "1", "--mirror-x", "10", "--mesh-space",
                         "ras", "--out", mirrored, "--quiet"});
  ASSERT_EQ(mr.exitCode, 0) << mr.err;
  EXPECT_NE(mr.out.find("mirrored"), std::string::npos) << mr.out;
  const msk::TriangleMesh mm = msk::readMesh(mirrored, &space);
  EXPECT_EQ(space, msk::MeshSpace::RAS);
  EXPECT_GT(msk::enclosedVolume(mm), 0);
  EXPECT_NEAR(msk::enclosedVolume(mm), msk::enclosedVolume(m), 1e-3 * msk::enclosedVolume(m));
  EXPECT_NEAR(mm.vertices.col(0).minCoeff(), 20.0 - m.vertices.col(0).maxCoeff(), 1e-4);
  EXPECT_NEAR(mm.vertices.col(1).mean(), m.vertices.col(1).mean(), 1e-4);

  // Fewer vertices and explicit smoothing.
  CliResult small = runCli({"template", "--labels", kSampleLabels, "--label", "2", "--vertices", "500", "--smooth", "2",
                            "--out", dir.file("quad.stl")});
  ASSERT_EQ(small.exitCode, 0) << small.err;
  EXPECT_NEAR(msk::readMesh(dir.file("quad.stl")).vertexCount(), 500, 50);
}

TEST(TemplateCli, AbsentLabelIsOneLineNamingTheFile) {
  ScratchDir dir;
  const std::string out = dir.file("t.vtk");
  CliResult r = runCli({"template", "--labels", kSampleLabels, "--label", "9", "--out", out});
  expectOneLineError(r, 1, "labels.nii.gz", "label 9 not found");
  EXPECT_NE(r.err.find("labels present: 1, 2, 3, 4"), std::string::npos) << r.err;
  expectOneLineError(runCli({"template", "--labels", dir.file("missing.nii.gz"), "--label", "1", "--out", out}), 1,
                     "missing.nii.gz", "missing.nii.gz");
  EXPECT_TRUE(dir.list().empty()) << "partial output";
}

TEST(TemplateCli, BadOptionsAreUsageErrors) {
  ScratchDir dir;
  const std::string out = dir.file("t.vtk");
  auto run = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"template", "--labels", kSampleLabels, "--out", out};
    args.insert(args.end(), extra.begin(), extra.end());
    return runCli(args);
  };
  expectOneLineError(run({"--label", "1", "--vertices", "abc"}), 2, "", "--vertices");
  expectOneLineError(run({"--label", "1", "--vertices", "3"}), 2, "", "--vertices");
  expectOneLineError(run({"--label", "1", "--vertices", "-100"}), 2, "", "--vertices");
  expectOneLineError(run({"--label", "1", "--smooth", "-1"}), 2, "", "--smooth");
  expectOneLineError(run({"--label", "0"}), 2, "", "--label");
  expectOneLineError(run({}), 2, "", "--label");
  expectOneLineError(run({"--label", "1", "--mesh-space", "xyz"}), 2, "", "xyz");
  expectOneLineError(run({"--label", "1", "--bogus", "1"}), 2, "", "--bogus");
  expectOneLineError(runCli({"template", "--labels", kSampleLabels, "--label", "1", "--out", dir.file("t.xyz")}), 2,
                     "t.xyz", "unsupported");
  EXPECT_TRUE(dir.list().empty()) << "partial output";

  CliResult help = runCli({"template", "--help"});
  EXPECT_EQ(help.exitCode, 0);
  EXPECT_NE(help.out.find("--mirror-x"), std::string::npos);
  EXPECT_NE(runCli({"--help"}).out.find("template"), std::string::npos);
}
