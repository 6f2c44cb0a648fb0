#include "phantom_synthesis.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "msk/core/error.h"

namespace msk::phantom {

namespace {

std::string num(double v) { return std::to_string(v); }
std::string vec(const Eigen::Vector3d& v) { return num(v[0]) + "," + num(v[1]) + "," + num(v[2]); }

// Separable Gaussian blur with sigma = `sigmaVoxels` along each grid axis (replicated borders).
void blurVoxels(ImageF& img, double sigmaVoxels) {
  const int r = static_cast<int>(std::ceil(3 * sigmaVoxels));
  std::vector<double> w(static_cast<size_t>(2 * r + 1));
  double sum = 0;
  for (int d = -r; d <= r; ++d)
    sum += w[static_cast<size_t>(d + r)] = std::exp(-0.5 * d * d / (sigmaVoxels * sigmaVoxels));
  for (double& x : w) x /= sum;
  const Eigen::Vector3i n = img.grid.dims;
  std::vector<float> line;
  for (int axis = 0; axis < 3; ++axis) {
    const int len = n[axis];
    line.resize(static_cast<size_t>(len));
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    for (int v = 0; v < n[a2]; ++v)
      for (int u = 0; u < n[a1]; ++u) {
        Eigen::Vector3i ijk;
        ijk[a1] = u;
        ijk[a2] = v;
        for (int t = 0; t < len; ++t) {
          ijk[axis] = t;
          line[static_cast<size_t>(t)] = img.at(ijk[0], ijk[1], ijk[2]);
        }
        for (int t = 0; t < len; ++t) {
          double s = 0;
          for (int d = -r; d <= r; ++d)
            s += w[static_cast<size_t>(d + r)] * line[static_cast<size_t>(std::clamp(t + d, 0, len - 1))];
          ijk[axis] = t;
          img.at(ijk[0], ijk[1], ijk[2]) = static_cast<float>(s);
        }
      }
  }
}

// Smooth multiplicative bias: 1 + amplitude · B(p), B a sum of three long-wavelength plane waves, |B| ≤ 1.
struct BiasField {
  std::array<Eigen::Vector3d, 3> k;
  std::array<double, 3> phase{}, weight{0.5, 0.3, 0.2};
  explicit BiasField(uint32_t seed) {
    Random rng(seed);
    for (size_t j = 0; j < 3; ++j) {
      Eigen::Vector3d d = rng.normal3();
      if (d.norm() < 1e-6) d = Eigen::Vector3d::UnitX();
      k[j] = d.normalized() * (2 * M_PI / rng.uniform(250, 450));
      phase[j] = rng.uniform(0, 2 * M_PI);
    }
  }
  double operator()(const Eigen::Vector3d& p) const {
    double b = 0;
    for (size_t j = 0; j < 3; ++j) b += weight[j] * std::sin(k[j].dot(p) + phase[j]);
    return b;
  }
};

}  // namespace

}  // namespace msk::phantom

namespace msk {

void checkPhantomOptions(const PhantomOptions& o) {
  using phantom::num;
  using phantom::vec;
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(o.spacing[a]) || o.spacing[a] <= 0 || o.spacing[a] > 10)
      throw ParameterError("--spacing", vec(o.spacing), "each voxel size must be in (0, 10] mm");
  if (!o.obliqueDegrees.allFinite()) throw ParameterError("--oblique", vec(o.obliqueDegrees), "angles must be finite");
  checkPhantomPose(o.pose);
  if (!std::isfinite(o.noise) || o.noise < 0 || o.noise > 1)
    throw ParameterError("--noise", num(o.noise), "must be in [0, 1] (fraction of fat intensity)");
  if (!std::isfinite(o.bias) || o.bias < 0 || o.bias >= 1)
    throw ParameterError("--bias", num(o.bias), "must be in [0, 1)");
  if (o.fovZ && !(o.fovZ->allFinite() && (*o.fovZ)[0] < (*o.fovZ)[1] && o.fovZ->cwiseAbs().maxCoeff() <= 1000))
    throw ParameterError("--fov-z", std::to_string((*o.fovZ)[0]) + "," + std::to_string((*o.fovZ)[1]),
                         "must be two finite numbers lo < hi within ±1000 mm");
  if (o.meshVertices < 100 || o.meshVertices > 1000000)
    throw ParameterError("--vertices", std::to_string(o.meshVertices), "must be in [100, 1000000]");
  if (!std::isfinite(o.meshSpacingMm) || o.meshSpacingMm < 0.2 || o.meshSpacingMm > 3)
    throw ParameterError("meshSpacingMm", num(o.meshSpacingMm), "must be in [0.2, 3] mm");
}

}  // namespace msk

namespace msk::phantom {

uint32_t streamSeed(uint32_t seed, uint32_t stream) {
  uint64_t z = (static_cast<uint64_t>(seed) << 32 | stream) + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return static_cast<uint32_t>((z ^ (z >> 31)) & 0xffffffffu);
}

Grid coveringGrid(const Eigen::Vector3d& spacing, const Eigen::Vector3d& obliqueDegrees, const Eigen::Vector3d& boxLo,
                  const Eigen::Vector3d& boxHi, const PhantomPose& pose, const std::optional<Eigen::Vector2d>& slab) {
  Grid g;
  g.spacing = spacing;
  g.direction = Grid::rotationXYZ(obliqueDegrees);
  const Eigen::Matrix4d p = phantomPoseMatrix(pose);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? boxHi[0] : boxLo[0], (c & 2) ? boxHi[1] : boxLo[1],
                                 (c & 4) ? boxHi[2] : boxLo[2]);
    const Eigen::Vector3d posed =
        pose.isIdentity() ? corner : Eigen::Vector3d(p.topLeftCorner<3, 3>() * corner + p.topRightCorner<3, 1>());
    const Eigen::Vector3d v = g.direction.transpose() * posed;
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  if (slab) {
    lo[2] = std::max(lo[2], (*slab)[0]);
    hi[2] = std::min(hi[2], (*slab)[1]);
    if (!(lo[2] < hi[2]))
      throw ParameterError("--fov-z", std::to_string((*slab)[0]) + "," + std::to_string((*slab)[1]),
                           "leaves nothing of the phantom's field of view (" + std::to_string(lo[2]) + " to " +
                               std::to_string(hi[2]) + " mm before the cut)");
  }
  for (int a = 0; a < 3; ++a) {
    g.dims[a] = static_cast<int>(std::ceil((hi[a] - lo[a]) / g.spacing[a] - 1e-9)) + 1;
    lo[a] -= 0.5 * ((g.dims[a] - 1) * g.spacing[a] - (hi[a] - lo[a]));
  }
  g.origin = g.direction * lo;
  return g;
}

Grid anatomyGrid(const Grid& image, const PhantomPose& pose) {
  if (pose.isIdentity()) return image;
  const Eigen::Matrix4d inverse = phantomPoseInverse(pose);
  Grid g = image;
  g.origin = inverse.topLeftCorner<3, 3>() * image.origin + inverse.topRightCorner<3, 1>();
  g.direction = Grid::rotationXYZ(pose.rotationDegrees).transpose() * image.direction;
  g.spacing = image.spacing / pose.scale;
  return g;
}

void renderTissues(const std::function<PointClass(const Eigen::Vector3d&)>& classify, double lipschitz,
                   const PhantomPose& pose, ImageF& image, LabelMap& labels, LabelMap& tissues,
                   const std::function<void(int k)>& sliceDone) {
  // Voxel (i, j, k) of the output grid shows the un-posed anatomy at P⁻¹(x_ijk), the voxel (i, j, k) of this grid.
  const Grid grid = anatomyGrid(labels.grid, pose);
  const Eigen::Matrix3d step = grid.direction * grid.spacing.asDiagonal();
  const double halfDiagonal = 0.5 * grid.spacing.norm();
  Eigen::Vector3i sub;
  for (int a = 0; a < 3; ++a) sub[a] = std::clamp(static_cast<int>(std::ceil(grid.spacing[a] / 0.6)), 2, 5);
  std::vector<Eigen::Vector3d> offsets;
  for (int c = 0; c < sub[2]; ++c)
    for (int b = 0; b < sub[1]; ++b)
      for (int a = 0; a < sub[0]; ++a)
        offsets.push_back(
            step * Eigen::Vector3d((a + 0.5) / sub[0] - 0.5, (b + 0.5) / sub[1] - 0.5, (c + 0.5) / sub[2] - 0.5));
  for (int k = 0; k < grid.dims[2]; ++k) {
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        const Eigen::Vector3d p = grid.toWorld(Eigen::Vector3d(i, j, k));
        const PointClass c = classify(p);
        const size_t n = grid.index(i, j, k);
        labels.data[n] = c.label;
        tissues.data[n] = c.tissue;
        double v = kTissueIntensity[c.tissue];
        if (c.bound < lipschitz * halfDiagonal) {
          v = 0;
          for (const Eigen::Vector3d& d : offsets) v += kTissueIntensity[classify(p + d).tissue];
          v /= static_cast<double>(offsets.size());
        }
        image.data[n] = static_cast<float>(v);
      }
    if ((k & 7) == 7 && sliceDone) sliceDone(k);
  }
}

TriangleMesh posedMesh(const TriangleMesh& truth, const PhantomPose& pose) {
  TriangleMesh m = truth;
  if (!pose.isIdentity()) transformMesh(m, phantomPoseMatrix(pose));
  return m;
}

void degradeImage(ImageF& image, uint32_t seed, double noise, double bias) {
  blurVoxels(image, 0.5);
  const BiasField field(streamSeed(seed, 2));
  Random rng(streamSeed(seed, 3));
  const Grid& grid = image.grid;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        const size_t n = grid.index(i, j, k);
        double v = image.data[n];
        if (bias > 0) v *= 1.0 + bias * field(grid.toWorld(Eigen::Vector3d(i, j, k)));
        if (noise > 0) {
          const double n1 = noise * rng.normal(), n2 = noise * rng.normal();
          v = std::sqrt((v + n1) * (v + n1) + n2 * n2);
        }
        image.data[n] = static_cast<float>(kFatIntensity * v);
      }
}

Grid implicitSamplingGrid(const std::array<Eigen::Vector3d, 2>& box, double h) {
  constexpr int S = kSampleCoarsening;
  Grid g;
  g.spacing = Eigen::Vector3d::Constant(h);
  for (int a = 0; a < 3; ++a) {
    const double lo = box[0][a] - 3 * h, hi = box[1][a] + 3 * h;
    const int cells = static_cast<int>(std::ceil((hi - lo) / (S * h)));
    g.dims[a] = S * cells + 1;
    g.origin[a] = 0.5 * (lo + hi) - 0.5 * (g.dims[a] - 1) * h;
  }
  return g;
}

ImageF sampleImplicit(const Grid& g, double lipschitz, const std::function<float(int i, int j, int k)>& eval) {
  constexpr int S = kSampleCoarsening;
  ImageF f(g);
  const Eigen::Vector3i cells = (g.dims - Eigen::Vector3i::Ones()) / S;
  const double h = g.spacing[0];
  // Coarse lattice.
  const Eigen::Vector3i cn = cells + Eigen::Vector3i::Ones();
  std::vector<float> coarse(static_cast<size_t>(cn[0]) * cn[1] * cn[2]);
  auto cidx = [&](int i, int j, int k) {
    return static_cast<size_t>(i) + static_cast<size_t>(cn[0]) * (j + static_cast<size_t>(cn[1]) * k);
  };
  for (int k = 0; k < cn[2]; ++k)
    for (int j = 0; j < cn[1]; ++j)
      for (int i = 0; i < cn[0]; ++i) coarse[cidx(i, j, k)] = eval(S * i, S * j, S * k);
  // Interpolate everywhere (sign-correct in cells far from the surface) ...
  for (int k = 0; k < g.dims[2]; ++k) {
    const int ck = std::min(k / S, cells[2] - 1);
    const double tk = (k - S * ck) / static_cast<double>(S);
    for (int j = 0; j < g.dims[1]; ++j) {
      const int cj = std::min(j / S, cells[1] - 1);
      const double tj = (j - S * cj) / static_cast<double>(S);
      for (int i = 0; i < g.dims[0]; ++i) {
        const int ci = std::min(i / S, cells[0] - 1);
        const double ti = (i - S * ci) / static_cast<double>(S);
        double v = 0;
        for (int c = 0; c < 8; ++c) {
          const double wt = ((c & 1) ? ti : 1 - ti) * ((c & 2) ? tj : 1 - tj) * ((c & 4) ? tk : 1 - tk);
          if (wt != 0) v += wt * coarse[cidx(ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1))];
        }
        f.at(i, j, k) = static_cast<float>(v);
      }
    }
  }
  // ... then evaluate exactly in the cells that may hold surface.
  const double threshold = lipschitz * 0.5 * std::sqrt(3.0) * S * h;
  std::vector<uint8_t> done(g.voxelCount(), 0);
  for (int ck = 0; ck < cells[2]; ++ck)
    for (int cj = 0; cj < cells[1]; ++cj)
      for (int ci = 0; ci < cells[0]; ++ci) {
        bool pos = false, neg = false;
        double minAbs = INFINITY;
        for (int c = 0; c < 8; ++c) {
          const float v = coarse[cidx(ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1))];
          (v < 0 ? neg : pos) = true;
          minAbs = std::min(minAbs, std::fabs(static_cast<double>(v)));
        }
        if (!(pos && neg) && minAbs > threshold) continue;
        for (int k = S * ck; k <= S * ck + S; ++k)
          for (int j = S * cj; j <= S * cj + S; ++j)
            for (int i = S * ci; i <= S * ci + S; ++i) {
              const size_t n = g.index(i, j, k);
              if (done[n]) continue;
              done[n] = 1;
              f.data[n] = eval(i, j, k);
            }
      }
  return f;
}

}  // namespace msk::phantom
