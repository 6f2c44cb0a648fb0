#pragma once
/// Whether a segmented surface lies on a boundary of the image: figures measured on the final surface from the image
/// alone (no reference labels), and the status they give (ok, doubtful, failed). A run on the wrong body part, on an
/// image without structure, or from a misplaced template still converges and reports small residuals; these figures
/// tell it apart. The limits live in QualityThresholds (docs/method.md, "Knowing when a segmentation failed"; the
/// calibration in docs/measurements.md).
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/image_forces.h"

namespace msk {

/// How far a result can be trusted; ordered from best to worst.
enum class QualityStatus { Ok, Doubtful, Failed };

/// Name of a status ("ok", "doubtful", "failed"), as report.json and the batch summary write it.
const char* qualityStatusName(QualityStatus s);

/// The worse of two statuses.
inline QualityStatus worseStatus(QualityStatus a, QualityStatus b) { return a > b ? a : b; }

/// One object's figures, from the image and its final surface only. Each vertex is sampled at 0.5, 1.0, ..., 3 mm
/// inside and outside along its normal in the image at the finest scale of the run; its step is (mean outside − mean
/// inside) · s, s = +1 for dark-inside and −1 for bright-inside, so that a boundary of the object's polarity steps up.
struct ObjectQuality {
  /// Share of the vertices whose samples all lie in the image (0..1); the others are left out of the figures below.
  /// Vertices outside the image that the source of the object's profiles did not show either (a structure the atlas's
  /// scan cut, continued beyond it) are not counted at all: the scan was not expected to show them.
  double inImageShare = 0;
  /// Share of the sampled vertices whose step exceeds QualityThresholds::significantStep noise levels
  /// (imageNoiseSigma(); any step on a noise-free image): vertices on an edge of the object's polarity that stands out
  /// of the noise (0..1).
  double edgeShare = 0;
  /// Contrast-to-noise ratio across the surface: (median outside − median inside) · s / (1.4826 · √((MAD_in² +
  /// MAD_out²)/2)), over all the samples of each side pooled.
  double contrastToNoise = 0;
  /// Whether the contrast is judged: the object's last pass used the gradient force (which seeks a step of its
  /// polarity). A profile force seeks a learned profile, which may be a boundary of little contrast.
  bool contrastJudged = false;
  /// Objects on the profile force: the mean, over the final surface's vertices that have a profile both in the image
  /// and where they learned it, of the correlation of the two (1: every boundary looks as where the profiles were
  /// learned); NaN otherwise.
  double profileMatch = std::numeric_limits<double>::quiet_NaN();
  /// Pairs of faces of the written surface that cross each other (ObjectResult::selfIntersections), once counted; 0
  /// until then.
  size_t crossingFacePairs = 0;
  QualityStatus status = QualityStatus::Ok;
  std::vector<std::string> reasons;  ///< one line per figure beyond its limit: the status, figure, value and limit
};

/// The limits of the status, in one place (calibrated in docs/measurements.md: every correct run of the test suite is
/// ok; a wrong body part, templates moved 30 mm, pure noise and a constant image are flagged).
struct QualityThresholds {
  double significantStep = 2.0;     ///< a vertex's step counts as an edge above this many noise levels
  double minInImageShare = 0.5;     ///< below: failed (the surface lies mostly outside the image)
  double minEdgeShare = 0.1;        ///< below: failed (no edge of the object's polarity stands out of the noise)
  double minContrastToNoise = 0.5;  ///< below, where the contrast is judged: doubtful (no consistent boundary)
  double minProfileMatch = 0.3;     ///< below, where measured: doubtful (the boundary does not look as learned)
  size_t maxCrossingFacePairs = 0;  ///< above: doubtful (the surface crosses itself: not a valid closed surface)
};

/// The noise level of an image: 1.4826 · MAD of the differences of neighbouring voxels along i, divided by √2 (0 for a
/// constant image). Edges are few among all pairs of neighbours, so the MAD sees the noise.
double imageNoiseSigma(const ImageF& image);

/// Measures the figures of `mesh` (a final surface, RAS mm, outward-oriented) in `features` (the finest scale of the
/// run), for an object of `polarity` (not Auto) whose last pass used `lastForce`; `noiseSigma` is
/// imageNoiseSigma(features.smoothed). `unseen`, if set, tells the points (RAS mm) that the source of the object's
/// profiles did not show (ObjectQuality::inImageShare). Sets the status and reasons with judgeQuality(`t`).
ObjectQuality measureQuality(const ImageFeatures& features, const TriangleMesh& mesh, Polarity polarity,
                             TargetMode lastForce, double noiseSigma, const QualityThresholds& t = {},
                             const std::function<bool(const Eigen::Vector3d&)>& unseen = {});

/// Sets `q.status` and `q.reasons` from its figures and the limits `t`.
void judgeQuality(ObjectQuality& q, const QualityThresholds& t = {});

}  // namespace msk
