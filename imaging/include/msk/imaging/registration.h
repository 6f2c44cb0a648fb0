#pragma once
/// Intensity-based registration in world space (RAS mm): where a reference image (an atlas's) lies in a subject image,
/// as a rigid, similarity or affine map of reference world points onto subject world points. Any orientation,
/// anisotropic and oblique grids on both sides: everything is computed on world positions.
#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "msk/core/log.h"
#include "msk/core/transform_fit.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Similarity measure between the reference and the subject.
enum class RegistrationMetric {
  Ncc,      ///< normalised cross-correlation (same modality)
  MattesMi  ///< Mattes mutual information (Parzen histograms; modalities may differ)
};
/// "ncc" | "mi".
const char* registrationMetricName(RegistrationMetric m);
/// The metric registrationMetricName() names `name`; nullopt for any other string.
std::optional<RegistrationMetric> parseRegistrationMetric(const std::string& name);

/// "ct" when the image's intensities look like Hounsfield units (1st percentile below −500), else "mr".
std::string guessModality(const ImageF& image);

/// Parameters of registerImages().
struct RegistrationOptions {
  RegistrationMetric metric = RegistrationMetric::Ncc;
  /// The last stage: rigid → similarity → affine are run in that order up to this one.
  PriorTransform model = PriorTransform::Affine;
  /// Start from the intensity centroids and principal moments, then a coarse search over rotations (±searchDegrees
  /// about each axis) and isotropic scale (±searchScale) at the coarsest level, before the gradient stages. false: the
  /// stages start from `start` as given.
  bool initialise = true;
  double searchDegrees = 30;  ///< > 0
  double searchScale = 0.1;   ///< fraction, ≥ 0
  /// Pyramid: the spacing (mm) of each level, coarse to fine; images are smoothed and sampled at it. Empty: chosen
  /// from the reference's size and both images' voxels.
  std::vector<double> levelSpacingMm;
  int maxIterations = 100;  ///< per stage and level, > 0
  /// Sample points per level at most (≥ 100): beyond it, a deterministic pseudo-random subset of the reference's
  /// level voxels.
  int maxSamples = 40000;
  int threads = 0;  ///< 0 = all cores; the result does not depend on it
};

/// One stage of a registration (e.g. "search", "rigid 4 mm", "affine 2 mm").
struct RegistrationStage {
  std::string name;
  double metricBefore = 0, metricAfter = 0;  ///< the metric at the stage's level (higher is better)
  int iterations = 0;
  double seconds = 0;
};

/// Result of registerImages().
struct RegistrationResult {
  /// Maps reference world points (RAS mm) to subject world points: x_subject = transform · x_reference.
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();
  std::vector<RegistrationStage> stages;  ///< in the order they ran
  /// The metric at the finest level at the end (NCC in [−1, 1]; MI in nats), and at `start` on the same level.
  double metric = 0, startMetric = 0;
  double overlap = 0;  ///< share of the reference's sample points that map inside the subject at the end
  double seconds = 0;
};

/// Registers `reference` (all of it: crop it to the region that should count) onto `subject`, starting at `start`
/// (reference → subject). Intensities are normalised robustly on both sides first. Throws ParameterError for options
/// out of range, Error when the images do not overlap at the start or either is constant.
RegistrationResult registerImages(const ImageF& reference, const ImageF& subject, const RegistrationOptions& opts,
                                  const Eigen::Matrix4d& start = Eigen::Matrix4d::Identity(),
                                  const ProgressFn& progress = {});

/// The part of `image` inside the world box [lo, hi] (RAS mm; the voxels whose centres the box's voxel-space hull
/// covers), on the same grid geometry (origin moved). Throws Error if the box holds no voxel.
ImageF cropToWorldBox(const ImageF& image, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

/// Rotation angles (degrees) and translation (mm) between two transforms, for reports and tests: the angle of the
/// rotation part of a·b⁻¹ (polar decomposition) and the distance a·p − b·p at point `p`.
struct TransformDifference {
  double degrees = 0, mm = 0;
};
TransformDifference transformDifference(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b,
                                        const Eigen::Vector3d& p = Eigen::Vector3d::Zero());

}  // namespace msk
