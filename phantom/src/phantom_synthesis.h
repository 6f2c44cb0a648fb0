#pragma once
// Private to the phantoms (phantom.cpp, multi_phantom.cpp): image formation from a point classifier (partial volume,
// blur, bias, Rician noise) and the sampling of implicit surfaces for meshing, shared so that every phantom forms its
// image and meshes the same way.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <optional>

#include "msk/imaging/volume.h"
#include "msk/phantom/phantom.h"
#include "phantom_model.h"

namespace msk::phantom {

/// T1-weighted intensity of each PhantomTissue class (index = class value), fat = 1.
constexpr double kTissueIntensity[] = {0.0, 0.45, 1.0, 0.35, 0.08, 0.85, 0.7};
/// Stored image intensity of fat.
constexpr double kFatIntensity = 1000;

/// A seed for an independent random stream `stream` of a phantom seed (splitmix-like mixing, so that neighbouring
/// seeds give unrelated streams).
uint32_t streamSeed(uint32_t seed, uint32_t stream);

/// The image grid with voxel size `spacing` (mm) rotated by `obliqueDegrees` (about x, y, z) that covers the world box
/// [lo, hi] (RAS mm) mapped by `pose` (its eight corners), centred on the mapped box. `slab` (PhantomOptions::fovZ)
/// limits it along the grid's third axis to the world coordinates [slab₀, slab₁] along that axis (world z unless the
/// grid is oblique), as a scanner's slab cuts the anatomy; ParameterError if nothing is left.
Grid coveringGrid(const Eigen::Vector3d& spacing, const Eigen::Vector3d& obliqueDegrees, const Eigen::Vector3d& lo,
                  const Eigen::Vector3d& hi, const PhantomPose& pose = {},
                  const std::optional<Eigen::Vector2d>& slab = std::nullopt);

/// The grid P⁻¹(`image`) of the un-posed anatomy for pose P: origin P⁻¹(origin), direction R⁻¹·direction, spacing
/// spacing / s, so that its voxel (i, j, k) is the point of the un-posed anatomy that P moves to voxel (i, j, k) of
/// `image`. The identity pose returns `image` bitwise.
Grid anatomyGrid(const Grid& image, const PhantomPose& pose);

/// Labels, tissue classes and partial-volume intensities (fat = 1) at every voxel of `labels.grid` from a point
/// classifier of the un-posed anatomy, moved by `pose`: voxel (i, j, k) holds the anatomy at P⁻¹(x_ijk), evaluated on
/// anatomyGrid(). Voxels whose (un-posed) centre lies within the classifier's distance bound (× `lipschitz`) of a
/// tissue boundary are supersampled (about 0.6 mm of un-posed anatomy apart, 2 to 5 samples per axis). `image`,
/// `labels` and `tissues` must share the grid; `sliceDone(k)` is called after every eighth plane k.
void renderTissues(const std::function<PointClass(const Eigen::Vector3d&)>& classify, double lipschitz,
                   const PhantomPose& pose, ImageF& image, LabelMap& labels, LabelMap& tissues,
                   const std::function<void(int k)>& sliceDone);

/// `truth` mapped by the pose P (an exact copy for the identity pose).
TriangleMesh posedMesh(const TriangleMesh& truth, const PhantomPose& pose);

/// Scanner degradation of a rendered image (fat = 1) in place: Gaussian blur of σ = 0.5 voxel, a smooth multiplicative
/// bias field 1 + bias·B(p) (|B| ≤ 1, wavelengths 250–450 mm, p the world position of the voxel: the field is the
/// scanner's and does not move with a posed anatomy), Rician noise of σ = `noise` (fraction of fat), then
/// scaling so that fat ≈ kFatIntensity. Bias and noise are drawn from streams 2 and 3 of `seed`.
void degradeImage(ImageF& image, uint32_t seed, double noise, double bias);

/// Step between the coarse lattice points of sampleImplicit(), in fine samples.
constexpr int kSampleCoarsening = 4;

/// The axis-aligned sampling grid of step h (mm) around the world box [box[0], box[1]] with a margin of 3h, whose
/// size is a multiple of kSampleCoarsening cells along every axis.
Grid implicitSamplingGrid(const std::array<Eigen::Vector3d, 2>& box, double h);

/// Samples an implicit function (negative inside, |f| / lipschitz ≤ distance to its zero set) at the nodes of a grid
/// from implicitSamplingGrid(): evaluated exactly in the coarse cells that may hold the surface, trilinearly
/// interpolated (sign-exact) elsewhere, since only the sign matters there to marching cubes. `eval(i, j, k)` returns
/// the function at node (i, j, k).
ImageF sampleImplicit(const Grid& grid, double lipschitz, const std::function<float(int i, int j, int k)>& eval);

}  // namespace msk::phantom
