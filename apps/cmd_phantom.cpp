// mskseg phantom: a synthetic T1-weighted thigh MRI (or both thighs and lower legs) with exact ground truth.
#include <iostream>
#include <string>
#include <vector>

#include "commands.h"
#include "msk/imaging/mesh_io.h"
#include "msk/phantom/multi_phantom.h"
#include "msk/phantom/phantom.h"

namespace msk::cli {

namespace {

// The numbers of --pose (ax, ay, az, tx, ty, tz[, s]) as a pose; ParameterError for any other count.
PhantomPose parsePose(const std::vector<double>& v) {
  if (v.size() != 6 && v.size() != 7) {
    std::string value;
    for (size_t i = 0; i < v.size(); ++i) value += (i ? "," : "") + std::to_string(v[i]);
    throw ParameterError("--pose", value, "needs 6 or 7 numbers: ax,ay,az,tx,ty,tz[,scale]");
  }
  PhantomPose p;
  p.rotationDegrees = Eigen::Vector3d(v[0], v[1], v[2]);
  p.translationMm = Eigen::Vector3d(v[3], v[4], v[5]);
  if (v.size() == 7) p.scale = v[6];
  return p;
}

}  // namespace

int cmdPhantom(const std::vector<std::string>& argv) {
  CommandLine app(
      "phantom",
      "Writes a synthetic T1-weighted thigh MRI with exact ground truth into OUT: image.nii.gz, labels.nii.gz, "
      "truth_<name>.vtk (this seed's anatomy), template_<name>.vtk (mean anatomy; the muscles' remeshed "
      "isotropically, as segment would remesh them) and scene.json. Anatomy "
      "(position, bend, radii, twist, septa) varies with the seed.");
  PhantomOptions opts;
  std::string out;
  int structures = 4;
  app.add_option("--seed", opts.seed, "anatomy and noise vary with it (default 1)");
  app.add_option("--out", out, "output folder (appears whole or not at all)")->required();
  addVec3(app, "--spacing", opts.spacing, "voxel size in mm along i,j,k (default 1.2,1.2,3)");
  addVec3(app, "--oblique", opts.obliqueDegrees, "grid rotation in degrees about x,y,z (default 0,0,0)");
  std::vector<double> pose;
  app.add_option("--pose", pose,
                 "moves the anatomy (image, labels, truth meshes; not the templates, which stay at the mean anatomy) "
                 "by x' = t + s·R·x, RAS mm: R rotates by ax, ay, az degrees about the world x, then y, then z axes "
                 "(R = Rz·Ry·Rx, as --oblique), about the centre of the un-posed field of view, the RAS origin; "
                 "t = (tx, ty, tz) mm; s the scale (default 1, in [0.5, 2]). The field of view grows and moves to "
                 "cover the posed anatomy (default 0,0,0,0,0,0)")
      ->delimiter(',')
      ->type_name("AX,AY,AZ,TX,TY,TZ[,S]");
  addNumber(app, "--noise", opts.noise, "Rician noise sigma, fraction of fat (default 0.03)");
  addNumber(app, "--bias", opts.bias, "multiplicative bias field amplitude (default 0.15)");
  std::vector<double> fovZ;
  app.add_option("--fov-z", fovZ,
                 "the field of view's z range in world mm (along the grid's third axis if oblique), as a short scan "
                 "cuts the anatomy: the femur and muscles end at the cut (default: the whole limb)")
      ->delimiter(',')
      ->expected(2)
      ->type_name("LO,HI");
  app.add_option("--vertices", opts.meshVertices, "vertices of each truth and template mesh (default 3000)");
  addMeshSpace(app, opts.meshSpace, "space of the mesh files, tagged: lps (default) or ras");
  app.add_option("--structures", structures,
                 "4: one right thigh (femur, quadriceps, hamstrings, adductors; default); 24: both thighs and both "
                 "lower legs, each a bone wrapped by five muscles");
  if (!parseArgs(app, argv)) return 0;
  if (!pose.empty()) opts.pose = parsePose(pose);
  if (!fovZ.empty()) opts.fovZ = Eigen::Vector2d(fovZ[0], fovZ[1]);
  if (structures != 4 && structures != kMultiPhantomStructures)
    throw ParameterError(
        "--structures", std::to_string(structures),
        "must be 4 (thigh) or " + std::to_string(kMultiPhantomStructures) + " (thighs and lower legs)");
  checkPhantomOptions(opts);
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
