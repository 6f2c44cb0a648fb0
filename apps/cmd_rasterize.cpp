// mskseg rasterize: a closed mesh → label map on the grid of a reference image.
#include <iostream>

#include "args.h"
#include "commands.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"

namespace msk::cli {

int cmdRasterize(const std::vector<std::string>& argv) {
  Args args(argv, {"mesh", "like", "out", "label"}, {"help"});
  if (args.has("help")) {
    std::cout << "usage: mskseg rasterize --mesh MESH --like IMAGE.nii.gz --out LABELS.nii.gz [--label N]\n\n"
                 "Voxels of IMAGE's grid whose centre lies inside the closed MESH get label N (default 1); the\n"
                 "output has IMAGE's grid and affine exactly (sform and qform copied).\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  const long label = args.integer("label", 1);
  if (label < 1 || label > 32767) throw ParameterError("--label", std::to_string(label), "must be in 1..32767");
  const std::string out = args.str("out");
  TriangleMesh mesh = readMesh(args.str("mesh"));
  Grid grid;
  NiftiInfo info = readNiftiHeader(args.str("like"), &grid);
  LabelMap labels(grid, 0);
  rasterizeInto(labels, mesh, static_cast<int32_t>(label));
  size_t count = 0;
  for (int32_t v : labels.data) count += v != 0;
  NiftiWriteOptions wo;
  wo.like = &info;
  wo.description = "mskseg rasterize";
  writeNifti(out, labels, label <= 255 ? DataType::UInt8 : DataType::Int16, wo);
  std::cout << out << ": " << count << " voxels labelled " << label << " ("
            << count * grid.spacing.prod() / 1000.0 << " mL; mesh encloses " << enclosedVolume(mesh) / 1000.0
            << " mL)\n";
  return 0;
}

}  // namespace msk::cli
