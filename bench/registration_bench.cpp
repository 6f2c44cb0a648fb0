// Atlas registration: an atlas reference (a 150 mm box at 1.5 mm) onto a subject of 384 × 384 × 35 voxels at
// 0.9 × 0.9 × 5.2 mm (oblique), global affine with the coarse search, then similarity per object (60 mm boxes around
// four structures, starting from the global result). Synthetic images (ellipsoids + noise), the subject moved by a
// known rigid transform (12°, 25 mm). Target: the whole (global + per-object) ≤ 5 s on 2 cores.
// Run: build/bench/registration_bench  (counters: seconds per part, rotation and translation errors).
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <random>

#include "msk/imaging/registration.h"

namespace {

/// Ellipsoids (centre mm, semi-axes mm, intensity) of the synthetic anatomy about the origin; later ones win.
struct Blob {
  Eigen::Vector3d centre, axes;
  float value;
};
const std::array<Blob, 5> kBlobs = {Blob{{0, 0, 0}, {65, 50, 70}, 100.f}, Blob{{25, 10, -20}, {14, 14, 40}, 200.f},
                                    Blob{{-25, -12, 15}, {12, 18, 30}, 160.f}, Blob{{-5, 25, 30}, {25, 9, 12}, 40.f},
                                    Blob{{10, -25, -30}, {10, 12, 20}, 240.f}};

/// The anatomy moved by `truth` sampled at the voxel centres of `grid`, plus Gaussian noise σ = 6.
msk::ImageF anatomy(const msk::Grid& grid, const Eigen::Matrix4d& truth, unsigned seed) {
  const Eigen::Matrix4d toAnatomy = truth.inverse() * grid.voxelToWorld();
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, 6.f);
  msk::ImageF img(grid);
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        const Eigen::Vector3d x = (toAnatomy * Eigen::Vector4d(i, j, k, 1)).head<3>();
        float v = 0;
        for (const Blob& b : kBlobs)
          if ((x - b.centre).cwiseQuotient(b.axes).squaredNorm() <= 1) v = b.value;
        img.at(i, j, k) = v + noise(rng);
      }
  return img;
}

void BM_AtlasRegistration(benchmark::State& state) {
  msk::Grid sg;  // the subject: 384 × 384 × 35 at 0.9 × 0.9 × 5.2 mm, oblique
  sg.dims = {384, 384, 35};
  sg.spacing = {0.9, 0.9, 5.2};
  sg.direction = msk::Grid::rotationXYZ({8, 0, -10});
  sg.origin = -sg.direction * (0.5 * (sg.dims.cast<double>() - Eigen::Vector3d::Ones()).cwiseProduct(sg.spacing));
  Eigen::Matrix4d truth = Eigen::Matrix4d::Identity();
  truth.topLeftCorner<3, 3>() = Eigen::AngleAxisd(12 * M_PI / 180, Eigen::Vector3d(1, -1, 2).normalized()).matrix();
  truth.topRightCorner<3, 1>() = Eigen::Vector3d(15, -12, 16);
  const msk::ImageF subject = anatomy(sg, truth, 1);
  msk::Grid rg;  // the atlas: a 150 mm box at 1.5 mm
  rg.dims = {100, 100, 100};
  rg.spacing = {1.5, 1.5, 1.5};
  rg.origin = Eigen::Vector3d::Constant(-74.25);
  const msk::ImageF atlas = anatomy(rg, Eigen::Matrix4d::Identity(), 2);

  msk::RegistrationOptions global;
  global.threads = 2;
  msk::RegistrationOptions local = global;
  local.initialise = false;
  local.model = msk::PriorTransform::Similarity;
  double globalSeconds = 0, localSeconds = 0, worstDegrees = 0, worstMm = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const msk::RegistrationResult g = msk::registerImages(atlas, subject, global);
    const auto t1 = std::chrono::steady_clock::now();
    worstDegrees = msk::transformDifference(g.transform, truth).degrees;
    worstMm = msk::transformDifference(g.transform, truth).mm;
    for (int b = 1; b < 5; ++b) {  // per object: a 60 mm box around each inner structure
      const Eigen::Vector3d c = kBlobs[b].centre;
      const msk::ImageF box = msk::cropToWorldBox(atlas, c.array() - 30, c.array() + 30);
      const msk::RegistrationResult o = msk::registerImages(box, subject, local, g.transform);
      const msk::TransformDifference d = msk::transformDifference(o.transform, truth, c);
      worstDegrees = std::max(worstDegrees, d.degrees), worstMm = std::max(worstMm, d.mm);
    }
    const auto t2 = std::chrono::steady_clock::now();
    globalSeconds = std::chrono::duration<double>(t1 - t0).count();
    localSeconds = std::chrono::duration<double>(t2 - t1).count();
  }
  state.counters["global_s"] = globalSeconds;
  state.counters["four_objects_s"] = localSeconds;
  state.counters["total_s"] = globalSeconds + localSeconds;
  state.counters["worst_deg"] = worstDegrees;
  state.counters["worst_mm"] = worstMm;
}
BENCHMARK(BM_AtlasRegistration)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
