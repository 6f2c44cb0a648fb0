#include "msk/test/volumes.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "msk/core/error.h"

namespace msk::test {

namespace {

/// An image on `grid`: each voxel `value(m)`, m the mean of `sample` over the voxel's 4³ sub-samples (world points).
template <class Sample, class Value>
ImageF subsampledImage(const Grid& grid, const Sample& sample, const Value& value) {
  ImageF img(grid, 0.f);
  const int ss = 4;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        double sum = 0;
        for (int a = 0; a < ss; ++a)
          for (int b = 0; b < ss; ++b)
            for (int c = 0; c < ss; ++c)
              sum += sample(grid.toWorld(
                  Eigen::Vector3d(i + (a + 0.5) / ss - 0.5, j + (b + 0.5) / ss - 0.5, k + (c + 0.5) / ss - 0.5)));
        img.at(i, j, k) = value(sum / (ss * ss * ss));
      }
  return img;
}

}  // namespace

ImageF partialVolumeImage(const Grid& grid, const std::function<bool(const Eigen::Vector3d&)>& isInside, float inside,
                          float outside) {
  // The mean of a 0/1 indicator over 64 samples is a count over 64: exact in double.
  return subsampledImage(
      grid, [&](const Eigen::Vector3d& x) { return isInside(x) ? 1.0 : 0.0; },
      [&](double f) { return static_cast<float>(f * inside + (1 - f) * outside); });
}

ImageF sampledImage(const Grid& grid, const std::function<double(const Eigen::Vector3d&)>& intensity) {
  return subsampledImage(grid, intensity, [](double mean) { return static_cast<float>(mean); });
}

ImageF ballImage(const Grid& grid, const Eigen::Vector3d& centre, double radiusMm, float inside, float outside) {
  const double r2 = radiusMm * radiusMm;
  return partialVolumeImage(
      grid, [&](const Eigen::Vector3d& x) { return (x - centre).squaredNorm() <= r2; }, inside, outside);
}

ImageF ellipsoidImage(const Grid& grid, const Eigen::Vector3d& centre, const Eigen::Vector3d& axesMm, float inside,
                      float outside) {
  return partialVolumeImage(
      grid, [&](const Eigen::Vector3d& x) { return (x - centre).cwiseQuotient(axesMm).squaredNorm() <= 1.0; }, inside,
      outside);
}

void paintBall(LabelMap& labels, const Eigen::Vector3d& centre, double radiusMm, int label) {
  const Grid& g = labels.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if ((g.toWorld(Eigen::Vector3d(i, j, k)) - centre).norm() <= radiusMm) labels.at(i, j, k) = label;
}

LabelMap ballLabels(const Grid& grid, const Eigen::Vector3d& centre, double radiusMm, int label) {
  LabelMap labels(grid, 0);
  paintBall(labels, centre, radiusMm, label);
  return labels;
}

ImageF sphereSdf(const Grid& grid, const Eigen::Vector3d& centre, double radiusMm) {
  ImageF f(grid);
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i)
        f.at(i, j, k) = static_cast<float>((grid.toWorld(Eigen::Vector3d(i, j, k)) - centre).norm() - radiusMm);
  return f;
}

double labelDice(const LabelMap& a, int labelA, const LabelMap& b, int labelB) {
  if (a.data.size() != b.data.size()) throw Error("labelDice: the label maps differ in size");
  size_t na = 0, nb = 0, both = 0;
  for (size_t n = 0; n < a.data.size(); ++n) {
    const bool x = a.data[n] == labelA, y = b.data[n] == labelB;
    na += x;
    nb += y;
    both += x && y;
  }
  return na + nb ? 2.0 * static_cast<double>(both) / static_cast<double>(na + nb) : 1.0;
}

Eigen::Vector3d labelCentroid(const LabelMap& labels, int label) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double n = 0;
  for (int k = 0; k < labels.grid.dims[2]; ++k)
    for (int j = 0; j < labels.grid.dims[1]; ++j)
      for (int i = 0; i < labels.grid.dims[0]; ++i)
        if (labels.at(i, j, k) == label) {
          sum += labels.grid.toWorld(Eigen::Vector3d(i, j, k));
          n += 1;
        }
  if (n == 0) throw Error("label " + std::to_string(label) + " not found");
  return sum / n;
}

void voxelBox(const Grid& grid, const std::vector<TriangleMesh>& meshes, double marginMm, Eigen::Vector3i& lo,
              Eigen::Vector3i& hi) {
  Eigen::Vector3d a = Eigen::Vector3d::Constant(1e300), b = Eigen::Vector3d::Constant(-1e300);
  for (const TriangleMesh& m : meshes)
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
      const Eigen::Vector3d p = grid.toVoxel(m.vertices.row(v).transpose());
      a = a.cwiseMin(p);
      b = b.cwiseMax(p);
    }
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(marginMm).cwiseQuotient(grid.spacing);
  for (int d = 0; d < 3; ++d) {
    lo[d] = std::clamp(static_cast<int>(std::floor(a[d] - margin[d])), 0, grid.dims[d] - 1);
    hi[d] = std::clamp(static_cast<int>(std::ceil(b[d] + margin[d])), lo[d], grid.dims[d] - 1);
  }
}

ImageF cropVolume(const ImageF& image, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) {
  Grid g = image.grid;
  g.dims = hi - lo + Eigen::Vector3i::Ones();
  g.origin = image.grid.toWorld(lo.cast<double>());
  ImageF out(g);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) out.at(i, j, k) = image.at(i + lo[0], j + lo[1], k + lo[2]);
  return out;
}

}  // namespace msk::test
