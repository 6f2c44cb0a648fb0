#include "msk/imaging/registration.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <thread>

#include "msk/core/error.h"
#include "msk/imaging/filters.h"
#include "registration_metric.h"

namespace msk {
namespace {

using Clock = std::chrono::steady_clock;

/// Share of the reference's samples that must map inside the subject: at the start (else Error) and at every step.
constexpr double kMinOverlap = 0.05;
/// Score lost per unit of overlap lost below the overlap a stage started with (metric units): keeps the optimiser
/// from improving the metric by pushing the reference out of the subject.
constexpr double kOverlapPenalty = 1.0;
/// Candidates of the coarse search refined by gradient steps, and their iteration budget.
constexpr int kSearchKeep = 4, kSearchIterations = 40;
/// Principal-axis candidates (momentCandidates()): the axes count as defined when each variance is this many times
/// the next smaller one; the best kMomentKeep are refined, and a far turn wins only if it matches clearly better than
/// the best start near the given one: under NCC, its mismatch 1 − NCC at most kTurnedMismatchShare of the other's;
/// under mutual information, kTurnedMiGain nats more.
constexpr double kDistinctAxes = 1.1, kTurnedMismatchShare = 0.5, kTurnedMiGain = 0.05;
constexpr int kMomentKeep = 2;
/// Largest rotation step of the search grid (degrees).
constexpr double kSearchStepDegrees = 15;
/// Samples per candidate during the search (a subset of the coarsest level's).
constexpr int kSearchSamples = 3000;
/// Translation scan of the search: the reference's centre tried on a grid over the subject's field of view with steps
/// of at least kScanStepMm (and twice the coarsest level's spacing), at most kScanMaxCandidates places; the best
/// kScanKeep places at least two steps apart join the rotation search.
constexpr double kScanStepMm = 12;
constexpr int kScanMaxCandidates = 8000, kScanKeep = 3;
constexpr double kScanMinOverlap = 0.5;
/// Finest default level (mm) when both images have finer voxels; levels per default pyramid at most.
constexpr double kFinestDefaultMm = 2.0;
constexpr int kMaxDefaultLevels = 3;
/// Damping of the preconditioner, relative to the mean diagonal of the image's Gauss–Newton matrix.
constexpr double kDamping = 1e-3;

/// Seconds since `t0`.
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Throws ParameterError for options out of range.
void checkOptions(const RegistrationOptions& o) {
  auto text = [](double v) { return std::to_string(v); };
  if (!(o.searchDegrees > 0 && o.searchDegrees <= 180))
    throw ParameterError("searchDegrees", text(o.searchDegrees), "must be in (0, 180]");
  if (!(o.searchScale >= 0 && o.searchScale < 1))
    throw ParameterError("searchScale", text(o.searchScale), "must be in [0, 1)");
  if (o.maxIterations <= 0) throw ParameterError("maxIterations", std::to_string(o.maxIterations), "must be > 0");
  if (o.threads < 0) throw ParameterError("threads", std::to_string(o.threads), "must be ≥ 0 (0 = all cores)");
  if (o.maxSamples < 100) throw ParameterError("maxSamples", std::to_string(o.maxSamples), "must be ≥ 100");
  for (size_t l = 0; l < o.levelSpacingMm.size(); ++l) {
    const double s = o.levelSpacingMm[l];
    if (!(s > 0 && std::isfinite(s)))
      throw ParameterError("levelSpacingMm[" + std::to_string(l) + "]", text(s), "must be finite and > 0");
    if (l > 0 && s > o.levelSpacingMm[l - 1])
      throw ParameterError("levelSpacingMm[" + std::to_string(l) + "]", text(s), "levels go coarse to fine");
  }
}

/// Geometric mean voxel size (mm) of a grid.
double meanVoxelMm(const Grid& g) { return std::cbrt(g.spacing.prod()); }

/// Default pyramid (coarse → fine): the finest level max(2 mm, the coarser mean voxel of both images), doubled while
/// the next level keeps ≥ 10 samples across the reference's mean extent and ≥ 6 across its smallest (a slab of a few
/// slices keeps its finer levels), at most kMaxDefaultLevels.
std::vector<double> defaultLevels(const Grid& reference, const Grid& subject) {
  const double finest = std::max({kFinestDefaultMm, meanVoxelMm(reference), meanVoxelMm(subject)});
  const Eigen::Vector3d extent =
      (reference.dims.cast<double>() - Eigen::Vector3d::Ones()).cwiseProduct(reference.spacing);
  const double meanExtent = extent.mean();
  std::vector<double> levels{finest};
  while (static_cast<int>(levels.size()) < kMaxDefaultLevels && 2 * levels.back() <= meanExtent / 10 &&
         2 * levels.back() <= extent.minCoeff() / 6)
    levels.push_back(2 * levels.back());
  std::reverse(levels.begin(), levels.end());
  return levels;
}

/// The world box of `image`'s voxel centres mapped by `T`, grown by `marginMm`: {lo, hi}.
std::array<Eigen::Vector3d, 2> mappedBox(const Grid& g, const Eigen::Matrix4d& T, double marginMm) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? g.dims[0] - 1 : 0, (c & 2) ? g.dims[1] - 1 : 0, (c & 4) ? g.dims[2] - 1 : 0);
    const Eigen::Vector3d p = T.topLeftCorner<3, 3>() * g.toWorld(ijk) + T.topRightCorner<3, 1>();
    lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  }
  return {lo - Eigen::Vector3d::Constant(marginMm), hi + Eigen::Vector3d::Constant(marginMm)};
}

/// The images and metric evaluators of every pyramid level, plus the coarse search's.
struct Pyramid {
  std::vector<double> spacing;                  // mm, coarse → fine
  std::vector<reg::ReferenceSamples> samples;   // per level
  std::vector<reg::SubjectLevel> subject;       // per level
  std::vector<reg::MetricEvaluator> evaluator;  // per level
  reg::ReferenceSamples searchSamples;          // coarsest level, at most kSearchSamples
  reg::MetricEvaluator searchEvaluator;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // the reference's centre (mm): the update's pivot
  Eigen::Vector3d referenceCentroid = Eigen::Vector3d::Zero(), subjectCentroid = Eigen::Vector3d::Zero();
  reg::ForegroundMoments referenceMoments, subjectMoments;                                   // of the coarsest level
  Eigen::Vector3d subjectLo = Eigen::Vector3d::Zero(), subjectHi = Eigen::Vector3d::Zero();  // its world box (mm)
  double radius = 1;  // RMS distance of the coarsest samples from the centre (mm)
};

/// Builds the pyramid of both images and prepares the evaluators.
void buildPyramid(const ImageF& reference, const ImageF& subject, const RegistrationOptions& opts, Pyramid& p) {
  p.spacing = opts.levelSpacingMm.empty() ? defaultLevels(reference.grid, subject.grid) : opts.levelSpacingMm;
  const std::vector<ImageF> ref = reg::buildPyramid(reference, p.spacing, "reference");
  const std::vector<ImageF> sub = reg::buildPyramid(subject, p.spacing, "subject");
  const Grid& g = reference.grid;
  p.centre = g.toWorld(0.5 * (g.dims - Eigen::Vector3i::Ones()).cast<double>());
  p.referenceCentroid = reg::brightCentroid(ref.front());
  p.subjectCentroid = reg::brightCentroid(sub.front());
  p.referenceMoments = reg::foregroundMoments(ref.front());
  p.subjectMoments = reg::foregroundMoments(sub.front());
  const auto subjectBox = subject.grid.worldBounds();
  p.subjectLo = subjectBox[0];
  p.subjectHi = subjectBox[1];
  const size_t n = p.spacing.size();
  p.samples.resize(n), p.subject.resize(n), p.evaluator.resize(n);
  for (size_t l = 0; l < n; ++l) {
    p.samples[l] = reg::makeSamples(ref[l], opts.maxSamples);
    p.subject[l] = reg::makeSubjectLevel(sub[l]);
  }
  double sum = 0;
  for (const Eigen::Vector3d& x : p.samples.front().points) sum += (x - p.centre).squaredNorm();
  p.radius = std::max(1.0, std::sqrt(sum / std::max<size_t>(1, p.samples.front().points.size())));
  const int threads =
      opts.threads > 0 ? opts.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  for (size_t l = 0; l < n; ++l)
    p.evaluator[l].prepare(p.samples[l], p.subject[l], opts.metric, p.centre, p.radius, threads);
  p.searchSamples = reg::makeSamples(ref.front(), std::min(opts.maxSamples, kSearchSamples));
  p.searchEvaluator.prepare(p.searchSamples, p.subject.front(), opts.metric, p.centre, p.radius, threads);
}

/// The metric with the overlap penalty: −∞ below kMinOverlap.
double score(const reg::MetricValue& v, double overlapAtStart) {
  if (v.overlap < kMinOverlap) return -std::numeric_limits<double>::infinity();
  return v.metric - kOverlapPenalty * std::max(0.0, overlapAtStart - v.overlap);
}

/// Outcome of one gradient stage at one level.
struct StageOutcome {
  Eigen::Matrix4d transform;
  double metricBefore = 0, metricAfter = 0, scoreAfter = 0;
  int iterations = 0;
};

/// Ascent directions at one level: the gradient preconditioned by the image's Gauss–Newton matrix (frozen at the
/// stage's start), scaled so that a step moves the samples by a given RMS distance (mm).
struct Preconditioner {
  Eigen::LDLT<Eigen::MatrixXd> structure;
  Eigen::MatrixXd displacement;
  bool valid = false;

  /// Sets up at `T`; without enough samples inside, the plain gradient is used.
  Preconditioner(reg::MetricEvaluator& eval, const Eigen::Matrix4d& T, PriorTransform model) {
    Eigen::MatrixXd S;
    if (!eval.secondMoments(T, model, S, displacement)) return;
    // Levenberg-style damping keeps the solve well posed where the image constrains a parameter weakly.
    const double damping = kDamping * S.diagonal().mean();
    if (!(damping > 0)) return;
    S.diagonal().array() += damping;
    structure.compute(S);
    valid = structure.info() == Eigen::Success;
  }
  /// The update along the preconditioned `gradient` whose RMS sample displacement is `stepMm`.
  Eigen::VectorXd step(const Eigen::VectorXd& gradient, double stepMm) const {
    const Eigen::VectorXd d = valid ? Eigen::VectorXd(structure.solve(gradient)) : gradient;
    const double rms = valid ? std::sqrt(std::max(0.0, d.dot(displacement * d))) : d.norm();
    return rms > 0 ? Eigen::VectorXd(d * (stepMm / rms)) : Eigen::VectorXd::Zero(d.size());
  }
};

/// Regular-step gradient ascent of the penalised metric over updates of kind `model`: steps that move the samples by
/// `step` mm (RMS) along the preconditioned gradient, the step growing after a success and halved after a failure,
/// until it falls below 1% of the level spacing or after `maxIterations` evaluations.
StageOutcome optimise(reg::MetricEvaluator& eval, const Eigen::Matrix4d& start, PriorTransform model, double spacingMm,
                      int maxIterations, const Pyramid& p) {
  StageOutcome out;
  out.transform = start;
  const Preconditioner precond(eval, start, model);
  reg::MetricValue cur = eval.evaluate(start, model, true);
  const double overlapAtStart = cur.overlap;
  double curScore = score(cur, overlapAtStart), step = spacingMm;
  out.metricBefore = cur.metric;
  const double minStep = 0.01 * spacingMm;
  while (out.iterations < maxIterations && step >= minStep) {
    const Eigen::VectorXd delta = precond.step(cur.gradient, step);
    if (!(delta.squaredNorm() > 0)) break;
    const Eigen::Matrix4d trial = out.transform * reg::updateTransform(model, delta, p.centre, p.radius);
    reg::MetricValue next = eval.evaluate(trial, model, true);
    ++out.iterations;
    const double nextScore = score(next, overlapAtStart);
    if (nextScore > curScore) {
      out.transform = trial, cur = std::move(next), curScore = nextScore;
      step = std::min(spacingMm, 1.25 * step);
    } else {
      step *= 0.5;
    }
  }
  out.metricAfter = cur.metric;
  out.scoreAfter = curScore;
  return out;
}

/// The transform with linear part L and T(centre) = y.
Eigen::Matrix4d transformThrough(const Eigen::Matrix3d& L, const Eigen::Vector3d& centre, const Eigen::Vector3d& y) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = L;
  T.topRightCorner<3, 1>() = y - L * centre;
  return T;
}

/// Where the reference's centre may go: `start`'s linear part tried with the centre on a grid over the subject's field
/// of view (the fields of view of an atlas and a subject may differ a lot, so that neither `start` nor the intensity
/// centroids place it); returns the best kScanKeep places, at least two grid steps apart.
std::vector<Eigen::Vector3d> scanTranslations(Pyramid& p, const Eigen::Matrix4d& start, double overlapAtStart) {
  const Eigen::Vector3d extent = p.subjectHi - p.subjectLo;
  double step = std::max(kScanStepMm, 2 * p.spacing.front());
  auto count = [&](double h) { return ((extent / h).array().floor() + 1).prod(); };
  while (count(step) > kScanMaxCandidates) step *= 1.25;
  const Eigen::Vector3i n = ((extent / step).array().floor() + 1).cast<int>();
  const Eigen::Matrix3d L = start.topLeftCorner<3, 3>();
  std::vector<std::pair<double, Eigen::Vector3d>> scored;
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const Eigen::Vector3d y = p.subjectLo + step * Eigen::Vector3d(i, j, k) +
                                  0.5 * (extent - step * (n.cast<double>() - Eigen::Vector3d::Ones()));
        const reg::MetricValue v =
            p.searchEvaluator.evaluate(transformThrough(L, p.centre, y), PriorTransform::Rigid, false);
        // A place where less than half the reference (or less than at the start) lies in the subject is not one:
        // few samples match by chance, mutual information above all.
        if (v.overlap >= std::min(kScanMinOverlap, overlapAtStart)) scored.emplace_back(score(v, overlapAtStart), y);
      }
  std::stable_sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Eigen::Vector3d> out;
  for (const auto& entry : scored) {
    if (static_cast<int>(out.size()) == kScanKeep) break;
    const Eigen::Vector3d& y = entry.second;
    if (std::all_of(out.begin(), out.end(), [&](const Eigen::Vector3d& o) { return (o - y).norm() >= 2 * step; }))
      out.push_back(y);
  }
  return out;
}

/// Candidates of the coarse search: rotations on a grid within ±searchDegrees about each axis (steps ≤ 15°) and
/// scales 1, 1 ± searchScale applied to `start` on the reference side, each with the centre mapped where `start`
/// maps it, with the intensity centroids aligned, and at each place of `anchors`.
std::vector<Eigen::Matrix4d> searchCandidates(const Eigen::Matrix4d& start, const RegistrationOptions& opts,
                                              const Pyramid& p, const std::vector<Eigen::Vector3d>& anchors) {
  const int perSide = static_cast<int>(std::ceil(opts.searchDegrees / kSearchStepDegrees - 1e-9));
  const double stepDeg = opts.searchDegrees / perSide;
  std::vector<double> scales{1.0};
  if (opts.model != PriorTransform::Rigid && opts.searchScale > 0)
    scales = {1.0, 1.0 - opts.searchScale, 1.0 + opts.searchScale};
  const Eigen::Matrix3d L0 = start.topLeftCorner<3, 3>();
  const Eigen::Vector3d atStart = L0 * p.centre + start.topRightCorner<3, 1>();
  std::vector<Eigen::Matrix4d> out;
  for (double s : scales)
    for (int a = -perSide; a <= perSide; ++a)
      for (int b = -perSide; b <= perSide; ++b)
        for (int c = -perSide; c <= perSide; ++c) {
          const Eigen::Matrix3d L = s * L0 * Grid::rotationXYZ(stepDeg * Eigen::Vector3d(a, b, c));
          out.push_back(transformThrough(L, p.centre, atStart));
          const Eigen::Vector3d centroidAligned = p.subjectCentroid - L * (p.referenceCentroid - p.centre);
          if ((centroidAligned - atStart).norm() > 0.5 * p.spacing.front())
            out.push_back(transformThrough(L, p.centre, centroidAligned));
          for (const Eigen::Vector3d& y : anchors)
            if ((y - atStart).norm() > 0.5 * p.spacing.front()) out.push_back(transformThrough(L, p.centre, y));
        }
  return out;
}

/// Whether the principal axes of `m` are defined: each variance at least kDistinctAxes times the next smaller one.
bool momentsDefined(const reg::ForegroundMoments& m) {
  const Eigen::Vector3d& v = m.variances;  // ascending
  return v[0] > 0 && v[1] >= kDistinctAxes * v[0] && v[2] >= kDistinctAxes * v[1];
}

/// Candidates from the principal axes of what stands out of each image's background: each rotation that turns the
/// reference's axes onto the subject's (the four sign choices that make it proper), with the scales of the search,
/// the foreground centroids aligned. They reach any orientation, which the grid about `start` does not; they mean
/// something only when both images show much the same anatomy, and only where the axes are well apart (otherwise they
/// are a few more candidates among many).
std::vector<Eigen::Matrix4d> momentCandidates(const RegistrationOptions& opts, const Pyramid& p) {
  std::vector<double> scales{1.0};
  if (opts.model != PriorTransform::Rigid && opts.searchScale > 0)
    scales = {1.0, 1.0 - opts.searchScale, 1.0 + opts.searchScale};
  const Eigen::Matrix3d& A = p.referenceMoments.axes;
  const Eigen::Matrix3d& B = p.subjectMoments.axes;
  std::vector<Eigen::Matrix4d> out;
  for (int signs = 0; signs < 8; ++signs) {
    const Eigen::Vector3d flip((signs & 1) ? -1 : 1, (signs & 2) ? -1 : 1, (signs & 4) ? -1 : 1);
    const Eigen::Matrix3d R = B * flip.asDiagonal() * A.transpose();
    if (R.determinant() < 0) continue;
    for (double s : scales) {
      const Eigen::Matrix3d L = s * R;
      out.push_back(
          transformThrough(L, p.centre, p.subjectMoments.centroid - L * (p.referenceMoments.centroid - p.centre)));
    }
  }
  return out;
}

/// Coarse search: scores every candidate on the search samples, refines the best kSearchKeep with rigid (or
/// similarity) gradient steps at the coarsest level and returns the best.
StageOutcome search(Pyramid& p, const Eigen::Matrix4d& start, const RegistrationOptions& opts) {
  const PriorTransform model = opts.model == PriorTransform::Rigid ? PriorTransform::Rigid : PriorTransform::Similarity;
  const double overlapAtStart = p.searchEvaluator.evaluate(start, model, false).overlap;
  const std::vector<Eigen::Vector3d> anchors = scanTranslations(p, start, overlapAtStart);
  StageOutcome best;
  best.metricBefore = p.evaluator.front().evaluate(start, model, false).metric;
  best.scoreAfter = -std::numeric_limits<double>::infinity();
  int iterations = 0;
  // Scores `candidates`, refines the best `keep` and returns the best outcome.
  auto refineBest = [&](const std::vector<Eigen::Matrix4d>& candidates, size_t keep) {
    std::vector<std::pair<double, Eigen::Matrix4d>> scored;
    for (const Eigen::Matrix4d& T : candidates)
      scored.emplace_back(score(p.searchEvaluator.evaluate(T, model, false), overlapAtStart), T);
    keep = std::min(keep, scored.size());
    std::partial_sort(scored.begin(), scored.begin() + static_cast<std::ptrdiff_t>(keep), scored.end(),
                      [](const auto& a, const auto& b) { return a.first > b.first; });
    iterations += static_cast<int>(scored.size());
    StageOutcome out;
    out.scoreAfter = -std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < keep; ++k) {
      StageOutcome o = optimise(p.evaluator.front(), scored[k].second, model, p.spacing.front(),
                                std::min(opts.maxIterations, kSearchIterations), p);
      iterations += o.iterations;
      if (o.scoreAfter > out.scoreAfter)
        out.transform = o.transform, out.scoreAfter = o.scoreAfter, out.metricAfter = o.metricAfter;
    }
    return out;
  };
  const StageOutcome nearStart = refineBest(searchCandidates(start, opts, p, anchors), kSearchKeep);
  best.transform = nearStart.transform, best.scoreAfter = nearStart.scoreAfter,
  best.metricAfter = nearStart.metricAfter;
  // A far turn only where the principal axes are defined, and only if it matches clearly better than any start near
  // the given one: a limb is round, and turned about its axis it matches almost as well (a phantom thigh turned
  // 166° scored 0.974 at the coarsest level), which would put every muscle in another's compartment.
  if (momentsDefined(p.referenceMoments) && momentsDefined(p.subjectMoments)) {
    const StageOutcome turned = refineBest(momentCandidates(opts, p), kMomentKeep);
    const bool clearlyBetter = opts.metric == RegistrationMetric::Ncc
                                   ? 1 - turned.scoreAfter <= kTurnedMismatchShare * (1 - best.scoreAfter)
                                   : turned.scoreAfter >= best.scoreAfter + kTurnedMiGain;
    if (clearlyBetter)
      best.transform = turned.transform, best.scoreAfter = turned.scoreAfter, best.metricAfter = turned.metricAfter;
  }
  best.iterations = iterations;
  return best;
}

/// "rigid" | "similarity" | "affine".
const char* modelName(PriorTransform m) {
  return m == PriorTransform::Rigid ? "rigid" : m == PriorTransform::Similarity ? "similarity" : "affine";
}

/// "8 mm", "2.5 mm".
std::string mmText(double mm) {
  std::ostringstream s;
  s << mm << " mm";
  return s.str();
}

}  // namespace

const char* registrationMetricName(RegistrationMetric m) { return m == RegistrationMetric::Ncc ? "ncc" : "mi"; }

std::optional<RegistrationMetric> parseRegistrationMetric(const std::string& name) {
  for (RegistrationMetric m : {RegistrationMetric::Ncc, RegistrationMetric::MattesMi})
    if (name == registrationMetricName(m)) return m;
  return std::nullopt;
}

std::string guessModality(const ImageF& image) { return percentile(image, 1.0) < -500 ? "ct" : "mr"; }

RegistrationResult registerImages(const ImageF& reference, const ImageF& subject, const RegistrationOptions& opts,
                                  const Eigen::Matrix4d& start, const ProgressFn& progress) {
  const Clock::time_point t0 = Clock::now();
  checkOptions(opts);
  if (!start.allFinite() || std::abs(start.topLeftCorner<3, 3>().determinant()) < 1e-9)
    throw ParameterError("start", "(4×4 matrix)", "must be finite and invertible");
  // Without the search, only the subject around where `start` puts the reference can matter.
  const ImageF* sub = &subject;
  ImageF cropped;
  if (!opts.initialise) {
    const Grid& g = reference.grid;
    const double diag = ((g.dims.cast<double>() - Eigen::Vector3d::Ones()).cwiseProduct(g.spacing)).norm();
    const auto box = mappedBox(g, start, 0.5 * diag + 20.0);
    try {
      cropped = cropToWorldBox(subject, box[0], box[1]);
    } catch (const Error&) {
      throw Error("registerImages: the reference does not overlap the subject at the start");
    }
    sub = &cropped;
  }
  Pyramid p;
  buildPyramid(reference, *sub, opts, p);
  const double startOverlap = p.evaluator.front().evaluate(start, PriorTransform::Rigid, false).overlap;
  if (startOverlap < kMinOverlap)
    throw Error("registerImages: the reference does not overlap the subject at the start (" +
                std::to_string(100 * startOverlap) + "% of its samples inside, " + std::to_string(100 * kMinOverlap) +
                "% needed)");
  RegistrationResult result;
  const int models = static_cast<int>(opts.model) + 1, levels = static_cast<int>(p.spacing.size());
  const double total = models * levels + (opts.initialise ? 1 : 0);
  int done = 0;
  Eigen::Matrix4d T = start;
  if (opts.initialise) {
    if (progress) progress(0.0, "search");
    const Clock::time_point ts = Clock::now();
    const StageOutcome o = search(p, start, opts);
    T = o.transform;
    result.stages.push_back({"search", o.metricBefore, o.metricAfter, o.iterations, since(ts)});
    ++done;
  }
  for (int m = 0; m < models; ++m)
    for (int l = 0; l < levels; ++l) {
      const PriorTransform model = static_cast<PriorTransform>(m);
      const std::string name = std::string(modelName(model)) + " " + mmText(p.spacing[l]);
      if (progress) progress(done / total, name);
      const Clock::time_point ts = Clock::now();
      const StageOutcome o = optimise(p.evaluator[l], T, model, p.spacing[l], opts.maxIterations, p);
      T = o.transform;
      result.stages.push_back({name, o.metricBefore, o.metricAfter, o.iterations, since(ts)});
      ++done;
    }
  const reg::MetricValue last = p.evaluator.back().evaluate(T, PriorTransform::Rigid, false);
  result.transform = T;
  result.metric = last.metric;
  result.overlap = last.overlap;
  result.startMetric = p.evaluator.back().evaluate(start, PriorTransform::Rigid, false).metric;
  if (progress) progress(1.0, "done");
  result.seconds = since(t0);
  return result;
}

ImageF cropToWorldBox(const ImageF& image, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Grid& g = image.grid;
  Eigen::Vector3d vmin = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), vmax = -vmin;
  for (int c = 0; c < 8; ++c) {  // the box's corners in voxel space: their hull bounds the voxels kept
    const Eigen::Vector3d corner((c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]);
    const Eigen::Vector3d v = g.toVoxel(corner);
    vmin = vmin.cwiseMin(v), vmax = vmax.cwiseMax(v);
  }
  Eigen::Vector3i a, b;
  for (int k = 0; k < 3; ++k) {
    a[k] = std::max(0, static_cast<int>(std::ceil(vmin[k] - 1e-9)));
    b[k] = std::min(g.dims[k] - 1, static_cast<int>(std::floor(vmax[k] + 1e-9)));
    if (!(lo.allFinite() && hi.allFinite()) || a[k] > b[k]) {
      std::ostringstream s;
      s << "cropToWorldBox: the box [" << lo.transpose() << "] – [" << hi.transpose() << "] holds no voxel";
      throw Error(s.str());
    }
  }
  Grid out = g;
  out.dims = b - a + Eigen::Vector3i::Ones();
  out.origin = g.toWorld(a.cast<double>());
  ImageF crop(out);
  for (int k = 0; k < out.dims[2]; ++k)
    for (int j = 0; j < out.dims[1]; ++j)
      for (int i = 0; i < out.dims[0]; ++i) crop.at(i, j, k) = image.at(a[0] + i, a[1] + j, a[2] + k);
  return crop;
}

TransformDifference transformDifference(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b, const Eigen::Vector3d& p) {
  const Eigen::Matrix4d d = a * b.inverse();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(d.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  if ((U * svd.matrixV().transpose()).determinant() < 0) U.col(2) *= -1;  // the nearest proper rotation
  const Eigen::Matrix3d R = U * svd.matrixV().transpose();
  TransformDifference out;
  out.degrees = std::acos(std::clamp((R.trace() - 1) / 2, -1.0, 1.0)) * 180.0 / M_PI;
  const Eigen::Vector4d ph(p[0], p[1], p[2], 1);
  out.mm = ((a - b) * ph).head<3>().norm();
  return out;
}

}  // namespace msk
