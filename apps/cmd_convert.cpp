// mskseg convert: mesh formats and coordinate spaces.
#include <iostream>
#include <string>

#include "commands.h"
#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/surface_quality.h"

namespace msk::cli {

int cmdConvert(const std::vector<std::string>& argv) {
  CommandLine app("convert",
                  "Converts a closed surface mesh between .vtk (legacy 4.2), .vtp, .stl, .obj and .ply. The "
                  "input's SPACE tag is honoured (untagged = LPS); OUT is written in --mesh-space and tagged.");
  std::string in, out;
  MeshSpace space = MeshSpace::LPS;
  int remesh = -1;
  app.add_option("in", in, "the mesh to read")->required();
  app.add_option("out", out, "the mesh to write")->required();
  addMeshSpace(app, space, "lps (default) or ras");
  app.add_option("--remesh", remesh,
                 "remesh isotropically to about this many vertices (0: as many as the input has), as segment remeshes "
                 "a muscle's template; segment uses a template that is already isotropic as it is")
      ->type_name("VERTICES");
  if (!parseArgs(app, argv)) return 0;
  if (app.count("--remesh") && (remesh < 0 || (remesh > 0 && remesh < 4) || remesh > 10000000))
    throw ParameterError("--remesh", std::to_string(remesh), "must be 0 (as many as the input has) or 4..10000000");
  requireMeshOutput(out);
  MeshSpace inSpace = MeshSpace::LPS;
  TriangleMesh m = readMesh(in, &inSpace);
  const int inVertices = m.vertexCount(), inFaces = m.faceCount();
  if (app.count("--remesh")) m = remeshIsotropic(m, remesh > 0 ? remesh : m.vertexCount());  // readMesh: closed
  writeMesh(out, m, space);
  std::cout << in << " (" << meshSpaceName(inSpace) << ", " << inVertices << " vertices, " << inFaces << " faces) -> "
            << out << " (" << meshSpaceName(space);
  if (app.count("--remesh"))
    std::cout << ", remeshed: " << m.vertexCount() << " vertices, " << m.faceCount() << " faces";
  std::cout << ")\n";
  return 0;
}

}  // namespace msk::cli
