// End-to-end tests of the mskseg program: exit codes, one-line errors naming the file, no partial output.
#include "msk/test/cli.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/surface_quality.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::CliResult;
using msk::test::expectOneLineError;
using msk::test::lineCount;
using msk::test::runCli;
using msk::test::ScratchDir;

namespace {
msk::Volume<double> smallVolume() {
  msk::Grid g;
  g.dims = {6, 5, 4};
  g.spacing = {1.0, 1.5, 2.0};
  g.origin = {-3, 4, 5};
  msk::Volume<double> v(g, 0.0);
  for (size_t i = 0; i < v.data.size(); ++i) v.data[i] = static_cast<double>(i % 17);
  return v;
}
}  // namespace

TEST(Cli, HelpVersionAndUsageErrors) {
  CliResult h = runCli({"--help"});
  EXPECT_EQ(h.exitCode, 0);
  for (const char* c : {"info", "phantom", "eval", "rasterize", "convert"}) EXPECT_NE(h.out.find(c), std::string::npos);
  CliResult v = runCli({"--version"});
  EXPECT_EQ(v.exitCode, 0);
  EXPECT_NE(v.out.find(MSK_VERSION), std::string::npos);
  EXPECT_EQ(runCli({}).exitCode, 2);
  expectOneLineError(runCli({"frobnicate"}), 2, "", "unknown command");
  expectOneLineError(runCli({"info", "--bogus", "x"}), 2, "", "unknown option or unexpected argument: --bogus");
  expectOneLineError(runCli({"phantom", "--seed", "1"}), 2, "", "--out is required");
  expectOneLineError(runCli({"phantom", "--out", "/tmp/x", "--noise", "abc"}), 2, "", "--noise");
  for (const char* c : {"info", "phantom", "eval", "rasterize", "convert"})
    EXPECT_EQ(runCli({c, "--help"}).exitCode, 0);
}

TEST(Cli, InfoDescribesVolumeAndMesh) {
  ScratchDir dir;
  msk::writeNifti(dir.file("v.nii.gz"), smallVolume(), msk::DataType::Int16);
  CliResult r = runCli({"info", dir.file("v.nii.gz")});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("6 x 5 x 4"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("int16"), std::string::npos);
  EXPECT_NE(r.out.find("sform"), std::string::npos);
  CliResult j = runCli({"info", "--json", dir.file("v.nii.gz")});
  ASSERT_EQ(j.exitCode, 0) << j.err;
  msk::Json info = msk::parseJson(j.out);
  EXPECT_EQ(info.at("dims")[2].get<int>(), 4);
  EXPECT_DOUBLE_EQ(info.at("spacing_mm")[1].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(info.at("max").get<double>(), 16.0);
  EXPECT_EQ(info.at("nonfinite_count").get<int>(), 0);

  msk::writeMesh(dir.file("s.vtk"), msk::makeIcosphere(10, 3));
  CliResult m = runCli({"info", "--json", dir.file("s.vtk")});
  ASSERT_EQ(m.exitCode, 0) << m.err;
  msk::Json mj = msk::parseJson(m.out);
  EXPECT_EQ(mj.at("file_space").get<std::string>(), "LPS");
  EXPECT_NEAR(mj.at("volume_mm3").get<double>(), 4.0 / 3.0 * M_PI * 1000, 0.02 * 4.0 / 3.0 * M_PI * 1000);
}

// info --labels: each non-zero label's voxel count, volume and centroid in RAS mm (on a grid with spacing and origin),
// in the text table and in JSON; a volume with fractional values is refused naming the file.
TEST(Cli, InfoListsTheLabelsOfALabelMap) {
  ScratchDir dir;
  msk::Grid g;
  g.dims = {6, 5, 4};
  g.spacing = {1.0, 1.5, 2.0};
  g.origin = {-3, 4, 5};
  msk::Volume<double> v(g, 0.0);
  v.at(1, 1, 1) = v.at(3, 1, 1) = 7;  // label 7: centroid at voxel (2, 1, 1)
  v.at(5, 4, 3) = 300;                // label 300: one voxel
  msk::writeNifti(dir.file("l.nii.gz"), v, msk::DataType::Int16);
  CliResult r = runCli({"info", "--labels", dir.file("l.nii.gz")});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("2 besides 0"), std::string::npos) << r.out;
  // label 7: 2 voxels of 3 mm3, centroid (-3 + 2, 4 + 1.5, 5 + 2) mm
  EXPECT_NE(r.out.find("       7          2       0.006     -1.00      5.50      7.00"), std::string::npos) << r.out;
  CliResult j = runCli({"info", "--json", "--labels", dir.file("l.nii.gz")});
  ASSERT_EQ(j.exitCode, 0) << j.err;
  const msk::Json info = msk::parseJson(j.out);
  const auto& labels = info.at("labels");
  ASSERT_EQ(labels.size(), 2u);
  EXPECT_EQ(labels[1].at("label").get<int>(), 300);
  EXPECT_EQ(labels[1].at("voxels").get<int>(), 1);
  EXPECT_DOUBLE_EQ(labels[1].at("centroid_ras_mm")[0].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(labels[1].at("centroid_ras_mm")[1].get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(labels[1].at("centroid_ras_mm")[2].get<double>(), 11.0);
  EXPECT_DOUBLE_EQ(labels[0].at("volume_ml").get<double>(), 0.006);

  v.at(0, 0, 0) = 0.5;
  msk::writeNifti(dir.file("f.nii.gz"), v, msk::DataType::Float32);
  expectOneLineError(runCli({"info", "--labels", dir.file("f.nii.gz")}), 1, "f.nii.gz", "whole-number");
}

TEST(Cli, InfoOnRealCtGivesTheRightOrigin) {
  if (msk::test::sharedData().empty()) GTEST_SKIP() << "../shared/data absent";
  CliResult r = runCli({"info", "--json", msk::test::sharedData() + "/totalseg-ct/ct.nii.gz"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  msk::Json j = msk::parseJson(r.out);
  const auto& o = j.at("origin_ras_mm");
  EXPECT_NEAR(o[0].get<double>(), -177.96, 0.01);
  EXPECT_NEAR(o[1].get<double>(), 11.32, 0.01);
  EXPECT_NEAR(o[2].get<double>(), 94.30, 0.01);
}

TEST(Cli, BadVolumesGiveOneLineNamingTheFile) {
  ScratchDir dir;
  expectOneLineError(runCli({"info", dir.file("missing.nii.gz")}), 1, "missing.nii.gz", "missing.nii.gz");
  msk::test::writeBytes(dir.file("text.nii"), std::string(400, 'x'));
  CliResult magic = runCli({"info", dir.file("text.nii")});
  EXPECT_EQ(magic.exitCode, 1);
  EXPECT_EQ(lineCount(magic.err), 1) << magic.err;
  EXPECT_NE(magic.err.find("text.nii"), std::string::npos);

  msk::writeNifti(dir.file("good.nii.gz"), smallVolume(), msk::DataType::Float32);
  std::string gz = msk::test::readBytes(dir.file("good.nii.gz"));
  msk::test::writeBytes(dir.file("cut.nii.gz"), gz.substr(0, gz.size() / 2));
  CliResult cut = runCli({"info", dir.file("cut.nii.gz")});
  EXPECT_EQ(cut.exitCode, 1);
  EXPECT_EQ(lineCount(cut.err), 1) << cut.err;
  EXPECT_NE(cut.err.find("cut.nii.gz"), std::string::npos);

  msk::Volume<double> nan = smallVolume();
  nan.data[3] = NAN;
  msk::writeNifti(dir.file("nan.nii"), nan, msk::DataType::Float32);
  // info reports NaNs (it is the tool to find them); eval refuses them.
  CliResult ni = runCli({"info", "--json", dir.file("nan.nii")});
  ASSERT_EQ(ni.exitCode, 0) << ni.err;
  EXPECT_EQ(msk::parseJson(ni.out).at("nonfinite_count").get<int>(), 1);
  CliResult ne = runCli({"eval", "--result", dir.file("nan.nii"), "--reference", dir.file("good.nii.gz")});
  expectOneLineError(ne, 1, "nan.nii", "NaN");
}

TEST(Cli, ConvertRoundTripsAndRefusesOpenMeshes) {
  ScratchDir dir;
  msk::TriangleMesh s = msk::makeIcosphere(8, 3, {10, -20, 30});
  msk::writeMesh(dir.file("s.vtk"), s);
  CliResult c = runCli({"convert", dir.file("s.vtk"), dir.file("s.ply"), "--mesh-space", "ras"});
  ASSERT_EQ(c.exitCode, 0) << c.err;
  msk::MeshSpace sp = msk::MeshSpace::LPS;
  msk::TriangleMesh back = msk::readMesh(dir.file("s.ply"), &sp);
  EXPECT_EQ(sp, msk::MeshSpace::RAS);
  EXPECT_LT((back.vertices - s.vertices).cwiseAbs().maxCoeff(), 1e-4);

  msk::test::writeBytes(dir.file("open.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\n");
  CliResult open = runCli({"convert", dir.file("open.obj"), dir.file("open.vtk")});
  EXPECT_EQ(open.exitCode, 1);
  EXPECT_EQ(lineCount(open.err), 1) << open.err;
  EXPECT_NE(open.err.find("open.obj"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir.file("open.vtk")));
  expectOneLineError(runCli({"convert", dir.file("s.vtk"), dir.file("s.xyz")}), 2, "s.xyz", "unsupported");
  expectOneLineError(runCli({"convert", dir.file("s.vtk"), dir.file("s.vtk"), "--mesh-space", "xyz"}), 2, "", "xyz");
}

// convert --remesh: a template of long thin triangles remeshed isotropically, as segment would remesh it (and then
// uses it as it is); bad vertex counts refused, nothing written.
TEST(Cli, ConvertRemeshesATemplateOnce) {
  ScratchDir dir;
  msk::TriangleMesh s = msk::makeIcosphere(8, 3);
  s.vertices.col(2) *= 5.0;
  msk::writeMesh(dir.file("thin.vtk"), s);
  ASSERT_FALSE(msk::isotropicTriangulation(s));
  CliResult c = runCli({"convert", dir.file("thin.vtk"), dir.file("iso.vtk"), "--remesh", "0"});
  ASSERT_EQ(c.exitCode, 0) << c.err;
  EXPECT_NE(c.out.find("remeshed"), std::string::npos) << c.out;
  const msk::TriangleMesh iso = msk::readMesh(dir.file("iso.vtk"));
  EXPECT_TRUE(msk::isotropicTriangulation(iso));
  const msk::TriangleMesh expected = msk::remeshIsotropic(msk::readMesh(dir.file("thin.vtk")), s.vertexCount());
  EXPECT_EQ(iso.faces, expected.faces);
  EXPECT_LT((iso.vertices - expected.vertices).cwiseAbs().maxCoeff(), 1e-12);
  CliResult n = runCli({"convert", dir.file("thin.vtk"), dir.file("n.vtk"), "--remesh", "500"});
  ASSERT_EQ(n.exitCode, 0) << n.err;
  EXPECT_NEAR(msk::readMesh(dir.file("n.vtk")).vertexCount(), 500, 100);
  for (const char* bad : {"2", "-1", "20000000"}) {
    expectOneLineError(runCli({"convert", dir.file("thin.vtk"), dir.file("bad.vtk"), "--remesh", bad}), 2, "--remesh",
                       bad);
    EXPECT_FALSE(fs::exists(dir.file("bad.vtk")));
  }
}

TEST(Cli, PhantomRasterizeEvalPipeline) {
  ScratchDir dir;
  const std::string out = dir.file("ph");
  CliResult p = runCli({"phantom", "--seed", "3", "--out", out, "--spacing", "2,2,4", "--oblique", "5,0,-10"});
  ASSERT_EQ(p.exitCode, 0) << p.err;
  for (const char* f : {"image.nii.gz", "labels.nii.gz", "scene.json", "truth_femur.vtk", "template_femur.vtk"})
    EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
  msk::Json scene = msk::readJsonFile(out + "/scene.json");
  EXPECT_GE(scene.at("objects").size(), 4u);
  EXPECT_EQ(scene.at("objects")[0].at("name").get<std::string>(), "femur");

  CliResult r = runCli({"rasterize", "--mesh", out + "/truth_femur.vtk", "--like", out + "/image.nii.gz", "--out",
                        dir.file("femur.nii.gz"), "--label", "1"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  CliResult e = runCli({"eval", "--result", dir.file("femur.nii.gz"), "--reference", out + "/labels.nii.gz", "--labels",
                        "1", "--json", dir.file("m.json"), "--csv", dir.file("m.csv")});
  ASSERT_EQ(e.exitCode, 0) << e.err;
  msk::Json m = msk::readJsonFile(dir.file("m.json"));
  EXPECT_GT(m.at("metrics")[0].at("dice").get<double>(), 0.97);
  EXPECT_NE(msk::test::readBytes(dir.file("m.csv")).find("dice"), std::string::npos);

  // Mesh-to-mesh: the truth femur against itself converted to another format.
  ASSERT_EQ(runCli({"convert", out + "/truth_femur.vtk", dir.file("f.stl")}).exitCode, 0);
  CliResult mm =
      runCli({"eval", "--result", dir.file("f.stl"), "--reference", out + "/truth_femur.vtk", "--json", "-"});
  ASSERT_EQ(mm.exitCode, 0) << mm.err;
  // stdout is the JSON alone (no table before it), so it pipes into a JSON reader.
  EXPECT_LT(msk::parseJson(mm.out).at("metrics")[0].at("assd_mm").get<double>(), 1e-3);

  // A mesh against a label map, either way round: the truth mesh rasterised on the map's grid against label 1 matches
  // the rasterised femur; label 1 is the femur; a map of several labels needs --labels, and one label only.
  for (const bool meshFirst : {true, false}) {
    const std::string mesh = out + "/truth_femur.vtk", map = out + "/labels.nii.gz";
    CliResult ml = runCli({"eval", "--result", meshFirst ? mesh : map, "--reference", meshFirst ? map : mesh,
                           "--labels", "1", "--json", "-"});
    ASSERT_EQ(ml.exitCode, 0) << ml.err;
    const msk::Json row = msk::parseJson(ml.out).at("metrics")[0];
    EXPECT_GT(row.at("dice").get<double>(), 0.97) << meshFirst;
    EXPECT_EQ(row.at("label").get<int>(), 1);
  }
  expectOneLineError(runCli({"eval", "--result", out + "/truth_femur.vtk", "--reference", out + "/labels.nii.gz"}), 2,
                     "", "--labels");
  expectOneLineError(
      runCli({"eval", "--result", out + "/truth_femur.vtk", "--reference", out + "/labels.nii.gz", "--labels", "1,2"}),
      2, "", "one label");
  expectOneLineError(
      runCli({"eval", "--result", out + "/truth_femur.vtk", "--reference", out + "/labels.nii.gz", "--labels", "99"}),
      1, "labels.nii.gz", "no voxel of label 99");
  // The same mesh against a map of the femur alone needs no --labels.
  CliResult single = runCli({"eval", "--result", out + "/truth_femur.vtk", "--reference", dir.file("femur.nii.gz")});
  EXPECT_EQ(single.exitCode, 0) << single.err;
}

TEST(Cli, AbsurdPhantomParametersLeaveNoOutput) {
  ScratchDir dir;
  for (auto args : std::vector<std::vector<std::string>>{{"--spacing", "0,1,1"},
                                                         {"--noise", "-1"},
                                                         {"--bias", "5"},
                                                         {"--spacing", "1,1"},
                                                         {"--pose", "1,2"},
                                                         {"--pose", "0,0,200,0,0,0"},
                                                         {"--pose", "0,0,0,0,0,0,3"},
                                                         {"--pose", "0,0,0,0,0,0,1,1"}}) {
    std::vector<std::string> cmd = {"phantom", "--out", dir.file("p")};
    cmd.insert(cmd.end(), args.begin(), args.end());
    CliResult r = runCli(cmd);
    EXPECT_EQ(r.exitCode, 2) << args[0] << ": " << r.err;
    EXPECT_EQ(lineCount(r.err), 1) << r.err;
    EXPECT_TRUE(dir.list().empty()) << "partial output after " << args[0];
    if (args[0] == "--pose") {
      EXPECT_NE(r.err.find("--pose"), std::string::npos) << r.err;
    }
  }
}

// A mistyped --out (a file, or a file where one of its parents would be) fails at once, before the phantom is built
// or the scene segmented, with one line naming the folder.
TEST(Cli, BadOutputFolderFailsBeforeTheWork) {
  ScratchDir dir;
  msk::test::writeBytes(dir.file("afile"), "x");
  for (const std::string& out : {dir.file("afile/p"), dir.file("afile")}) {
    const std::string phrase = out == dir.file("afile") ? "exists and is not a folder" : "afile is not a folder";
    for (const std::vector<std::string>& cmd :
         {std::vector<std::string>{"phantom", "--seed", "1", "--out", out},
          std::vector<std::string>{"segment", "--image", dir.file("none.nii.gz"), "--scene", dir.file("none.json"),
                                   "--out", out},
          std::vector<std::string>{"bench", "scene", "--structures", "4", "--out", out},
          std::vector<std::string>{"bench", "tradeoff", "--phantoms", "1", "--out", out}}) {
      const CliResult r = runCli(cmd);
      expectOneLineError(r, 1, out, phrase);
      EXPECT_EQ(r.err.find('%'), std::string::npos) << cmd[0] << ": work started before the check: " << r.err;
    }
  }
}

// --out's missing parent folders are created with it; a run that fails leaves none of them behind.
TEST(Cli, MissingParentsOfTheOutputFolderAreCreated) {
  ScratchDir dir;
  const std::string out = dir.file("study/subject-1/phantom");
  const CliResult r = runCli({"phantom", "--seed", "1", "--out", out, "--quiet"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(std::filesystem::exists(out + "/image.nii.gz"));
  const std::string failed = dir.file("other/subject-2/out");
  const CliResult bad =
      runCli({"segment", "--image", dir.file("none.nii.gz"), "--scene", dir.file("none.json"), "--out", failed});
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_FALSE(std::filesystem::exists(dir.file("other")));
}
