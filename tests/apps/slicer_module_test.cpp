// The commands as 3D Slicer CLI modules, tested the way Slicer uses them: each module's --xml validated against the
// Execution Model schema (tests/slicer/execution-model.xsd, and an official copy when MSK_SLICER_SCHEMA names one),
// then the module run with the argument list Slicer builds from that XML for the values set in its panel.
#include <gtest/gtest.h>
#include <vtkSmartPointer.h>
#include <vtkXMLDataElement.h>
#include <vtkXMLUtilities.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::CliResult;
using msk::test::runProgram;
using msk::test::ScratchDir;

namespace {

const std::string kSample = msk::test::bundledSample();
const std::string kSchema = std::string(MSK_SOURCE_DIR) + "/tests/slicer/execution-model.xsd";

std::string moduleExe(const std::string& command) { return std::string(MSK_SLICER_MODULE_DIR) + "/mskseg-" + command; }

/// xmllint's verdict on `xml` against `schema`: its exit code (0: valid) and messages.
CliResult validate(const ScratchDir& dir, const std::string& xml, const std::string& schema) {
  const std::string file = dir.file("module.xml");
  msk::test::writeBytes(file, xml);
  return runProgram("xmllint", {"--noout", "--schema", schema, file});
}

/// The text of the child `tag` of `e`, "" if it has none.
std::string childText(vtkXMLDataElement* e, const char* tag) {
  vtkXMLDataElement* c = e->FindNestedElementWithName(tag);
  return c != nullptr && c->GetCharacterData() != nullptr ? c->GetCharacterData() : "";
}

/// The argument list 3D Slicer builds to run a module from its XML, for the values set in the module's panel
/// (`panel`, by parameter name; the XML's defaults for the others). Slicer's rules: parameters in the XML's order,
/// each as "--longflag" (else "-flag"); a boolean as its bare flag when true; numbers and enumerations always, with
/// their value; strings, files and directories when not empty; an image or geometry when a node is chosen, as the
/// file Slicer exchanges it through (here the panel's value). Parameters with an index come last, in index order.
std::vector<std::string> slicerArguments(const std::string& xml, const std::map<std::string, std::string>& panel,
                                         std::set<std::string>* names = nullptr) {
  vtkSmartPointer<vtkXMLDataElement> root;
  root.TakeReference(vtkXMLUtilities::ReadElementFromString(xml.c_str()));
  EXPECT_TRUE(root != nullptr) << "the module's XML does not parse";
  if (root == nullptr) return {};
  std::vector<std::string> args;
  std::map<int, std::string> positional;
  for (int g = 0; g < root->GetNumberOfNestedElements(); ++g) {
    vtkXMLDataElement* group = root->GetNestedElement(g);
    if (std::string(group->GetName()) != "parameters") continue;
    for (int k = 0; k < group->GetNumberOfNestedElements(); ++k) {
      vtkXMLDataElement* p = group->GetNestedElement(k);
      const std::string tag = p->GetName();
      if (tag == "label" || tag == "description") continue;
      const std::string name = childText(p, "name");
      if (names != nullptr) names->insert(name);
      const auto set = panel.find(name);
      const std::string value = set != panel.end() ? set->second : childText(p, "default");
      const std::string index = childText(p, "index");
      if (!index.empty()) {
        if (!value.empty()) positional[std::stoi(index)] = value;
        continue;
      }
      const std::string longflag = childText(p, "longflag");
      const std::string flag = longflag.empty() ? "-" + childText(p, "flag") : "--" + longflag;
      if (tag == "boolean") {
        if (value == "true") args.push_back(flag);
      } else if (tag == "integer" || tag == "float" || tag == "double" ||
                 tag.find("-enumeration") != std::string::npos) {
        args.insert(args.end(), {flag, value});
      } else if (!value.empty()) {
        args.insert(args.end(), {flag, value});
      }
    }
  }
  for (const auto& [i, v] : positional) args.push_back(v);
  return args;
}

/// The last <filter-progress> value on a module's stdout, -1 if there is none.
double lastProgress(const std::string& out) {
  const size_t at = out.rfind("<filter-progress>");
  if (at == std::string::npos) return -1;
  return std::atof(out.c_str() + at + std::string("<filter-progress>").size());
}

}  // namespace

TEST(SlicerModule, EveryModuleDescriptionIsValidExecutionModelXml) {
  ScratchDir dir;
  for (const std::string command : {"segment", "atlas", "template"}) {
    SCOPED_TRACE(command);
    const CliResult xml = runProgram(moduleExe(command), {"--xml"});
    ASSERT_EQ(xml.exitCode, 0) << xml.err;
    ASSERT_NE(xml.out.find("<executable>"), std::string::npos) << xml.out;
    const CliResult v = validate(dir, xml.out, kSchema);
    EXPECT_EQ(v.exitCode, 0) << v.err;
    if (const char* official = std::getenv("MSK_SLICER_SCHEMA"); official != nullptr && *official != '\0') {
      const CliResult o = validate(dir, xml.out, official);
      EXPECT_EQ(o.exitCode, 0) << o.err;
    }
    // The same description from `mskseg <command> --xml`.
    const CliResult direct = msk::test::runCli({command, "--xml"});
    EXPECT_EQ(direct.out, xml.out);
  }
}

// The validation is not vacuous: a description with a hyphenated long flag, a parameter without a label, or its
// children out of order is refused.
TEST(SlicerModule, TheSchemaRefusesMalformedDescriptions) {
  ScratchDir dir;
  const CliResult xml = runProgram(moduleExe("segment"), {"--xml"});
  ASSERT_EQ(xml.exitCode, 0) << xml.err;
  const std::string good = xml.out;
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? s : s.replace(at, from.size(), to);
  };
  EXPECT_NE(
      validate(dir, replaced("<longflag>init_transform</longflag>", "<longflag>init-transform</longflag>"), kSchema)
          .exitCode,
      0);
  EXPECT_NE(validate(dir, replaced("<label>Quality</label>", ""), kSchema).exitCode, 0);
  EXPECT_NE(validate(dir,
                     replaced("<name>image</name>\n      <longflag>image</longflag>",
                              "<longflag>image</longflag>\n      <name>image</name>"),
                     kSchema)
                .exitCode,
            0);
  EXPECT_NE(validate(dir, replaced("<title>", "<titel>"), kSchema).exitCode, 0);
}

// Slicer's run of the segment module: the input volume and the outputs as the temporary files Slicer exchanges them
// through, the panel's other values at their defaults but the quality (fast) and the scene.
TEST(SlicerModule, SegmentRunsWithTheArgumentsSlicerBuilds) {
  ScratchDir dir;
  const CliResult xml = runProgram(moduleExe("segment"), {"--xml"});
  ASSERT_EQ(xml.exitCode, 0) << xml.err;
  fs::copy_file(kSample + "image.nii.gz", dir.file("vtkMRMLScalarVolumeNode1.nii.gz"));
  const std::string labels = dir.file("vtkMRMLLabelMapVolumeNode1.nii.gz");
  const std::string surfaces = dir.file("vtkMRMLModelNode1.vtk");
  std::set<std::string> names;
  const std::vector<std::string> args = slicerArguments(xml.out,
                                                        {{"image", dir.file("vtkMRMLScalarVolumeNode1.nii.gz")},
                                                         {"scene", kSample + "scene.json"},
                                                         {"label_map", labels},
                                                         {"surfaces", surfaces},
                                                         {"quality", "fast"}},
                                                        &names);
  for (const std::string n : {"image", "atlas", "scene", "label_map", "surfaces", "out", "quality", "threads"})
    EXPECT_EQ(names.count(n), 1u) << n;
  // What Slicer passes: underscored long flags, every number and enumeration, the hidden progress flag.
  const std::string joined = [&] {
    std::string s;
    for (const auto& a : args) s += a + " ";
    return s;
  }();
  EXPECT_NE(joined.find("--label_map " + labels), std::string::npos) << joined;
  EXPECT_NE(joined.find("--metric auto"), std::string::npos) << joined;
  EXPECT_NE(joined.find("--progress_tags"), std::string::npos) << joined;
  EXPECT_EQ(joined.find("--out"), std::string::npos) << joined;

  const CliResult r = runProgram(moduleExe("segment"), args);
  ASSERT_EQ(r.exitCode, 0) << joined << "\n" << r.err;
  EXPECT_DOUBLE_EQ(lastProgress(r.out), 1.0) << r.out;
  EXPECT_NE(r.out.find("<filter-start>"), std::string::npos);
  // The label map Slicer loads back: on the input's grid, every structure of the scene in it.
  const msk::LabelMap map = msk::readNifti<int32_t>(labels);
  const msk::ImageF image = msk::readNifti<float>(kSample + "image.nii.gz");
  EXPECT_EQ(map.grid.dims, image.grid.dims);
  EXPECT_TRUE(map.grid.toWorld(Eigen::Vector3d(0, 0, 0)).isApprox(image.grid.toWorld(Eigen::Vector3d(0, 0, 0))));
  std::set<int> present(map.data.begin(), map.data.end());
  EXPECT_EQ(present, (std::set<int>{0, 1, 2, 3, 4}));
  // The surfaces Slicer loads back as one model: LPS on disk (tagged), each object's vertices labelled.
  const std::string header = msk::test::readBytes(surfaces).substr(0, 200);
  EXPECT_NE(header.find("SPACE=LPS"), std::string::npos) << header;
  const msk::TriangleMesh all = msk::readMesh(surfaces);
  ASSERT_EQ(all.pointData.count("label"), 1u);
  std::set<int> meshLabels;
  for (int v = 0; v < all.vertexCount(); ++v) meshLabels.insert(static_cast<int>(all.pointData.at("label")[v]));
  EXPECT_EQ(meshLabels, (std::set<int>{1, 2, 3, 4}));
  EXPECT_TRUE(msk::closedMeshProblem(all).empty()) << msk::closedMeshProblem(all);
  // Nothing else was written beside Slicer's files (no --out given).
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) files += e.path().filename().string().rfind(".", 0) != 0;
  EXPECT_EQ(files, 3);  // the input, the label map, the surfaces
}

// Slicer's run of the template module: the label map it exchanges, the label and the model output.
TEST(SlicerModule, TemplateRunsWithTheArgumentsSlicerBuilds) {
  ScratchDir dir;
  const CliResult xml = runProgram(moduleExe("template"), {"--xml"});
  ASSERT_EQ(xml.exitCode, 0) << xml.err;
  const std::string out = dir.file("vtkMRMLModelNode4.vtk");
  const std::vector<std::string> args = slicerArguments(
      xml.out, {{"labels", kSample + "labels.nii.gz"}, {"label", "2"}, {"out", out}, {"vertices", "800"}});
  const CliResult r = runProgram(moduleExe("template"), args);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const msk::TriangleMesh mesh = msk::readMesh(out);
  EXPECT_TRUE(msk::closedMeshProblem(mesh).empty());
  EXPECT_NEAR(mesh.vertexCount(), 800, 200);
}

// Slicer's run of the atlas module: the reference volume and its label map, the structures typed in, and an atlas
// folder chosen; the atlas then segments the sample (with mskseg segment --atlas).
TEST(SlicerModule, AtlasRunsWithTheArgumentsSlicerBuilds) {
  ScratchDir dir;
  const CliResult xml = runProgram(moduleExe("atlas"), {"--xml"});
  ASSERT_EQ(xml.exitCode, 0) << xml.err;
  const std::string atlas = dir.file("chosen/atlas");
  const std::vector<std::string> args = slicerArguments(xml.out, {{"image", kSample + "image.nii.gz"},
                                                                  {"labels", kSample + "labels.nii.gz"},
                                                                  {"objects", "femur:1:bone,quadriceps:2:muscle"},
                                                                  {"out", atlas},
                                                                  {"vertices", "500"}});
  const CliResult r = runProgram(moduleExe("atlas"), args);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_DOUBLE_EQ(lastProgress(r.out), 1.0) << r.out;
  EXPECT_TRUE(fs::exists(atlas + "/atlas.json"));
  EXPECT_TRUE(fs::exists(atlas + "/scene.json"));
}

// A mistyped value in the panel is refused like on the command line: one line, exit code 2.
TEST(SlicerModule, BadPanelValuesAreUsageErrors) {
  ScratchDir dir;
  const CliResult xml = runProgram(moduleExe("segment"), {"--xml"});
  ASSERT_EQ(xml.exitCode, 0) << xml.err;
  const std::vector<std::string> args = slicerArguments(xml.out, {{"image", kSample + "image.nii.gz"},
                                                                  {"scene", kSample + "scene.json"},
                                                                  {"label_map", dir.file("labels.nii.gz")},
                                                                  {"threads", "-3"}});
  const CliResult r = runProgram(moduleExe("segment"), args);
  EXPECT_EQ(r.exitCode, 2) << r.err;
  EXPECT_EQ(msk::test::lineCount(r.err), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("labels.nii.gz")));
}
