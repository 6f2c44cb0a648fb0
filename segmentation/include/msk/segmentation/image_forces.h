#pragma once
/// Image forces (DESIGN-NOTES §7): per vertex, a target point searched along the normal within ±range mm, either the
/// strongest gradient of the expected polarity or the best normalised cross-correlation with a learned intensity
/// profile; scores regularised over mesh neighbours. The targets become independent constraints.
#include <Eigen/Core>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "msk/core/simplex_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Image features at one scale, computed once and shared by every object that uses that scale.
struct ImageFeatures {
  double sigmaMm = 0;  ///< Gaussian scale of the smoothed image (0 = unsmoothed)
  ImageF smoothed;     ///< G_sigma * I (normalised intensities)
  /// Intensity at a world point (trilinear), nullopt outside the grid.
  std::optional<double> sample(const Eigen::Vector3d& worldMm) const;
};

/// Builds the features of `image` at scale `sigmaMm` (Gaussian smoothing in mm): featuresOfNormalised() of
/// normalisedForFeatures().
ImageFeatures computeImageFeatures(const ImageF& image, double sigmaMm);

/// The intensities the features are built on, the same at every scale: the 1–99 % range mapped to [0, 1] (min–max if
/// that range is a single value; all zeros for a constant image), so scores compare across MRI and CT.
ImageF normalisedForFeatures(const ImageF& image);

/// The features at scale `sigmaMm` of an image normalised by normalisedForFeatures().
ImageFeatures featuresOfNormalised(const ImageF& normalised, double sigmaMm);

/// Edge polarity along the outward normal.
enum class Polarity {
  Auto,         ///< estimated from intensities just inside vs just outside the initial surface
  DarkInside,   ///< intensity rises going outward (T1: dark cortical bone against bright fat)
  BrightInside  ///< intensity falls going outward (CT bone against soft tissue, T1 marrow)
};

/// Name of a polarity ("auto", "dark-inside", "bright-inside"), as scenes and reports write it.
const char* polarityName(Polarity p);

/// What the search looks for.
enum class TargetMode {
  Gradient,  ///< strongest directional derivative of the right polarity
  Profile    ///< best NCC with the profile learned at the initial position
};

/// Search parameters. Lengths in mm; 0 means "relative to the voxel size" (documented per field).
struct TargetSearchOptions {
  TargetMode mode = TargetMode::Gradient;  ///< criterion
  Polarity polarity = Polarity::Auto;      ///< expected edge direction
  double rangeMm = 0;                      ///< search ±range along the normal; 0 → 4 × the largest voxel spacing
  double stepMm = 0;                       ///< sampling step along the normal; 0 → 0.25 × the smallest voxel spacing
  double distancePenalty = 0.1;            ///< score reduction per mm of displacement (relative to the best score)
  double profileHalfLengthMm = 0;          ///< half length of learned profiles; 0 → 2 × the largest voxel spacing
  int regularisationRings = 1;             ///< neighbour rings over which target offsets are smoothed (0 = none)
  /// Gradient mode: when finite, an edge counts only if the smoothed (normalised) intensity crosses this level across
  /// it, from the inside's side to the outside's (estimateEdgeLevel); NaN: every edge of the right polarity counts.
  double edgeLevel = std::numeric_limits<double>::quiet_NaN();
  /// Threads the vertices are searched on (0 = all cores); each vertex's target is its own, so the result is the same
  /// for any number.
  int threads = 1;
};

/// Per-vertex intensity profiles learned on the template's initial position (Profile mode).
/// How far (mm) and how differently oriented (degrees) a vertex beside the source image may borrow another's profile
/// (learnProfiles()).
constexpr double kProfileBorrowMm = 50, kProfileBorrowDegrees = 30;

struct LearnedProfiles {
  double stepMm = 0;         ///< sample spacing along the normal
  int halfSamples = 0;       ///< samples on each side of the surface
  Eigen::MatrixXd profiles;  ///< #V × (2·halfSamples+1), zero-mean unit-norm rows
};

/// Result of one target search.
struct TargetSearchResult {
  Points targets;            ///< #V×3 target positions (world mm); equal to the vertex where nothing was found
  Eigen::VectorXd offsets;   ///< signed offset along the normal (mm)
  Eigen::VectorXd scores;    ///< ≥ 0 confidence per vertex (0: no edge found, no force)
  Eigen::VectorXd residual;  ///< |offset| before regularisation (the "image residual", mm)
};

/// Targets kept between searches of one surface (searchTargets()): a vertex that has moved at most `moveMm` and turned
/// its normal by at most `turnDegrees` since its last search keeps that search's target point, its offset measured
/// anew along the current normal, and its score, instead of sampling the image again. Each vertex's entry is its own,
/// so the result does not depend on the threads. Clear it whenever the image features, the search options, the
/// profiles or the surface's vertices change.
struct SearchReuse {
  double moveMm = 0;                ///< 0: every vertex is searched
  double turnDegrees = 0;           ///< largest turn of the normal
  Points positions;                 ///< per vertex: where it was last searched (NaN row: not yet)
  Points normals;                   ///< per vertex: its unit normal then
  Eigen::VectorXd offsets, scores;  ///< per vertex: that search's offset (mm, before regularisation) and score
  long searched = 0, reused = 0;    ///< counts, for reports
  void clear() {
    positions.resize(0, 3);
    normals.resize(0, 3);
    offsets.resize(0);
    scores.resize(0);
  }
};

/// Estimates the polarity from the mean intensity sampled 0.5–3 mm inside vs outside along the normals.
Polarity estimatePolarity(const ImageFeatures& features, const Points& positions, const Points& normals);

/// The object's edge level: midway between the median intensities sampled 0.5–3 mm inside and outside along the normals
/// (the partial-volume level of its boundary). An edge that does not cross it belongs to another boundary: on CT at
/// 3 mm, a muscle-fat edge outside a bone is as strong as the blurred cortex-muscle edge and has the same polarity, but
/// lies wholly below the bone's level. NaN if nothing could be sampled.
double estimateEdgeLevel(const ImageFeatures& features, const Points& positions, const Points& normals);

/// Learns per-vertex profiles at the current positions (normals outward). A vertex whose profile line leaves the image
/// has none (a zero row). If the vertex itself lies beyond the image's voxel centres with its normal at least 60° from
/// the axis it is beyond along (the side of a template continued beyond the scan that cut its structure; not the cap
/// or the rounded rim a cut structure gets at the scan's edge), it borrows the profile of the nearest vertex that has
/// one, within kProfileBorrowMm and with a normal within kProfileBorrowDegrees of its own: the structure is taken to
/// continue as it looks at the edge of the scan. Flat profiles are not replaced. `borrow` false: no vertex borrows
/// (what the image itself shows, e.g. for comparing a result with what it learned).
LearnedProfiles learnProfiles(const ImageFeatures& features, const Points& positions, const Points& normals,
                              const TargetSearchOptions& opts, const Grid& grid, bool borrow = true);

/// Searches a target for every vertex along its normal. `neighbors` (#V×3, the simplex neighbour table) is used
/// for the regularisation; `profiles` is required in Profile mode. `polarity` must not be Auto (estimate it once).
/// Gradient mode with `focus` (features at a finer scale than `features`): edge focusing (Bergholm 1987) — the edge
/// found at the coarse scale is relocated to the strongest edge of the same polarity at the fine scale within
/// ±(coarse σ + the voxel's extent along the normal) of it (kept where the fine scale has none). Blurring moves an
/// edge: a thin bright shell (CT cortex) seen at σ shows its outer edge about σ beyond where it is, so coarse targets
/// alone pull a surface out by up to σ. The coarse scale still decides which edge; the fine one says where it is.
TargetSearchResult searchTargets(const ImageFeatures& features, const Points& positions, const Points& normals,
                                 const NeighborTable& neighbors, const TargetSearchOptions& opts, Polarity polarity,
                                 const Grid& grid, const LearnedProfiles* profiles = nullptr,
                                 const ImageFeatures* focus = nullptr, SearchReuse* reuse = nullptr);

}  // namespace msk
