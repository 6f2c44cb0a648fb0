#include "registration_metric.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <thread>

#include "msk/core/error.h"
#include "msk/imaging/filters.h"

namespace msk::reg {
namespace {

/// Fewer samples inside the subject than this and the metric is 0 (no statistics to speak of).
constexpr int kMinSamples = 16;
/// Histogram bins per image for Mattes MI (the subject's cubic B-spline window spans 4 of them).
constexpr int kBins = 32;
/// Sample counts below which the subject is sampled on the calling thread only.
constexpr size_t kParallelMinSamples = 8192;

/// The grid of a pyramid level from the next finer one: same orientation and first voxel centre, spacing
/// max(finer, levelMm) per axis, as many voxels as fit inside the finer grid's voxel-centre hull.
Grid coarserGrid(const Grid& finer, double levelMm) {
  Grid g = finer;
  for (int a = 0; a < 3; ++a) {
    g.spacing[a] = std::max(finer.spacing[a], levelMm);
    const double extent = (finer.dims[a] - 1) * finer.spacing[a];
    g.dims[a] = static_cast<int>(std::floor(extent / g.spacing[a] + 1e-9)) + 1;
  }
  return g;
}

/// Maps the 1st and 99th percentiles of `image` to 0 and 1 (its minimum and maximum if those coincide).
ImageF normalised(const ImageF& image) {
  const std::vector<double> range = percentiles(image, {1.0, 99.0});
  double lo = range[0], hi = range[1];
  if (!(hi > lo)) lo = percentile(image, 0.0), hi = percentile(image, 100.0);
  ImageF out = image;
  if (!(hi > lo)) return out;  // constant after smoothing: the caller's check on the raw image already threw
  const double scale = 1.0 / (hi - lo);
  for (float& v : out.data) v = static_cast<float>((v - lo) * scale);
  return out;
}

/// splitmix64: a well-mixed 64-bit hash of `x` (deterministic on every platform).
uint64_t mixBits(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// Cubic B-spline β³(x) (Parzen window of the subject's histogram, Mattes et al. 2003, eq. 3).
double bspline3(double x) {
  const double a = std::abs(x);
  if (a < 1) return 2.0 / 3.0 - a * a + 0.5 * a * a * a;
  if (a < 2) return (2 - a) * (2 - a) * (2 - a) / 6.0;
  return 0;
}

/// dβ³/dx.
double bspline3Derivative(double x) {
  const double a = std::abs(x), s = x < 0 ? -1.0 : 1.0;
  if (a < 1) return -2.0 * x + 1.5 * x * a;
  if (a < 2) return -0.5 * (2 - a) * (2 - a) * s;
  return 0;
}

/// Continuous bin of a normalised subject value (clamped to [0, 1]): u ∈ [1, kBins − 2], so the window's four bins
/// stay inside the histogram.
double movingBin(double m) { return 1.0 + std::clamp(m, 0.0, 1.0) * (kBins - 3); }

/// Runs f(begin, end) over [0, n) split into `threads` contiguous ranges, one thread each (the calling thread alone
/// for small n). Every index is processed exactly once, so per-index results do not depend on the split.
template <typename F>
void parallelRanges(size_t n, int threads, F&& f) {
  const size_t parts = n < kParallelMinSamples ? 1 : static_cast<size_t>(std::max(1, threads));
  if (parts == 1) return f(size_t{0}, n);
  std::vector<std::thread> pool;
  for (size_t p = 1; p < parts; ++p) pool.emplace_back([&, p] { f(n * p / parts, n * (p + 1) / parts); });
  f(size_t{0}, n / parts);
  for (std::thread& t : pool) t.join();
}

}  // namespace

std::vector<ImageF> buildPyramid(const ImageF& image, const std::vector<double>& spacingsMm, const char* what) {
  const auto [lo, hi] = std::minmax_element(image.data.begin(), image.data.end());
  if (image.data.empty() || !(*hi > *lo))
    throw Error(std::string("registerImages: the ") + what + " image is constant (value " +
                (image.data.empty() ? std::string("none") : std::to_string(*lo)) + ")");
  std::vector<ImageF> levels(spacingsMm.size());
  ImageF finer = image;  // smoothed with sigma `finerSigma`, not normalised
  double finerSigma = 0;
  for (size_t l = spacingsMm.size(); l-- > 0;) {
    const double sigma = 0.5 * spacingsMm[l];
    ImageF smooth = gaussianSmooth(finer, std::sqrt(std::max(0.0, sigma * sigma - finerSigma * finerSigma)));
    const Grid g = coarserGrid(finer.grid, spacingsMm[l]);
    finer = g.sameGeometry(finer.grid) ? std::move(smooth) : resample(smooth, g);
    finerSigma = sigma;
    levels[l] = normalised(finer);
  }
  return levels;
}

SubjectLevel makeSubjectLevel(const ImageF& image) {
  SubjectLevel s;
  s.grid = image.grid;
  s.worldToVoxel = image.grid.worldToVoxel();
  s.values = image.data;
  return s;
}

ReferenceSamples makeSamples(const ImageF& image, int maxSamples) {
  ReferenceSamples s;
  const Grid& g = image.grid;
  const double keep = std::min(1.0, static_cast<double>(maxSamples) / static_cast<double>(g.voxelCount()));
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const size_t idx = g.index(i, j, k);
        if (keep < 1 && static_cast<double>(mixBits(idx) >> 11) * 0x1.0p-53 >= keep) continue;
        s.points.push_back(g.toWorld(Eigen::Vector3d(i, j, k)));
        s.values.push_back(image.data[idx]);
      }
  return s;
}

Eigen::Vector3d brightCentroid(const ImageF& image) {
  const double median = percentile(image, 50.0);
  const Grid& g = image.grid;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double w = image.at(i, j, k) - median;
        if (!(w > 0)) continue;
        sum += w * g.toWorld(Eigen::Vector3d(i, j, k));
        weight += w;
      }
  if (weight > 0) return sum / weight;
  return g.toWorld(0.5 * (g.dims - Eigen::Vector3i::Ones()).cast<double>());
}

ForegroundMoments foregroundMoments(const ImageF& image) {
  const Grid& g = image.grid;
  std::vector<double> border;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const bool face = i == 0 || j == 0 || k == 0 || i == g.dims[0] - 1 || j == g.dims[1] - 1 || k == g.dims[2] - 1;
        if (face && std::isfinite(image.at(i, j, k))) border.push_back(image.at(i, j, k));
      }
  ForegroundMoments m;
  m.centroid = g.toWorld(0.5 * (g.dims - Eigen::Vector3i::Ones()).cast<double>());
  if (border.empty()) return m;
  auto median = [](std::vector<double>& x) {
    std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2), x.end());
    return x[x.size() / 2];
  };
  const double background = median(border);
  // The background's noise (1.4826 · MAD): differences below three times it do not count as foreground.
  for (double& b : border) b = std::abs(b - background);
  const double floor = 3 * 1.4826 * median(border);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  double weight = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const double w = std::abs(image.at(i, j, k) - background) - floor;
        if (!(w > 0)) continue;
        const Eigen::Vector3d x = g.toWorld(Eigen::Vector3d(i, j, k));
        sum += w * x;
        outer += w * x * x.transpose();
        weight += w;
      }
  if (!(weight > 0)) return m;
  m.centroid = sum / weight;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(outer / weight - m.centroid * m.centroid.transpose());
  if (eig.info() == Eigen::Success) {
    m.axes = eig.eigenvectors();
    m.variances = eig.eigenvalues().cwiseMax(0.0);
  }
  return m;
}

int parameterCount(PriorTransform model) {
  return model == PriorTransform::Rigid ? 6 : model == PriorTransform::Similarity ? 7 : 12;
}

Eigen::Matrix4d updateTransform(PriorTransform model, const Eigen::VectorXd& delta, const Eigen::Vector3d& centre,
                                double radiusMm) {
  Eigen::Matrix3d E = Eigen::Matrix3d::Identity();
  if (model == PriorTransform::Affine) {
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) E(j, k) += delta[3 + 3 * j + k] / radiusMm;
  } else {
    const Eigen::Vector3d w = delta.segment<3>(3) / radiusMm;  // rotation vector (rad)
    if (w.norm() > 0) E = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    if (model == PriorTransform::Similarity) E *= std::exp(delta[6] / radiusMm);
  }
  Eigen::Matrix4d D = Eigen::Matrix4d::Identity();
  D.topLeftCorner<3, 3>() = E;
  D.topRightCorner<3, 1>() = centre + delta.head<3>() - E * centre;
  return D;
}

void MetricEvaluator::prepare(const ReferenceSamples& samples, const SubjectLevel& subject, RegistrationMetric metric,
                              const Eigen::Vector3d& centre, double radiusMm, int threads) {
  samples_ = &samples;
  subject_ = &subject;
  metric_ = metric;
  centre_ = centre;
  radius_ = radiusMm;
  threads_ = std::max(1, threads);
  const size_t n = samples.points.size();
  inside_.assign(n, 0);
  moving_.assign(n, 0.f);
  pulledGradient_.assign(n, Eigen::Vector3f::Zero());
  weight_.assign(n, 0.0);
  fixedBin_.resize(n);
  for (size_t i = 0; i < n; ++i)  // zero-order (nearest-bin) window on the reference, as in Mattes et al.
    fixedBin_[i] = std::clamp(static_cast<int>(std::clamp<double>(samples.values[i], 0, 1) * kBins), 0, kBins - 1);
}

void MetricEvaluator::sampleSubject(const Eigen::Matrix4d& T) {
  const Eigen::Matrix4d A = subject_->worldToVoxel * T;  // reference world → subject voxel
  const Eigen::Matrix3d lin = A.topLeftCorner<3, 3>();
  const Eigen::Vector3d off = A.topRightCorner<3, 1>();
  const Eigen::Vector3i dims = subject_->grid.dims;
  const Grid& g = subject_->grid;
  parallelRanges(samples_->points.size(), threads_, [&](size_t begin, size_t end) {
    for (size_t s = begin; s < end; ++s) {
      const Eigen::Vector3d v = lin * samples_->points[s] + off;
      int i0[3], i1[3];
      float t[3];
      bool in = true;
      for (int a = 0; a < 3 && in; ++a) {
        if (dims[a] == 1) {  // a single voxel across: inside within half a voxel
          in = std::abs(v[a]) <= 0.5;
          i0[a] = i1[a] = 0, t[a] = 0;
          continue;
        }
        in = v[a] >= 0 && v[a] <= dims[a] - 1;
        i0[a] = std::min(static_cast<int>(v[a]), dims[a] - 2);
        i1[a] = i0[a] + 1;
        t[a] = static_cast<float>(v[a] - i0[a]);
      }
      inside_[s] = in;
      if (!in) continue;
      // Trilinear interpolation and its exact derivative along i, j, k (consistent with the value).
      float c[8];
      for (int n = 0; n < 8; ++n)
        c[n] = subject_->values[g.index((n & 1) ? i1[0] : i0[0], (n & 2) ? i1[1] : i0[1], (n & 4) ? i1[2] : i0[2])];
      const float x00 = c[0] + t[0] * (c[1] - c[0]), x10 = c[2] + t[0] * (c[3] - c[2]);
      const float x01 = c[4] + t[0] * (c[5] - c[4]), x11 = c[6] + t[0] * (c[7] - c[6]);
      const float y0 = x00 + t[1] * (x10 - x00), y1 = x01 + t[1] * (x11 - x01);
      const float di0 = (c[1] - c[0]) + t[1] * ((c[3] - c[2]) - (c[1] - c[0]));
      const float di1 = (c[5] - c[4]) + t[1] * ((c[7] - c[6]) - (c[5] - c[4]));
      const Eigen::Vector4f acc(y0 + t[2] * (y1 - y0), dims[0] == 1 ? 0.f : di0 + t[2] * (di1 - di0),
                                dims[1] == 1 ? 0.f : (x10 - x00) + t[2] * ((x11 - x01) - (x10 - x00)),
                                dims[2] == 1 ? 0.f : y1 - y0);
      moving_[s] = acc[0];
      // Chain rule: d(value)/d(reference point) = (d voxel / d reference point)ᵀ · d(value)/d voxel.
      pulledGradient_[s] = (lin.transpose() * acc.tail<3>().cast<double>()).cast<float>();
    }
  });
}

double MetricEvaluator::nccWeights(int& inside) {
  const size_t n = moving_.size();
  double sf = 0, sm = 0;
  inside = 0;
  for (size_t s = 0; s < n; ++s)
    if (inside_[s]) sf += samples_->values[s], sm += moving_[s], ++inside;
  std::fill(weight_.begin(), weight_.end(), 0.0);
  if (inside < kMinSamples) return 0;
  const double mf = sf / inside, mm = sm / inside;
  double a = 0, b = 0, c = 0;  // Σ f̃m̃, Σ f̃², Σ m̃² over the samples inside (centred values)
  for (size_t s = 0; s < n; ++s) {
    if (!inside_[s]) continue;
    const double f = samples_->values[s] - mf, m = moving_[s] - mm;
    a += f * m, b += f * f, c += m * m;
  }
  if (!(b > 0 && c > 0)) return 0;
  const double root = std::sqrt(b * c), ratio = a / c;
  // NCC = a / √(bc); ∂NCC/∂m_s = (f̃_s − (a/c)·m̃_s) / √(bc) (the centring terms cancel since Σ f̃ = Σ m̃ = 0).
  for (size_t s = 0; s < n; ++s)
    if (inside_[s]) weight_[s] = (samples_->values[s] - mf - ratio * (moving_[s] - mm)) / root;
  return a / root;
}

double MetricEvaluator::miWeights(int& inside) {
  const size_t n = moving_.size();
  Eigen::MatrixXd joint = Eigen::MatrixXd::Zero(kBins, kBins);  // (reference bin, subject bin)
  inside = 0;
  for (size_t s = 0; s < n; ++s) {
    if (!inside_[s]) continue;
    const double u = movingBin(moving_[s]);
    for (int k = static_cast<int>(u) - 1; k <= static_cast<int>(u) + 2; ++k)
      if (k >= 0 && k < kBins) joint(fixedBin_[s], k) += bspline3(k - u);
    ++inside;
  }
  std::fill(weight_.begin(), weight_.end(), 0.0);
  if (inside < kMinSamples) return 0;
  joint /= joint.sum();  // α normalisation (Mattes eq. 4); the window sums to 1 per sample
  const Eigen::VectorXd pf = joint.rowwise().sum(), pm = joint.colwise().sum().transpose();
  double mi = 0;
  for (int r = 0; r < kBins; ++r)
    for (int k = 0; k < kBins; ++k)
      if (joint(r, k) > 0) mi += joint(r, k) * std::log(joint(r, k) / (pf[r] * pm[k]));
  // Mattes eq. 12–13: ∂MI/∂m_s = −(1/N)·u'·Σ_κ β³'(κ − u_s)·log(p(ι_s, κ)/p_m(κ)), u' = du/dm (0 where clamped).
  const double du = kBins - 3.0;
  for (size_t s = 0; s < n; ++s) {
    if (!inside_[s] || moving_[s] <= 0.f || moving_[s] >= 1.f) continue;
    const double u = movingBin(moving_[s]);
    double sum = 0;
    for (int k = static_cast<int>(u) - 1; k <= static_cast<int>(u) + 2; ++k)
      if (k >= 0 && k < kBins && joint(fixedBin_[s], k) > 0)
        sum += bspline3Derivative(k - u) * std::log(joint(fixedBin_[s], k) / pm[k]);
    weight_[s] = -du * sum / inside;
  }
  return mi;
}

MetricValue MetricEvaluator::evaluate(const Eigen::Matrix4d& T, PriorTransform model, bool gradient) {
  sampleSubject(T);
  MetricValue out;
  int inside = 0;
  out.metric = metric_ == RegistrationMetric::Ncc ? nccWeights(inside) : miWeights(inside);
  out.overlap = moving_.empty() ? 0.0 : static_cast<double>(inside) / static_cast<double>(moving_.size());
  if (!gradient) return out;
  // ∂metric/∂δ = Σ_s w_s · (∂ reference-side update of x_s / ∂δ)ᵀ · ∇_x m_s, x_s relative to the centre.
  Eigen::VectorXd grad = Eigen::VectorXd::Zero(parameterCount(model));
  const double invR = 1.0 / radius_;
  for (size_t s = 0; s < moving_.size(); ++s) {
    if (weight_[s] == 0) continue;
    const Eigen::Vector3d g = weight_[s] * pulledGradient_[s].cast<double>();
    const Eigen::Vector3d r = samples_->points[s] - centre_;
    grad.head<3>() += g;
    if (model == PriorTransform::Affine) {
      for (int j = 0; j < 3; ++j) grad.segment<3>(3 + 3 * j) += g[j] * invR * r;
    } else {
      grad.segment<3>(3) += invR * r.cross(g);
      if (model == PriorTransform::Similarity) grad[6] += invR * r.dot(g);
    }
  }
  out.gradient = grad;
  return out;
}

Eigen::MatrixXd MetricEvaluator::updateJacobian(PriorTransform model, const Eigen::Vector3d& x) const {
  const Eigen::Vector3d r = (x - centre_) / radius_;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3, parameterCount(model));
  J.leftCols<3>().setIdentity();
  if (model == PriorTransform::Affine) {
    for (int j = 0; j < 3; ++j) J.block<1, 3>(j, 3 + 3 * j) = r.transpose();
    return J;
  }
  J.block<3, 3>(0, 3) << 0, r[2], -r[1], -r[2], 0, r[0], r[1], -r[0], 0;  // ∂(ω × r)/∂ω = −[r]×
  if (model == PriorTransform::Similarity) J.col(6) = r;
  return J;
}

bool MetricEvaluator::secondMoments(const Eigen::Matrix4d& T, PriorTransform model, Eigen::MatrixXd& structure,
                                    Eigen::MatrixXd& displacement) {
  sampleSubject(T);
  const int np = parameterCount(model);
  structure = Eigen::MatrixXd::Zero(np, np);
  displacement = Eigen::MatrixXd::Zero(np, np);
  int inside = 0;
  for (size_t s = 0; s < moving_.size(); ++s) {
    if (!inside_[s]) continue;
    const Eigen::MatrixXd J = updateJacobian(model, samples_->points[s]);
    const Eigen::VectorXd j = J.transpose() * pulledGradient_[s].cast<double>();
    structure.selfadjointView<Eigen::Lower>().rankUpdate(j);
    displacement.noalias() += J.transpose() * J;
    ++inside;
  }
  if (inside < kMinSamples) return false;
  structure = structure.selfadjointView<Eigen::Lower>();
  structure /= inside;
  displacement /= inside;
  return true;
}

}  // namespace msk::reg
