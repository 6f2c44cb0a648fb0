#pragma once
/// Private to registration.cpp: the image pyramid of a registration (smoothed, normalised levels), the reference's
/// sample points, and the metric (NCC or Mattes MI) with its analytic gradient with respect to a small update of the
/// transform about the reference's centre. World mm throughout.
#include <Eigen/Core>
#include <vector>

#include "msk/core/transform_fit.h"
#include "msk/imaging/registration.h"
#include "msk/imaging/volume.h"

namespace msk::reg {

/// One level of the subject: normalised values on its grid and the world → voxel map.
struct SubjectLevel {
  Grid grid;
  LargeVector<float> values;  ///< i fastest
  Eigen::Matrix4d worldToVoxel = Eigen::Matrix4d::Identity();
};

/// One level of the reference: sample points (world mm) and normalised values there.
struct ReferenceSamples {
  std::vector<Eigen::Vector3d> points;
  std::vector<float> values;
};

/// The pyramid of `image` at `spacingsMm` (coarse → fine): each level smoothed with sigma 0.5·spacing (incrementally,
/// from the next finer level), resampled to a grid of the same orientation with spacing max(native, level) per axis,
/// then normalised (1st/99th percentiles → 0/1; min/max if those coincide). Throws Error if `image` is constant.
std::vector<ImageF> buildPyramid(const ImageF& image, const std::vector<double>& spacingsMm, const char* what);

/// The subject level of a normalised image.
SubjectLevel makeSubjectLevel(const ImageF& image);

/// Every voxel centre of `image` as a sample, or a deterministic pseudo-random subset of about `maxSamples` of them.
ReferenceSamples makeSamples(const ImageF& image, int maxSamples);

/// Intensity-weighted centroid (world mm) of the values above the image's median.
Eigen::Vector3d brightCentroid(const ImageF& image);

/// The moments of what stands out of an image's background: each voxel weighted by |value − b|, b the median of the
/// voxels on the grid's faces (the background where the scan holds the whole body part; any modality, bright or dark
/// anatomy alike): the centroid (world mm), the principal axes (columns, unit) and their variances (mm², ascending).
struct ForegroundMoments {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d variances = Eigen::Vector3d::Zero();
};
ForegroundMoments foregroundMoments(const ImageF& image);

/// Number of parameters of an update of kind `model`: 6 (rigid), 7 (similarity), 12 (affine).
int parameterCount(PriorTransform model);

/// The update D(δ) about `centre` (4×4): x ↦ centre + t + E·(x − centre), δ = (t mm, then rotation·radius (rigid,
/// similarity), log-scale·radius (similarity) or the 9 entries of (E − I)·radius row by row (affine)). Scaling by
/// `radiusMm` makes one unit of every parameter move points at that radius by about 1 mm.
Eigen::Matrix4d updateTransform(PriorTransform model, const Eigen::VectorXd& delta, const Eigen::Vector3d& centre,
                                double radiusMm);

/// A metric value with the share of samples inside the subject and, if asked, the gradient with respect to δ of
/// updateTransform() composed on the reference side (T ∘ D(δ)) at δ = 0.
struct MetricValue {
  double metric = 0;   ///< NCC or MI (nats); 0 when fewer than kMinSamples samples are inside
  double overlap = 0;  ///< share of the samples inside the subject
  Eigen::VectorXd gradient;
};

/// Evaluates the metric of one level for many transforms: set up once with prepare(), then evaluate().
class MetricEvaluator {
 public:
  /// Keeps references to `samples` and `subject` (which must outlive the evaluator).
  void prepare(const ReferenceSamples& samples, const SubjectLevel& subject, RegistrationMetric metric,
               const Eigen::Vector3d& centre, double radiusMm, int threads);
  /// The metric of reference → subject transform `T`, with its gradient for updates of kind `model` if `gradient`.
  MetricValue evaluate(const Eigen::Matrix4d& T, PriorTransform model, bool gradient);
  /// At `T`, over the samples inside the subject: `structure` = mean of j·jᵀ with j = Jᵀ·∇m (the Gauss–Newton matrix
  /// of the image, up to the metric's scale) and `displacement` = mean of JᵀJ (δᵀ·displacement·δ is the mean squared
  /// displacement, mm², of the samples under the update δ), J = ∂(update of x)/∂δ. False if too few samples inside.
  bool secondMoments(const Eigen::Matrix4d& T, PriorTransform model, Eigen::MatrixXd& structure,
                     Eigen::MatrixXd& displacement);

 private:
  void sampleSubject(const Eigen::Matrix4d& T);
  Eigen::MatrixXd updateJacobian(PriorTransform model, const Eigen::Vector3d& x) const;
  double nccWeights(int& inside);
  double miWeights(int& inside);

  const ReferenceSamples* samples_ = nullptr;
  const SubjectLevel* subject_ = nullptr;
  RegistrationMetric metric_ = RegistrationMetric::Ncc;
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  double radius_ = 1;
  int threads_ = 1;
  std::vector<int> fixedBin_;                    // MI: the reference's bin per sample
  std::vector<unsigned char> inside_;            // per sample: maps inside the subject
  std::vector<float> moving_;                    // per sample: subject value
  std::vector<Eigen::Vector3f> pulledGradient_;  // per sample: d(subject value)/d(reference point)
  std::vector<double> weight_;                   // per sample: d(metric)/d(subject value)
};

}  // namespace msk::reg
