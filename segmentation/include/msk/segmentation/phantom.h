#pragma once
/// Synthetic T1-weighted thigh MRI with exact ground truth (femur, muscle compartments, fat, skin).
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "msk/core/log.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Phantom parameters (user input only).
struct PhantomOptions {
  uint32_t seed = 1;                                          ///< anatomy and noise vary with it
  Eigen::Vector3d spacing = Eigen::Vector3d(1.2, 1.2, 3.0);   ///< mm
  Eigen::Vector3d obliqueDegrees = Eigen::Vector3d::Zero();   ///< grid rotation about x, y, z
  double noise = 0.03;                                        ///< Rician noise sigma, fraction of fat intensity
  double bias = 0.15;                                         ///< bias field amplitude (0 = none, fraction)
};

/// One anatomical structure of the phantom.
struct PhantomObject {
  std::string name;      ///< "femur", "quadriceps", ...
  int32_t label = 0;     ///< value in the label map
  std::string kind;      ///< "bone" | "muscle" | "generic"
  TriangleMesh truth;    ///< ground-truth surface for this seed, RAS mm
  TriangleMesh templ;    ///< mean-anatomy surface (seed-independent), RAS mm
};

/// A generated phantom.
struct Phantom {
  ImageF image;                       ///< T1-weighted intensities
  LabelMap labels;                    ///< exact labels on the image grid
  std::vector<PhantomObject> objects; ///< structures with labels > 0
};

/// Generates a phantom in memory.
Phantom makePhantom(const PhantomOptions& opts, const ProgressFn& progress = {});

/// Writes image.nii.gz, labels.nii.gz, truth_<name>.vtk, template_<name>.vtk, scene.json (templates as objects,
/// collision pairs between touching structures) into `dir` (created if needed).
void writePhantom(const Phantom& phantom, const PhantomOptions& opts, const std::string& dir);

}  // namespace msk
