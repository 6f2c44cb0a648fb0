#include "msk/segmentation/quality_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "msk/core/error.h"
#include "msk/core/order_statistics.h"

namespace msk {

namespace {

constexpr double kMadToSigma = 1.4826;  ///< MAD of a normal distribution × this = its standard deviation
constexpr int kSideSamples = 6;         ///< samples each side, 0.5, 1.0, ..., 3.0 mm along the normal
constexpr double kSampleStepMm = 0.5;
constexpr double kFlat = 1e-9;  ///< a difference of normalised intensity this small counts as none

/// The median (the upper one of an even count) of `x`, reordering `x` in place.
double medianInPlace(std::vector<double>& x) {
  if (x.empty()) return 0;
  const auto mid = x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2);
  std::nth_element(x.begin(), mid, x.end());
  return *mid;
}

double median(std::vector<double> x) { return medianInPlace(x); }

/// Median absolute deviation of `x` from `med`.
double mad(const std::vector<double>& x, double med) {
  std::vector<double> d(x.size());
  for (size_t i = 0; i < x.size(); ++i) d[i] = std::fabs(x[i] - med);
  return median(std::move(d));
}

std::string reason(QualityStatus s, const char* figure, double value, const char* relation, double limit) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%s: %s %.3g %s %.3g", qualityStatusName(s), figure, value, relation, limit);
  return buf;
}

}  // namespace

const char* qualityStatusName(QualityStatus s) {
  switch (s) {
    case QualityStatus::Ok:
      return "ok";
    case QualityStatus::Doubtful:
      return "doubtful";
    case QualityStatus::Failed:
      return "failed";
  }
  return "failed";
}

double imageNoiseSigma(const ImageF& image) {
  const Grid& g = image.grid;
  // The differences of neighbours along i, enumerated afresh by each pass of the selections (OrderStatistics) rather
  // than kept: the median, then the median absolute deviation from it.
  const auto differences = [&](const auto& f) {
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j) {
        const float* row = image.data.data() + g.index(0, j, k);
        for (int i = 0; i + 1 < g.dims[0]; ++i) {
          const double a = row[i], b = row[i + 1];
          if (std::isfinite(a) && std::isfinite(b)) f(b - a);
        }
      }
  };
  const OrderStatistics d(differences);
  if (d.count() == 0) return 0;
  const double med = d.select(differences, {d.count() / 2}).front();
  const auto deviations = [&](const auto& f) { differences([&](double x) { f(std::fabs(x - med)); }); };
  const OrderStatistics dev(deviations);
  return kMadToSigma * dev.select(deviations, {dev.count() / 2}).front() / std::sqrt(2.0);
}

ObjectQuality measureQuality(const ImageFeatures& features, const TriangleMesh& mesh, Polarity polarity,
                             TargetMode lastForce, double noiseSigma, const QualityThresholds& t,
                             const std::function<bool(const Eigen::Vector3d&)>& unseen) {
  if (polarity == Polarity::Auto) throw ParameterError("polarity", "Auto", "must be resolved before measureQuality");
  ObjectQuality q;
  q.contrastJudged = lastForce == TargetMode::Gradient;
  const int nv = mesh.vertexCount();
  const double sign = polarity == Polarity::DarkInside ? 1.0 : -1.0;
  const Points normals = nv > 0 ? vertexNormals(mesh) : Points();
  std::vector<double> inside, outside;
  int sampled = 0, edges = 0, expectedOutside = 0;
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3d p = mesh.vertices.row(v).transpose(), n = normals.row(v).transpose();
    if (!(n.norm() > 0.5)) continue;
    double in[kSideSamples], out[kSideSamples];
    int found = 0;
    for (int k = 0; k < kSideSamples; ++k) {
      const double d = kSampleStepMm * (k + 1);
      const auto a = features.sample(p - d * n), b = features.sample(p + d * n);
      if (!a || !b) break;
      in[k] = *a, out[k] = *b, ++found;
    }
    if (found < kSideSamples) {
      if (unseen && unseen(p)) ++expectedOutside;
      continue;
    }
    ++sampled;
    double step = 0;
    for (int k = 0; k < kSideSamples; ++k) {
      inside.push_back(in[k]);
      outside.push_back(out[k]);
      step += sign * (out[k] - in[k]) / kSideSamples;
    }
    if (step > t.significantStep * std::max(noiseSigma, kFlat)) ++edges;
  }
  q.inImageShare = nv > expectedOutside ? static_cast<double>(sampled) / (nv - expectedOutside) : 0.0;
  q.edgeShare = sampled > 0 ? static_cast<double>(edges) / sampled : 0.0;
  if (sampled > 0) {
    const double mIn = median(inside), mOut = median(outside);
    const double spread =
        kMadToSigma * std::sqrt(0.5 * (std::pow(mad(inside, mIn), 2) + std::pow(mad(outside, mOut), 2)));
    const double step = sign * (mOut - mIn);
    q.contrastToNoise = std::fabs(step) <= kFlat ? 0.0 : step / std::max(spread, kFlat);
  }
  judgeQuality(q, t);
  return q;
}

void judgeQuality(ObjectQuality& q, const QualityThresholds& t) {
  q.reasons.clear();
  q.status = QualityStatus::Ok;
  auto flag = [&](QualityStatus s, const char* figure, double value, const char* relation, double limit) {
    q.status = worseStatus(q.status, s);
    q.reasons.push_back(reason(s, figure, value, relation, limit));
  };
  if (q.inImageShare < t.minInImageShare) {
    flag(QualityStatus::Failed, "share of the surface inside the image", q.inImageShare, "<", t.minInImageShare);
    return;  // the other figures describe the few vertices left
  }
  if (q.edgeShare < t.minEdgeShare)
    flag(QualityStatus::Failed, "share of vertices on an edge of the object's polarity", q.edgeShare, "<",
         t.minEdgeShare);
  if (q.contrastJudged && q.contrastToNoise < t.minContrastToNoise)
    flag(QualityStatus::Doubtful, "contrast-to-noise across the surface", q.contrastToNoise, "<", t.minContrastToNoise);
  if (std::isfinite(q.profileMatch) && q.profileMatch < t.minProfileMatch)
    flag(QualityStatus::Doubtful, "correlation of the surface's profiles with the learned ones", q.profileMatch, "<",
         t.minProfileMatch);
  if (q.crossingFacePairs > t.maxCrossingFacePairs)
    flag(QualityStatus::Doubtful, "pairs of faces of the surface crossing each other",
         static_cast<double>(q.crossingFacePairs), ">", static_cast<double>(t.maxCrossingFacePairs));
}

}  // namespace msk
