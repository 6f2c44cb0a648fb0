#pragma once
/// Synthetic T1-weighted thigh MRI with exact ground truth (femur, muscle compartments, fat, skin).
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "msk/core/log.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/volume.h"
#include "msk/phantom/phantom_pose.h"
#include "msk/segmentation/scene.h"

namespace msk {

/// Phantom parameters (user input only).
struct PhantomOptions {
  uint32_t seed = 1;                                         ///< anatomy and noise vary with it
  Eigen::Vector3d spacing = Eigen::Vector3d(1.2, 1.2, 3.0);  ///< mm
  Eigen::Vector3d obliqueDegrees = Eigen::Vector3d::Zero();  ///< grid rotation about x, y, z
  PhantomPose pose;                                          ///< moves the anatomy, not the templates (default: none)
  double noise = 0.03;                                       ///< Rician noise sigma, fraction of fat intensity
  double bias = 0.15;                                        ///< bias field amplitude (0 = none, fraction)
  /// z range (mm, lo < hi) of the un-posed field of view, clipped to the phantom's own (which holds the whole
  /// anatomy): a shorter range cuts bones and muscles as a short scan does. Unset: the phantom's own range.
  std::optional<Eigen::Vector2d> fovZ;
  bool meshes = true;       ///< compute truth and template meshes (false: image, labels and tissues only; faster)
  int meshVertices = 3000;  ///< target vertex count of each truth and template mesh
  /// The muscles' templates remeshed isotropically to their vertex count, as segment remeshes a muscle's template
  /// (then uses them as they are); false: decimated, as the bones' templates and the truth meshes are.
  bool remeshMuscleTemplates = true;
  double meshSpacingMm = 0.8;  ///< step of the fine grid on which the implicit surfaces are sampled for meshing
  MeshSpace meshSpace = MeshSpace::LPS;  ///< space the mesh files are written in (tagged)
};

/// Throws ParameterError naming the command-line option (--spacing, --oblique, --pose, --noise, --bias, --fov-z,
/// --vertices) of the first PhantomOptions field out of range.
void checkPhantomOptions(const PhantomOptions& opts);

/// Tissue classes of the phantom image (values of Phantom::tissues).
enum class PhantomTissue : int32_t {
  Air = 0,              ///< outside the skin (intensity 0)
  Skin = 1,             ///< 1.5 mm skin layer (0.45)
  Fat = 2,              ///< subcutaneous fat, septa, periosteal gap (1.0)
  Muscle = 3,           ///< muscle compartments (0.35)
  Cortex = 4,           ///< cortical bone (0.08)
  Marrow = 5,           ///< fatty marrow (0.85)
  IntramuscularFat = 6  ///< thin fat streaks inside muscles, labelled as their muscle (0.7)
};

/// One anatomical structure of the phantom.
struct PhantomObject {
  std::string name;                   ///< "femur", "quadriceps", ...
  int32_t label = 0;                  ///< value in the label map
  std::string kind;                   ///< "bone" | "muscle" | "generic"
  TriangleMesh truth;                 ///< ground-truth surface for this seed, RAS mm, posed (PhantomOptions::pose)
  TriangleMesh templ;                 ///< mean-anatomy surface (seed-independent, never posed), RAS mm
  std::vector<std::string> touching;  ///< names of the structures this one touches (collision pairs)
};

/// A generated phantom.
struct Phantom {
  ImageF image;                              ///< T1-weighted intensities
  LabelMap labels;                           ///< exact labels on the image grid
  std::vector<PhantomObject> objects;        ///< structures with labels > 0
  LabelMap tissues;                          ///< PhantomTissue class at each voxel centre (same grid as the image)
  std::string generator = "mskseg-phantom";  ///< generator name written into scene.json's "phantom" key
};

/// Generates a phantom in memory: a right thigh in RAS mm (+x lateral, +y anterior, +z superior) with
/// femur (label 1, "bone"), quadriceps (2), hamstrings (3) and adductors (4) ("muscle"). Deterministic for a seed.
/// Image intensities are scaled so that fat ≈ 1000. Throws ParameterError for invalid options.
/// With a pose P (opts.pose) the anatomy is moved by P: voxel centre x of the image, labels and tissues shows the
/// un-posed anatomy at P⁻¹(x) (evaluated there exactly, no resampling), truth meshes are mapped by P, templates stay
/// un-posed. The field of view is the un-posed one (the world box that holds the limb for every seed) mapped by P and
/// covered by a grid of opts.spacing and opts.obliqueDegrees; the bias field stays fixed in world space (the
/// scanner's). The identity pose gives bitwise the phantom without a pose.
Phantom makePhantom(const PhantomOptions& opts, const ProgressFn& progress = {});

/// The scene a phantom declares: its templates as objects (template paths `folder`/template_<name>.vtk, the meshes in
/// memory), its touching structures as collision pairs.
Scene phantomScene(const Phantom& phantom, const std::string& folder = ".");

/// Writes image.nii.gz, labels.nii.gz, truth_<name>.vtk, template_<name>.vtk and scene.json (phantomScene(), its
/// "provenance" the generating parameters) into `dir` (created if needed). Options are validated first
/// (ParameterError), so invalid ones leave no output.
void writePhantom(const Phantom& phantom, const PhantomOptions& opts, const std::string& dir);

}  // namespace msk
