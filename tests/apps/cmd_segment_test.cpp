// mskseg segment end to end: outputs, report contents, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include "msk/core/volume_simplex.h"
#include "msk/imaging/image_export.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/tet_mesh_io.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"
#include "msk/test/tet_surface.h"

namespace fs = std::filesystem;
using msk::test::runCli;

namespace {
const std::string kSample = msk::test::bundledSample();

std::string femurScene(const msk::test::ScratchDir& dir, const std::string& extra = "") {
  const std::string path = dir.file("scene.json");
  msk::test::writeBytes(
      path, "{\"objects\": [{\"name\": \"femur\", \"label\": 1, \"kind\": \"bone\", \"template\": \"" + kSample +
                "template_femur.vtk\"" + extra + "}]}");
  return path;
}
/// The written tet mesh OUT/NAME.vtu is valid, LPS-tagged, has no inverted tet, and its boundary nodes are the
/// vertices of the written surface OUT/NAME.vtk (the same places, to the files' precision), except the few that the
/// untangling moved where the surface left no room (by a tenth of the mean edge at most, segmenter.cpp).
void expectTetMeshOnItsSurface(const std::string& out, const std::string& name) {
  msk::MeshSpace space = msk::MeshSpace::RAS;
  const msk::TetMesh tets = msk::readTetMesh(out + "/" + name + ".vtu", &space);
  EXPECT_EQ(space, msk::MeshSpace::LPS);
  EXPECT_EQ(msk::tetMeshProblem(tets), "");
  EXPECT_GT(msk::tetVolumes(tets).minCoeff(), 0.0) << name;
  const msk::test::TetSurfaceOffsets o = msk::test::tetSurfaceOffsets(tets, msk::readMesh(out + "/" + name + ".vtk"));
  ASSERT_EQ(o.boundaryNodes, o.surfaceVertices) << name;
  EXPECT_LE(o.largestMm, 0.1 * o.meanEdgeMm + 1e-3) << name;
  EXPECT_LT(o.offSurface, o.surfaceVertices / 25) << name;  // measured: femur alone 0 of 771, quadriceps 0 of 1953
}
}  // namespace

TEST(SegmentCli, WritesMeshesLabelsReportAndPictures) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", femurScene(dir), "--out", out,
                         "--quality", "fast", "--mesh-space", "ras"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("level 1/1"), std::string::npos) << "progress on stderr";  // fast: one level
  for (const char* f : {"femur.vtk", "labels.nii.gz", "report.json", "qc/femur_axial.png", "qc/femur_coronal.png",
                        "qc/femur_sagittal.png"})
    EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
  msk::MeshSpace space = msk::MeshSpace::LPS;
  const msk::TriangleMesh m = msk::readMesh(out + "/femur.vtk", &space);
  EXPECT_EQ(space, msk::MeshSpace::RAS);
  EXPECT_EQ(m.pointData.count("displacement_mm"), 1u);
  EXPECT_EQ(m.pointData.count("image_residual_mm"), 1u);
  const msk::Json rep = msk::readJsonFile(out + "/report.json");
  EXPECT_EQ(rep.at("mskseg_version").get<std::string>(), MSK_VERSION);
  EXPECT_EQ(rep.at("parameters").at("quality").get<std::string>(), "fast");
  EXPECT_GT(rep.at("objects")[0].at("steps").get<int>(), 0);
  EXPECT_GT(rep.at("objects")[0].at("volume_mm3").get<double>(), 50000.0);
  EXPECT_GT(rep.at("timing").at("constraint_projection_s").at("simplex-internal").get<double>(), 0.0);
  EXPECT_GT(rep.at("objects")[0].at("image_search_s").get<double>(), 0.0);
  EXPECT_EQ(rep.at("status").get<std::string>(), "ok");
  EXPECT_EQ(rep.at("objects")[0].at("quality").at("status").get<std::string>(), "ok");
  EXPECT_GT(rep.at("objects")[0].at("quality").at("contrast_to_noise").get<double>(), 0.0);
  EXPECT_NE(r.out.find("status ok"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("segmentation"), std::string::npos) << "no quality warning for a good run:\n" << r.err;
  // The label map sits on the input grid with the input's affine, exactly.
  msk::Grid in, lab;
  const msk::NiftiInfo a = msk::readNiftiHeader(kSample + "image.nii.gz", &in);
  const msk::NiftiInfo b = msk::readNiftiHeader(out + "/labels.nii.gz", &lab);
  EXPECT_TRUE(in.sameGeometry(lab, 0.0));
  EXPECT_EQ(a.sform, b.sform);
}

// A segmentation that cannot have worked (a constant image: no boundary anywhere) still writes its outputs and exits
// 0, but report.json says "failed" per object (with the reasons) and for the case, stderr has a warning line for the
// object and one for the case, and the summary on stdout says so.
// An image flat but for one corner voxel has no edge a surface could lock onto: the run goes through, and says it
// failed.
TEST(SegmentCli, FailedSegmentationIsReportedAndWarnedButWritten) {
  msk::test::ScratchDir dir;
  msk::NiftiInfo info;
  msk::ImageF image = msk::readNifti<float>(kSample + "image.nii.gz", &info);
  std::fill(image.data.begin(), image.data.end(), 300.f);
  image.at(0, 0, 0) = 0.f;  // one dark corner voxel, far from the templates: not constant, yet no edge to find
  const std::string flat = dir.file("flat.nii.gz"), out = dir.file("out");
  msk::NiftiWriteOptions wo;
  wo.like = &info;
  msk::writeNifti(flat, image, msk::DataType::Int16, wo);
  const auto r =
      runCli({"segment", "--image", flat, "--scene", femurScene(dir), "--out", out, "--quality", "fast", "--no-qc"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(out + "/femur.vtk"));
  const msk::Json rep = msk::readJsonFile(out + "/report.json");
  EXPECT_EQ(rep.at("status").get<std::string>(), "failed");
  const msk::Json& q = rep.at("objects")[0].at("quality");
  EXPECT_EQ(q.at("status").get<std::string>(), "failed");
  ASSERT_FALSE(q.at("reasons").empty());
  EXPECT_NE(q.at("reasons")[0].get<std::string>().find("edge"), std::string::npos) << q.dump();
  EXPECT_NE(r.err.find("femur: segmentation failed ("), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("case: segmentation failed"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("status failed"), std::string::npos) << r.out;
}

// An image that cannot carry any segmentation (one value everywhere), or one the templates do not lie in (another
// subject's world coordinates, another region), is refused before any work, naming the image, and nothing is written.
TEST(SegmentCli, ImagesThatCannotCarryASegmentationAreRefused) {
  msk::test::ScratchDir dir;
  msk::NiftiInfo info;
  const msk::ImageF sample = msk::readNifti<float>(kSample + "image.nii.gz", &info);
  msk::NiftiWriteOptions wo;
  wo.like = &info;
  const std::string out = dir.file("out");
  for (float value : {0.f, 300.f}) {
    msk::ImageF image = sample;
    std::fill(image.data.begin(), image.data.end(), value);
    const std::string path = dir.file("constant.nii.gz");
    msk::writeNifti(path, image, msk::DataType::Int16, wo);
    const auto r = runCli({"segment", "--image", path, "--scene", femurScene(dir), "--out", out, "--quality", "fast"});
    msk::test::expectOneLineError(r, 1, "constant.nii.gz", "constant image");
    EXPECT_FALSE(fs::exists(out));
  }
  // The same image 400 mm away along z: the femur template no longer lies in it.
  msk::ImageF moved = sample;
  moved.grid.origin.z() += 400;
  const std::string path = dir.file("moved.nii.gz");
  msk::writeNifti(path, moved, msk::DataType::Int16);
  const auto r = runCli({"segment", "--image", path, "--scene", femurScene(dir), "--out", out, "--quality", "fast"});
  msk::test::expectOneLineError(r, 1, "moved.nii.gz", "femur: 0 % of its template lies inside the image");
  EXPECT_FALSE(fs::exists(out));
}

// A muscle's decimated template is remeshed before the evolution (its output then has about the template's vertex
// count on another triangulation), a bone's is not; --keep-template-mesh keeps the muscle's too; a muscle's template
// that is already isotropic (the bundled one, remeshed when it was written) is used as it is. The report says what was
// done and how many face pairs of each written surface cross each other (none here).
TEST(SegmentCli, MuscleTemplatesAreRemeshedAndTheReportCountsCrossingFaces) {
  msk::test::ScratchDir dir;
  const std::string decimated = dir.file("hamstrings_decimated.vtk");
  const auto t = runCli({"template", "--labels", kSample + "labels.nii.gz", "--label", "3", "--out", decimated});
  ASSERT_EQ(t.exitCode, 0) << t.err;
  auto sceneWith = [&](const std::string& file, const std::string& hamstrings) {
    msk::test::writeBytes(
        file, "{\"objects\": [{\"name\": \"femur\", \"label\": 1, \"kind\": \"bone\", \"template\": \"" + kSample +
                  "template_femur.vtk\"}, {\"name\": \"hamstrings\", \"label\": 3, " +
                  "\"kind\": \"muscle\", \"template\": \"" + hamstrings + "\"}]}");
    return file;
  };
  const std::string scene = sceneWith(dir.file("scene.json"), decimated);
  {
    const std::string out = dir.file("isotropic");
    const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene",
                           sceneWith(dir.file("bundled.json"), kSample + "template_hamstrings.vtk"), "--out", out,
                           "--quality", "fast", "--no-qc"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const msk::Json muscle = msk::readJsonFile(out + "/report.json").at("objects")[1];
    EXPECT_FALSE(muscle.at("template_remeshed").get<bool>());
    EXPECT_EQ(muscle.at("vertices").get<int>(), muscle.at("template_vertices").get<int>());
  }
  for (bool keep : {false, true}) {
    const std::string out = dir.file(keep ? "kept" : "remeshed");
    std::vector<std::string> args = {
        "segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--quality", "fast", "--no-qc"};
    if (keep) args.push_back("--keep-template-mesh");
    const auto r = runCli(args);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const msk::Json rep = msk::readJsonFile(out + "/report.json");
    EXPECT_EQ(rep.at("parameters").at("remesh_templates").get<bool>(), !keep);
    const msk::Json& femur = rep.at("objects")[0];
    const msk::Json& muscle = rep.at("objects")[1];
    EXPECT_FALSE(femur.at("template_remeshed").get<bool>());
    EXPECT_EQ(femur.at("vertices").get<int>(), femur.at("template_vertices").get<int>());
    EXPECT_EQ(muscle.at("template_remeshed").get<bool>(), !keep);
    const int tv = muscle.at("template_vertices").get<int>(), v = muscle.at("vertices").get<int>();
    if (keep)
      EXPECT_EQ(v, tv);
    else
      EXPECT_NEAR(v, tv, 0.1 * tv);
    for (const msk::Json& o : rep.at("objects")) {
      EXPECT_EQ(o.at("self_intersections").get<double>(), 0.0) << o.dump();
      EXPECT_GE(o.at("folds_unfolded").get<double>(), 0.0) << o.dump();
    }
    EXPECT_EQ(msk::readMesh(out + "/hamstrings.vtk").vertexCount(), v);
  }
  // With a template cache: the first run derives the remeshed muscle (and any coarser level) and stores it, the
  // second reads it, and both write the meshes of the run without it, byte for byte.
  int derived = 0;
  for (const char* run : {"cached1", "cached2"}) {
    const std::string out = dir.file(run);
    const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--quality",
                           "fast", "--no-qc", "--template-cache", dir.file("cache")});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const msk::Json cache = msk::readJsonFile(out + "/report.json").at("template_cache");
    if (std::string(run) == "cached1") {
      derived = cache.at("misses").get<int>();
      EXPECT_GE(derived, 1) << cache.dump();
      EXPECT_EQ(cache.at("hits").get<int>(), 0) << cache.dump();
    } else {
      EXPECT_EQ(cache.at("hits").get<int>(), derived) << cache.dump();
      EXPECT_EQ(cache.at("misses").get<int>(), 0) << cache.dump();
    }
    for (const char* mesh : {"/hamstrings.vtk", "/femur.vtk"})
      EXPECT_EQ(msk::test::readBytes(out + mesh), msk::test::readBytes(dir.file("remeshed") + mesh)) << run << mesh;
  }
}

TEST(SegmentCli, BadInputIsOneLineAndLeavesNoOutput) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  auto check = [&](const std::vector<std::string>& args, int code, const std::string& phrase) {
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, code) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(phrase), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
  };
  const std::string scene = femurScene(dir);
  check({"segment", "--image", dir.file("none.nii.gz"), "--scene", scene, "--out", out}, 1, "none.nii.gz");
  msk::test::writeBytes(dir.file("bad.json"), "{\"objects\": [{\"name\": \"femur\", \"lable\": 1}]}");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", dir.file("bad.json"), "--out", out}, 1, "lable");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--internal-stiffness", "-1"},
        2, "--internal-stiffness");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--quality", "ultra"}, 2,
        "ultra");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--collision-resolution",
         "parallel"},
        2, "--collision-resolution");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--starts", "reference"}, 2,
        "need --atlas");  // (the default, each, passes: 3D Slicer sends every parameter)
  check({"segment", "--image", kSample + "image.nii.gz", "--atlas", dir.file("none"), "--out", out, "--starts", "all"},
        2, "--starts");
  check({"segment", "--image", kSample + "image.nii.gz", "--scene", scene, "--out", out, "--template-cache", scene}, 2,
        "--template-cache");
}

// A volumetric object (scene "model": {"volumetric": true}) also gets its tet mesh written as an LPS-tagged .vtu
// when none of its tets is inverted (else a warning and the count in the report, and no file); the report says what
// was built; without the key nothing volumetric is built.
TEST(SegmentCli, VolumetricObjectWritesItsTetMesh) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r =
      runCli({"segment", "--image", kSample + "image.nii.gz", "--scene",
              femurScene(dir, ", \"model\": {\"volumetric\": true, \"volume_stiffness\": 0.5}"), "--out", out});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json rep = msk::readJsonFile(out + "/report.json");
  EXPECT_EQ(rep.at("volume_models_built").get<int>(), 1);
  const msk::Json& vm = rep.at("objects")[0].at("volume_model");
  EXPECT_GT(vm.at("tets").get<int>(), 1000);
  const int inverted = vm.at("inverted_tets").get<int>();
  EXPECT_EQ(inverted, 0);
  expectTetMeshOnItsSurface(out, "femur");
  EXPECT_EQ(vm.at("mesh").get<std::string>(), "femur.vtu");
  const auto plain = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", femurScene(dir), "--out",
                             dir.file("plain"), "--quality", "fast"});
  ASSERT_EQ(plain.exitCode, 0) << plain.err;
  EXPECT_FALSE(fs::exists(dir.file("plain") + "/femur.vtu"));
  EXPECT_EQ(msk::readJsonFile(dir.file("plain") + "/report.json").at("volume_models_built").get<int>(), 0);
}

// A volumetric muscle among collision partners: the surfaces are separated after the evolution, and the written tet
// mesh follows its separated surface (boundary nodes on the .vtk's vertices, no inverted tet). The same run in process
// is BM_VolumetricQuadricepsAmongPartners in bench/volume_model_bench.cpp, which reports the figures.
TEST(SegmentCli, VolumetricMuscleAmongPartnersFollowsItsSeparatedSurface) {
  msk::test::ScratchDir dir;
  std::string scene = msk::test::readBytes(kSample + "scene.json");
  const std::string quad = "\"template\": \"template_quadriceps.vtk\"";
  ASSERT_NE(scene.find(quad), std::string::npos);
  scene.replace(scene.find(quad), quad.size(), quad + ", \"model\": {\"volumetric\": true}");
  for (const char* name : {"femur", "quadriceps", "hamstrings", "adductors"}) {
    const std::string t = std::string("\"template_") + name + ".vtk\"";
    scene.replace(scene.find(t), t.size(), "\"" + kSample + "template_" + name + ".vtk\"");
  }
  msk::test::writeBytes(dir.file("scene.json"), scene);
  const std::string out = dir.file("out");
  const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", dir.file("scene.json"), "--out",
                         out, "--quality", "fast", "--no-qc"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::Json rep = msk::readJsonFile(out + "/report.json");
  EXPECT_EQ(rep.at("volume_models_built").get<int>(), 1);
  expectTetMeshOnItsSurface(out, "quadriceps");
}

// An object name that would leave the output folder is refused when the scene is read: one line naming the scene and
// the object, exit 1, nothing written inside or outside --out.
TEST(SegmentCli, ObjectNamesCannotLeaveTheOutputFolder) {
  msk::test::ScratchDir dir;
  msk::Json scene = msk::readJsonFile(kSample + "scene.json");
  for (msk::Json& o : scene["objects"]) o["template"] = kSample + o["template"].get<std::string>();
  scene["objects"][0]["name"] = "../../escaped_femur";
  scene["collisions"] = msk::Json::array();
  const std::string scenePath = dir.file("scene.json");
  msk::writeJsonFile(scenePath, scene);
  fs::create_directories(dir.file("a/b"));
  const msk::test::CliResult r =
      runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", scenePath, "--out", dir.file("a/b/out")});
  msk::test::expectOneLineError(r, 1, "scene.json", "objects[0] (../../escaped_femur)");
  EXPECT_FALSE(fs::exists(dir.file("a/b/out")));
  EXPECT_FALSE(fs::exists(dir.file("escaped_femur.vtk")));
  EXPECT_FALSE(fs::exists(dir.file("a/escaped_femur.vtk")));
}

// A template wound inward (negative enclosed volume, as some tools write meshes) is turned outward with a warning and
// gives the same result as the same template wound outward; a template whose surface crosses itself is refused.
TEST(SegmentCli, InwardTemplatesAreTurnedAndCrossingOnesRefused) {
  msk::test::ScratchDir dir;
  msk::TriangleMesh femur = msk::readMesh(kSample + "template_femur.vtk");
  msk::writeMesh(dir.file("outward.vtk"), femur);
  msk::flipFaces(femur);
  msk::writeMesh(dir.file("inward.vtk"), femur);
  auto run = [&](const std::string& templ, const std::string& out) {
    msk::writeJsonFile(dir.file(out + ".json"),
                       msk::parseJson(R"({"objects": [{"name": "femur", "label": 1, "kind": "bone", "template": ")" +
                                      templ + R"("}]})"));
    return runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", dir.file(out + ".json"), "--out",
                   dir.file(out), "--quality", "fast", "--no-qc"});
  };
  const msk::test::CliResult outward = run("outward.vtk", "a");
  const msk::test::CliResult inward = run("inward.vtk", "b");
  ASSERT_EQ(outward.exitCode, 0) << outward.err;
  ASSERT_EQ(inward.exitCode, 0) << inward.err;
  EXPECT_NE(inward.err.find("wound inward"), std::string::npos) << inward.err;
  EXPECT_EQ(msk::test::readBytes(dir.file("a/labels.nii.gz")), msk::test::readBytes(dir.file("b/labels.nii.gz")));

  // Two copies of the template, one shifted into the other: a closed surface that crosses itself.
  msk::TriangleMesh twice = msk::readMesh(kSample + "template_femur.vtk");
  const int nv = twice.vertexCount(), nf = twice.faceCount();
  twice.vertices.conservativeResize(2 * nv, 3);
  twice.faces.conservativeResize(2 * nf, 3);
  twice.vertices.bottomRows(nv) = twice.vertices.topRows(nv).rowwise() + Eigen::RowVector3d(3, 0, 0);
  twice.faces.bottomRows(nf) = twice.faces.topRows(nf).array() + nv;
  twice.pointData.clear();
  msk::writeMesh(dir.file("crossing.vtk"), twice);
  msk::test::expectOneLineError(run("crossing.vtk", "c"), 1, "crossing.vtk", "crosses itself");
  EXPECT_FALSE(fs::exists(dir.file("c")));
}

// A 0 given to an option whose default is the preset's is refused, not replaced by the preset's value; a scene's
// collision gap has the range of --collision-gap.
TEST(SegmentCli, ExplicitZerosAreRefusedNotReplaced) {
  msk::test::ScratchDir dir;
  for (const char* option : {"--steps", "--levels", "--tolerance", "--substeps", "--iterations"}) {
    const msk::test::CliResult r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene",
                                           kSample + "scene.json", "--out", dir.file("out"), option, "0"});
    msk::test::expectOneLineError(r, 2, option, option);
    EXPECT_FALSE(fs::exists(dir.file("out"))) << option;
  }
}

// A run whose requested work would take hours is refused up front with the estimate, not started.
TEST(SegmentCli, AbsurdWorkIsRefusedWithTheEstimate) {
  msk::test::ScratchDir dir;
  const msk::test::CliResult r =
      runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", kSample + "scene.json", "--out",
              dir.file("out"), "--substeps", "1000", "--iterations", "1000"});
  msk::test::expectOneLineError(r, 2, "--substeps", "hours");
  EXPECT_FALSE(fs::exists(dir.file("out")));
}

// Names and colours for the viewers (3D Slicer, ITK-SNAP, BIDS), per-structure statistics that agree with the label
// map and the mesh, and --split's one mask per structure.
TEST(SegmentCli, LabelTablesStatisticsAndSplitMasks) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r =
      runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", femurScene(dir, ", \"colour\": [10, 20, 30]"),
              "--out", out, "--quality", "fast", "--no-qc", "--split"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const std::string slicer = msk::test::readBytes(out + "/labels.ctbl");
  EXPECT_NE(slicer.find("\n1 femur 10 20 30 255\n"), std::string::npos) << slicer;
  const std::string snap = msk::test::readBytes(out + "/labels.itksnap.txt");
  EXPECT_NE(snap.find("ITK-SnAP Label Description File"), std::string::npos);
  EXPECT_NE(snap.find("    1    10   20   30        1  1  1    \"femur\"\n"), std::string::npos) << snap;
  EXPECT_EQ(msk::test::readBytes(out + "/labels.tsv"), "index\tname\tcolor\n1\tfemur\t#0a141e\n");

  const msk::LabelMap labels = msk::readNifti<int32_t>(out + "/labels.nii.gz");
  const long inside = std::count(labels.data.begin(), labels.data.end(), 1);
  const msk::Json stats = msk::readJsonFile(out + "/statistics.json");
  ASSERT_EQ(stats.size(), 1u);
  const msk::Json& femur = stats[0];
  EXPECT_EQ(femur.at("name").get<std::string>(), "femur");
  EXPECT_EQ(femur.at("voxels").get<long>(), inside);
  EXPECT_NEAR(femur.at("volume_labels_ml").get<double>(), inside * labels.grid.spacing.prod() / 1000.0, 1e-9);
  EXPECT_NEAR(femur.at("volume_mesh_ml").get<double>() / femur.at("volume_labels_ml").get<double>(), 1.0, 0.03);
  EXPECT_GT(femur.at("surface_area_mm2").get<double>(), 1000.0);
  EXPECT_GT(femur.at("intensity_sd").get<double>(), 0.0);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LE(femur.at("bbox_min_ras_mm")[a].get<double>(), femur.at("centroid_ras_mm")[a].get<double>());
    EXPECT_GE(femur.at("bbox_max_ras_mm")[a].get<double>(), femur.at("centroid_ras_mm")[a].get<double>());
  }
  EXPECT_NE(msk::test::readBytes(out + "/statistics.csv").find("\nfemur,1," + std::to_string(inside) + ","),
            std::string::npos);

  // eval scores the labels of the result's table, by name (not the reference's other three labels).
  const auto scored =
      runCli({"eval", "--result", out + "/labels.nii.gz", "--reference", kSample + "labels.nii.gz", "--csv", "-"});
  ASSERT_EQ(scored.exitCode, 0) << scored.err;
  EXPECT_EQ(msk::test::lineCount(scored.out), 2) << scored.out;
  EXPECT_NE(scored.out.find("\nfemur,0.9"), std::string::npos) << scored.out;

  const msk::LabelMap mask = msk::readNifti<int32_t>(out + "/labels/femur.nii.gz");
  ASSERT_EQ(mask.data.size(), labels.data.size());
  for (size_t v = 0; v < mask.data.size(); ++v) ASSERT_EQ(mask.data[v], labels.data[v] == 1 ? 1 : 0) << v;
}

// --image-export vti: the image and the label map as .vti in the meshes' space; read back, the femur's voxels and its
// mesh occupy the same world box, and the image's grid is the NIfTI's.
TEST(SegmentCli, ExportedImagesLieWhereTheMeshesAre) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", femurScene(dir), "--out", out,
                         "--quality", "fast", "--no-qc", "--image-export", "vti"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::ImageF image = msk::readVtkImage(out + "/image.vti");
  const msk::ImageF nifti = msk::readNifti<float>(kSample + "image.nii.gz");
  ASSERT_EQ(image.grid.dims, nifti.grid.dims);
  EXPECT_LT((image.grid.origin - nifti.grid.origin).norm(), 1e-3);
  EXPECT_TRUE(image.grid.direction.isApprox(nifti.grid.direction, 1e-6));

  const msk::ImageF labels = msk::readVtkImage(out + "/labels.vti");
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  const msk::Grid& g = labels.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (labels.at(i, j, k) == 1.0f) {
          const Eigen::Vector3d w = g.toWorld(Eigen::Vector3d(i, j, k));
          lo = lo.cwiseMin(w);
          hi = hi.cwiseMax(w);
        }
  const msk::TriangleMesh mesh = msk::readMesh(out + "/femur.vtk");  // LPS on disk, RAS here
  const Eigen::Vector3d meshLo = mesh.vertices.colwise().minCoeff(), meshHi = mesh.vertices.colwise().maxCoeff();
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(lo[a], meshLo[a], g.spacing[a]) << "axis " << a;
    EXPECT_NEAR(hi[a], meshHi[a], g.spacing[a]) << "axis " << a;
  }
}
