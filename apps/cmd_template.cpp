// mskseg template: a smooth closed template surface from one label of a label map.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>

#include "commands.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/template_builder.h"
#include "slicer_module.h"

namespace msk::cli {

void requireLabel(const LabelMap& labels, long label, const std::string& labelsPath) {
  if (std::find(labels.data.begin(), labels.data.end(), static_cast<int32_t>(label)) != labels.data.end()) return;
  std::set<int32_t> present(labels.data.begin(), labels.data.end());
  present.erase(0);
  std::string list;
  int shown = 0;
  for (int32_t v : present) {
    if (++shown > 20) {
      list += ", ...";
      break;
    }
    list += (list.empty() ? "" : ", ") + std::to_string(v);
  }
  throw IoError(labelsPath, "label " + std::to_string(label) +
                                " not found (labels present: " + (list.empty() ? "none" : list) + ")");
}

void addTemplateOptions(CLI::App& app, TemplateOptions& opts, bool bonesOnly) {
  app.add_option("--vertices", opts.vertices, "vertices of the template, 4..10000000 (default 3000)");
  addNumber(app, "--smooth", opts.smoothingSigmaMm,
            "Gaussian blur of the label, mm (default 0: half the largest voxel spacing, which removes the "
            "staircase of thick slices)");
  std::ostringstream extendDefault;
  extendDefault << opts.extendCutMm;
  addNumber(app, "--extend-cut", opts.extendCutMm,
            std::string(bonesOnly ? "a bone" : "a label") +
                " cut by the edge of the scan is continued this far beyond it, mm, its last section repeated straight "
                "out, so that the template reaches into a scan that shows more of the structure (0: a flat cap at "
                "the edge; default " +
                extendDefault.str() + (bonesOnly ? "; muscles and generic objects are capped" : "") + ")");
}

std::vector<SlicerParameter> templateParameters(const std::string& verticesLabel, double extendCutMm) {
  std::ostringstream extendDefault;
  extendDefault << extendCutMm;
  return {SlicerParameter("integer", "--vertices", verticesLabel).byDefault("3000").range(4, 100000, 100),
          SlicerParameter("double", "--smooth", "Label blur (mm, 0: automatic)").byDefault("0").range(0, 20, 0.1),
          SlicerParameter("double", "--extend-cut", "Continue structures cut by the scan's edge (mm)")
              .byDefault(extendDefault.str())
              .range(0, 500, 5)};
}

namespace {
/// The module's parameters: the options 3D Slicer's panel shows for `mskseg template`.
SlicerModule templateModule() {
  SlicerModule m;
  m.title = "mskseg template";
  m.description = "A smooth closed template surface of one label of a label map (for a scene of mskseg segment).";
  using P = SlicerParameter;
  m.groups.push_back({"Input and output",
                      "The label map, the label and the surface written.",
                      false,
                      {P("image", "--labels", "Label map").type("label").extensions(".nii.gz"),
                       P("integer", "--label", "Label").byDefault("1").range(1, 2147483647, 1),
                       P("geometry", "--out", "Template surface").output().type("model").extensions(".vtk")}});
  m.groups.push_back({"Surface", "Its resolution and smoothness.", false,
                      templateParameters("Vertices", TemplateOptions{}.extendCutMm)});
  return m;
}
}  // namespace

int cmdTemplate(const std::vector<std::string>& argv) {
  CommandLine app(
      "template",
      "Builds a smooth closed template surface of label N: the label's largest connected component is blurred, its "
      "0.5 isosurface extracted, smoothed without shrinking, decimated to about --vertices vertices and offset so "
      "that it encloses the label's voxel volume.");
  std::string labelsPath, out;
  long label = 0;
  TemplateOptions opts;
  std::optional<double> mirrorX;
  MeshSpace space = MeshSpace::LPS;
  app.add_option("--labels", labelsPath, "label map (NIfTI)")->required();
  app.add_option("--label", label, "the label, 1..2147483647")->required();
  app.add_option("--out", out, "the mesh to write (.vtk .vtp .stl .obj .ply), its folder created if missing")
      ->required();
  addTemplateOptions(app, opts);
  app.add_option_function<double>(
         "--mirror-x", [&mirrorX](double x) { mirrorX = x; },
         "reflect the surface across the sagittal plane x = MM (RAS mm), e.g. a left-side template from a "
         "right-side label")
      ->type_name("MM");
  addMeshSpace(app, space, "lps (default) or ras; tagged");
  if (handleSlicerXml(app, argv, templateModule())) return 0;
  if (!parseArgs(app, argv)) return 0;
  if (label < 1 || label > 2147483647L)
    throw ParameterError("--label", std::to_string(label), "must be in 1..2147483647");
  checkTemplateOptions(opts);
  if (mirrorX && !std::isfinite(*mirrorX))
    throw ParameterError("--mirror-x", std::to_string(*mirrorX), "must be finite");
  requireMeshOutput(out);
  checkOutputFile(out);

  const LabelMap labels = readNifti<int32_t>(labelsPath);
  requireLabel(labels, label, labelsPath);
  TemplateReport report;
  TriangleMesh mesh = templateFromLabels(labels, static_cast<int>(label), opts, &report);
  if (mirrorX) mesh = mirrorMesh(mesh, Eigen::Vector3d(*mirrorX, 0, 0), Eigen::Vector3d::UnitX());
  writeFileWithParents(out, [&] { writeMesh(out, mesh, space); });
  std::cout << out << ": " << mesh.vertexCount() << " vertices, " << mesh.faceCount() << " faces, volume "
            << enclosedVolume(mesh) / 1000.0 << " mL (label " << label << ": " << report.voxels << " voxels, "
            << report.maskVolumeMm3 / 1000.0 << " mL";
  if (report.componentsDropped > 0) std::cout << "; " << report.componentsDropped << " smaller component(s) dropped";
  if (!report.extendedFaces.empty()) {
    std::cout << "; cut by the scan's edge (";
    for (size_t f = 0; f < report.extendedFaces.size(); ++f) std::cout << (f ? ", " : "") << report.extendedFaces[f];
    std::cout << ") and continued " << report.extendedMm << " mm beyond it, " << report.extendedVolumeMm3 / 1000.0
              << " mL";
  }
  std::cout << "), smoothing " << report.sigmaMm << " mm";
  if (mirrorX) std::cout << ", mirrored across x = " << *mirrorX << " mm";
  std::cout << ", " << meshSpaceName(space) << "\n";
  return 0;
}

}  // namespace msk::cli
