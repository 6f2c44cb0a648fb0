// mskseg phantom: a synthetic T1-weighted thigh MRI (or both thighs and lower legs) with exact ground truth.
#include <iostream>

#include "args.h"
#include "commands.h"
#include "msk/imaging/mesh_io.h"
#include "msk/segmentation/multi_phantom.h"
#include "msk/segmentation/phantom.h"

namespace msk::cli {

int cmdPhantom(const std::vector<std::string>& argv) {
  Args args(argv, {"seed", "out", "spacing", "oblique", "noise", "bias", "vertices", "mesh-space", "structures"}, {"help"});
  if (args.has("help")) {
    std::cout << "usage: mskseg phantom --seed N --out DIR [--spacing 1.2,1.2,3] [--oblique ax,ay,az]\n"
                 "                      [--noise SIGMA] [--bias B] [--vertices N] [--mesh-space lps|ras]\n"
                 "                      [--structures 4|24]\n\n"
                 "Writes a synthetic T1-weighted thigh MRI with exact ground truth into DIR: image.nii.gz,\n"
                 "labels.nii.gz, truth_<name>.vtk (this seed's anatomy), template_<name>.vtk (mean anatomy)\n"
                 "and scene.json. Anatomy (position, bend, radii, twist, septa) varies with the seed.\n"
                 "  --structures  4: one right thigh (femur, quadriceps, hamstrings, adductors; default);\n"
                 "                24: both thighs and both lower legs, each a bone wrapped by five muscles\n"
                 "  --spacing   voxel size in mm along i,j,k            (default 1.2,1.2,3)\n"
                 "  --oblique   grid rotation in degrees about x,y,z    (default 0,0,0)\n"
                 "  --noise     Rician noise sigma, fraction of fat     (default 0.03)\n"
                 "  --bias      multiplicative bias field amplitude     (default 0.15)\n"
                 "  --vertices  vertices of each truth/template mesh    (default 3000)\n"
                 "  --mesh-space  space of the mesh files, tagged       (default lps)\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  PhantomOptions opts;
  long seed = args.integer("seed", 1);
  if (seed < 0 || seed > 0xffffffffL) throw ParameterError("--seed", std::to_string(seed), "must be in [0, 2^32)");
  opts.seed = static_cast<uint32_t>(seed);
  opts.spacing = args.vec3("spacing", opts.spacing);
  opts.obliqueDegrees = args.vec3("oblique", opts.obliqueDegrees);
  opts.noise = args.num("noise", opts.noise);
  opts.bias = args.num("bias", opts.bias);
  const long vertices = args.integer("vertices", opts.meshVertices);
  if (vertices < 100 || vertices > 1000000)
    throw ParameterError("--vertices", std::to_string(vertices), "must be in 100..1000000");
  opts.meshVertices = static_cast<int>(vertices);
  opts.meshSpace = parseMeshSpace(args.str("mesh-space", "lps"));
  const long structures = args.integer("structures", 4);
  if (structures != 4 && structures != kMultiPhantomStructures)
    throw ParameterError("--structures", std::to_string(structures),
                         "must be 4 (thigh) or " + std::to_string(kMultiPhantomStructures) + " (thighs and lower legs)");
  const std::string out = args.str("out");
  checkOutputFolder(out);
  Phantom p = structures == 4 ? makePhantom(opts, stderrProgress("phantom"))
                              : makeMultiPhantom(opts, stderrProgress("phantom"));
  writeFolderAtomically(out, [&](const std::string& staging) { writePhantom(p, opts, staging); });
  std::cout << "phantom seed " << opts.seed << " written to " << out << " (" << p.objects.size() << " objects:";
  for (const auto& o : p.objects) std::cout << " " << o.name << "=" << o.label;
  std::cout << ")\n";
  return 0;
}

}  // namespace msk::cli
