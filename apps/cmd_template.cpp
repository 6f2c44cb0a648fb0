// mskseg template: a smooth closed template surface from one label of a label map.
#include <algorithm>
#include <iostream>
#include <set>

#include "args.h"
#include "commands.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/template_builder.h"

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

TemplateOptions templateOptionsFrom(const Args& args) {
  TemplateOptions opts;
  const long vertices = args.integer("vertices", opts.vertices);
  if (vertices < 4 || vertices > 10000000L)
    throw ParameterError("--vertices", std::to_string(vertices), "must be in 4..10000000");
  opts.vertices = static_cast<int>(vertices);
  opts.smoothingSigmaMm = args.num("smooth", 0.0);
  if (opts.smoothingSigmaMm < 0)
    throw ParameterError("--smooth", args.str("smooth"), "must be >= 0 (0: half the largest voxel spacing)");
  return opts;
}

int cmdTemplate(const std::vector<std::string>& argv) {
  Args args(argv, {"labels", "label", "vertices", "smooth", "mirror-x", "mesh-space", "out"}, {"help"});
  if (args.has("help")) {
    std::cout
        << "usage: mskseg template --labels SEG.nii.gz --label N --out MESH [--vertices 3000] [--smooth MM]\n"
           "                       [--mirror-x MM] [--mesh-space lps|ras]\n\n"
           "Builds a smooth closed template surface of label N: the label's largest connected component is\n"
           "blurred with a Gaussian of --smooth mm (default: half the largest voxel spacing, which removes the\n"
           "staircase of thick slices), its 0.5 isosurface is extracted, smoothed without shrinking, decimated to\n"
           "about --vertices vertices and offset so that it encloses the label's voxel volume.\n"
           "--mirror-x MM reflects the surface across the sagittal plane x = MM (RAS mm), e.g. to make a\n"
           "left-side template from a right-side label. MESH (.vtk .vtp .stl .obj .ply) is written in\n"
           "--mesh-space (default lps) and tagged.\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  const std::string labelsPath = args.str("labels"), out = args.str("out");
  if (!args.has("label")) throw UsageError("missing required option --label");
  const long label = args.integer("label", 0);
  if (label < 1 || label > 2147483647L)
    throw ParameterError("--label", std::to_string(label), "must be in 1..2147483647");
  const TemplateOptions opts = templateOptionsFrom(args);
  const bool mirror = args.has("mirror-x");
  const double mirrorX = args.num("mirror-x", 0.0);
  const MeshSpace space = parseMeshSpace(args.str("mesh-space", "lps"));
  if (!isMeshFile(out))
    throw UsageError("unsupported output extension for '" + out + "' (use .vtk .vtp .stl .obj .ply)");

  const LabelMap labels = readNifti<int32_t>(labelsPath);
  requireLabel(labels, label, labelsPath);
  TemplateReport report;
  TriangleMesh mesh = templateFromLabels(labels, static_cast<int>(label), opts, &report);
  if (mirror) mesh = mirrorMesh(mesh, Eigen::Vector3d(mirrorX, 0, 0), Eigen::Vector3d::UnitX());
  writeMesh(out, mesh, space);
  std::cout << out << ": " << mesh.vertexCount() << " vertices, " << mesh.faceCount() << " faces, volume "
            << enclosedVolume(mesh) / 1000.0 << " mL (label " << label << ": " << report.voxels << " voxels, "
            << report.maskVolumeMm3 / 1000.0 << " mL";
  if (report.componentsDropped > 0) std::cout << "; " << report.componentsDropped << " smaller component(s) dropped";
  std::cout << "), smoothing " << report.sigmaMm << " mm";
  if (mirror) std::cout << ", mirrored across x = " << mirrorX << " mm";
  std::cout << ", " << meshSpaceName(space) << "\n";
  return 0;
}

}  // namespace msk::cli
