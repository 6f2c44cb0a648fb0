// mskseg convert: mesh formats and coordinate spaces.
#include <iostream>

#include "args.h"
#include "commands.h"
#include "msk/imaging/mesh_io.h"

namespace msk::cli {

int cmdConvert(const std::vector<std::string>& argv) {
  Args args(argv, {"mesh-space"}, {"help"});
  if (args.has("help")) {
    std::cout << "usage: mskseg convert IN OUT [--mesh-space lps|ras]\n\n"
                 "Converts a closed surface mesh between .vtk (legacy 4.2), .vtp, .stl, .obj and .ply. The input's\n"
                 "SPACE tag is honoured (untagged = LPS); OUT is written in --mesh-space (default lps) and tagged.\n";
    return 0;
  }
  if (args.positional().size() != 2) throw UsageError("expected IN and OUT");
  const MeshSpace space = parseMeshSpace(args.str("mesh-space", "lps"));
  const std::string& in = args.positional()[0];
  const std::string& out = args.positional()[1];
  if (!isMeshFile(out)) throw UsageError("unsupported output extension for '" + out + "' (use .vtk .vtp .stl .obj .ply)");
  MeshSpace inSpace = MeshSpace::LPS;
  TriangleMesh m = readMesh(in, &inSpace);
  writeMesh(out, m, space);
  std::cout << in << " (" << meshSpaceName(inSpace) << ", " << m.vertexCount() << " vertices, " << m.faceCount()
            << " faces) -> " << out << " (" << meshSpaceName(space) << ")\n";
  return 0;
}

}  // namespace msk::cli
