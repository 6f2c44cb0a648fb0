// mskseg rasterize: a closed mesh → label map on the grid of a reference image.
#include <iostream>

#include "commands.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"

namespace msk::cli {

int cmdRasterize(const std::vector<std::string>& argv) {
  CommandLine app("rasterize",
                  "Voxels of IMAGE's grid whose centre lies inside the closed MESH get label N; the output has "
                  "IMAGE's grid and affine exactly (sform and qform copied).");
  std::string meshPath, likePath, out;
  int label = 1;
  app.add_option("--mesh", meshPath, "closed surface mesh (.vtk .vtp .stl .obj .ply)")->required();
  app.add_option("--like", likePath, "image whose grid the labels take (NIfTI)")->required();
  app.add_option("--out", out, "label map to write (NIfTI)")->required();
  app.add_option("--label", label, "label of the inside, 1..32767 (default 1)");
  if (!parseArgs(app, argv)) return 0;
  if (label < 1 || label > 32767) throw ParameterError("--label", std::to_string(label), "must be in 1..32767");
  TriangleMesh mesh = readMesh(meshPath);
  Grid grid;
  NiftiInfo info = readNiftiHeader(likePath, &grid);
  LabelMap labels(grid, 0);
  rasterizeInto(labels, mesh, static_cast<int32_t>(label));
  size_t count = 0;
  for (int32_t v : labels.data) count += v != 0;
  NiftiWriteOptions wo;
  wo.like = &info;
  wo.description = "mskseg rasterize";
  writeNifti(out, labels, label <= 255 ? DataType::UInt8 : DataType::Int16, wo);
  std::cout << out << ": " << count << " voxels labelled " << label << " (" << count * grid.spacing.prod() / 1000.0
            << " mL; mesh encloses " << enclosedVolume(mesh) / 1000.0 << " mL)\n";
  return 0;
}

}  // namespace msk::cli
