// mskseg convert: mesh formats and coordinate spaces.
#include <iostream>

#include "commands.h"
#include "msk/imaging/mesh_io.h"

namespace msk::cli {

int cmdConvert(const std::vector<std::string>& argv) {
  CommandLine app("convert",
                  "Converts a closed surface mesh between .vtk (legacy 4.2), .vtp, .stl, .obj and .ply. The "
                  "input's SPACE tag is honoured (untagged = LPS); OUT is written in --mesh-space and tagged.");
  std::string in, out;
  MeshSpace space = MeshSpace::LPS;
  app.add_option("in", in, "the mesh to read")->required();
  app.add_option("out", out, "the mesh to write")->required();
  addMeshSpace(app, space, "lps (default) or ras");
  if (!parseArgs(app, argv)) return 0;
  requireMeshOutput(out);
  MeshSpace inSpace = MeshSpace::LPS;
  TriangleMesh m = readMesh(in, &inSpace);
  writeMesh(out, m, space);
  std::cout << in << " (" << meshSpaceName(inSpace) << ", " << m.vertexCount() << " vertices, " << m.faceCount()
            << " faces) -> " << out << " (" << meshSpaceName(space) << ")\n";
  return 0;
}

}  // namespace msk::cli
