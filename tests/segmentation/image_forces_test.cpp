#include "msk/segmentation/image_forces.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <set>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/filters.h"
#include "msk/imaging/registration.h"
#include "msk/test/shapes.h"
#include "msk/test/volumes.h"

namespace msk {
namespace {

const Eigen::Vector3d kCenter(0.37, -0.61, 0.23);  // ball centre, off the grid lattice
constexpr double kRadius = 20.0;
constexpr double kDegree = 3.14159265358979323846 / 180;  // radians

/// An oblique grid (rotation in degrees) covering ±halfExtentMm around kCenter, its centre off the ball's centre.
Grid ballGrid(const Eigen::Vector3d& spacing, const Eigen::Vector3d& rotationDeg, double halfExtentMm) {
  Grid g;
  g.spacing = spacing;
  g.direction = Grid::rotationXYZ(rotationDeg);
  for (int a = 0; a < 3; ++a) g.dims[a] = static_cast<int>(std::ceil(2 * halfExtentMm / spacing[a])) + 1;
  const Eigen::Vector3d gridCenter = kCenter + Eigen::Vector3d(0.31, -0.17, 0.53);
  g.origin = gridCenter - g.direction * spacing.cwiseProduct((g.dims.cast<double>().array() - 1).matrix() / 2);
  return g;
}

/// A volume on ballGrid(), each voxel the mean of `intensity` over its 4³ sub-samples (partial volume), then blurred
/// by `blurMm`.
ImageF makeImage(const Eigen::Vector3d& spacing, const Eigen::Vector3d& rotationDeg, double halfExtentMm,
                 const std::function<double(const Eigen::Vector3d&)>& intensity, double blurMm = 0.5) {
  return gaussianSmooth(test::sampledImage(ballGrid(spacing, rotationDeg, halfExtentMm), intensity), blurMm);
}

/// The ball of radius kRadius about kCenter on ballGrid() with partial volume (`inside` in, `outside` out), blurred by
/// `blurMm`.
ImageF ballImage(const Eigen::Vector3d& spacing, double halfExtentMm, float inside, float outside,
                 double blurMm = 0.5) {
  const Grid g = ballGrid(spacing, {10, -5, 20}, halfExtentMm);
  return gaussianSmooth(test::ballImage(g, kCenter, kRadius, inside, outside), blurMm);
}

/// The T1-like ball: 200 inside radius 20 mm, 800 outside (DarkInside), on 1.2×1.2×3 mm rotated (10°, −5°, 20°).
ImageF darkBall() { return ballImage({1.2, 1.2, 3.0}, 36, 200.f, 800.f); }

/// Vertex positions, normals and neighbour table of a sphere of radius `r` around kCenter: the simplex sphere's
/// neighbourhoods, its vertices put on the sphere, normals radial.
struct Sphere {
  Points positions, normals;
  NeighborTable neighbors;
};

Sphere makeSphere(double r, int subdivisions = 3) {
  const SimplexMesh m = test::simplexSphere(r, subdivisions, kCenter);
  Sphere s;
  s.normals = (m.positions.rowwise() - kCenter.transpose()).rowwise().normalized();
  s.positions = (r * s.normals).rowwise() + kCenter.transpose();
  s.neighbors = m.neighbors;
  return s;
}

/// Radial errors |target − c| − 20 of the vertices in `which` (all if empty).
struct RadialError {
  double mean = 0, meanAbs = 0, maxAbs = 0;
};

RadialError radialError(const Points& targets, const std::vector<int>& which = {}) {
  std::vector<int> idx = which;
  if (idx.empty())
    for (int v = 0; v < targets.rows(); ++v) idx.push_back(v);
  RadialError e;
  for (int v : idx) {
    const double d = (targets.row(v).transpose() - kCenter).norm() - kRadius;
    e.mean += d;
    e.meanAbs += std::abs(d);
    e.maxAbs = std::max(e.maxAbs, std::abs(d));
  }
  e.mean /= static_cast<double>(idx.size());
  e.meanAbs /= static_cast<double>(idx.size());
  return e;
}

/// Every entry of the result is finite.
bool allFinite(const TargetSearchResult& r) {
  return r.targets.allFinite() && r.offsets.allFinite() && r.scores.allFinite() && r.residual.allFinite();
}

/// Checks targets from spheres at 17 and 23 mm land on r = 20 within 0.25 voxel (mean) and 0.6 mm (max).
void expectEdgeFound(const ImageF& image, Polarity expected, double voxelMm, double maxErrorMm) {
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  for (double r0 : {17.0, 23.0}) {
    SCOPED_TRACE("start radius " + std::to_string(r0));
    const Sphere s = makeSphere(r0);
    const Polarity p = estimatePolarity(f, s.positions, s.normals);
    EXPECT_EQ(p, expected);
    const TargetSearchResult res = searchTargets(f, s.positions, s.normals, s.neighbors, {}, p, image.grid);
    ASSERT_TRUE(allFinite(res));
    EXPECT_GT(res.scores.minCoeff(), 0.0);
    const RadialError e = radialError(res.targets);
    ::testing::Test::RecordProperty("mean_error_r" + std::to_string(static_cast<int>(r0)), std::to_string(e.mean));
    ::testing::Test::RecordProperty("max_error_r" + std::to_string(static_cast<int>(r0)), std::to_string(e.maxAbs));
    EXPECT_LT(std::abs(e.mean), 0.15);
    EXPECT_LT(e.meanAbs, 0.25 * voxelMm);
    EXPECT_LT(e.maxAbs, maxErrorMm);
    EXPECT_NEAR(res.residual.mean(), 3.0, 0.3);
  }
}

TEST(ImageForcesGradient, DarkInsideFindsTheEdgeFromBothSides) {
  expectEdgeFound(darkBall(), Polarity::DarkInside, 1.2, 0.6);
}

TEST(ImageForcesGradient, BrightInsideFindsTheEdgeWithEstimatedPolarity) {
  ImageF inverted = darkBall();
  for (float& v : inverted.data) v = 1000.f - v;
  expectEdgeFound(inverted, Polarity::BrightInside, 1.2, 0.6);
}

TEST(ImageForcesGradient, WrongPolarityFindsNoStrongEdge) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere s = makeSphere(23.0);
  const TargetSearchResult right =
      searchTargets(f, s.positions, s.normals, s.neighbors, {}, Polarity::DarkInside, image.grid);
  const TargetSearchResult wrong =
      searchTargets(f, s.positions, s.normals, s.neighbors, {}, Polarity::BrightInside, image.grid);
  ASSERT_TRUE(allFinite(wrong));
  int strongAtEdge = 0;
  for (int v = 0; v < s.positions.rows(); ++v) {
    const double err = std::abs((wrong.targets.row(v).transpose() - kCenter).norm() - kRadius);
    if (err < 0.6 && wrong.scores[v] > 0.1 * right.scores[v]) ++strongAtEdge;
  }
  RecordProperty("wrong_polarity_strong_at_edge", strongAtEdge);
  RecordProperty("wrong_max_score_over_right_min_score",
                 std::to_string(wrong.scores.maxCoeff() / right.scores.minCoeff()));
  EXPECT_LT(strongAtEdge, s.positions.rows() / 20);
  EXPECT_LT(wrong.scores.maxCoeff(), 0.1 * right.scores.minCoeff());
}

TEST(ImageForcesProfile, LearnedOnTheSurfaceFindsItAgain) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere truth = makeSphere(kRadius), start = makeSphere(22.0);
  TargetSearchOptions opts;
  opts.mode = TargetMode::Profile;
  const LearnedProfiles lp = learnProfiles(f, truth.positions, truth.normals, opts, image.grid);
  ASSERT_EQ(lp.profiles.rows(), truth.positions.rows());
  ASSERT_EQ(lp.profiles.cols(), 2 * lp.halfSamples + 1);
  EXPECT_NEAR(lp.halfSamples * lp.stepMm, 2 * 3.0, lp.stepMm);  // default: 2 × the largest spacing
  for (int v = 0; v < lp.profiles.rows(); ++v) {
    EXPECT_NEAR(lp.profiles.row(v).sum(), 0.0, 1e-9);
    EXPECT_NEAR(lp.profiles.row(v).norm(), 1.0, 1e-9);
  }
  const TargetSearchResult res =
      searchTargets(f, start.positions, start.normals, start.neighbors, opts, Polarity::DarkInside, image.grid, &lp);
  ASSERT_TRUE(allFinite(res));
  EXPECT_GT(res.scores.minCoeff(), 0.9);
  const RadialError e = radialError(res.targets);
  RecordProperty("mean_error", std::to_string(e.mean));
  RecordProperty("max_error", std::to_string(e.maxAbs));
  EXPECT_LT(e.maxAbs, 0.3);
  EXPECT_LT(std::abs(e.mean), 0.1);
}

// A structure the source of its profiles cuts: a dark tube (radius 15 mm along z), its profiles learned on an image
// cropped above kCenter.z + 8 mm. A vertex on the tube's side beyond the crop borrows the profile of the nearest
// vertex that has one with a normal within kProfileBorrowDegrees, and finds the tube's wall in the whole image; a
// vertex inside the crop whose line leaves it keeps none, as does the tube's cap, facing along it. Without borrowing,
// every vertex whose line leaves the crop keeps none.
TEST(ImageForcesProfile, VerticesBeyondTheSourceBorrowTheNearestProfile) {
  constexpr double kTube = 15;
  const ImageF whole = makeImage({1.2, 1.2, 3.0}, {10, -5, 20}, 40, [](const Eigen::Vector3d& p) {
    return (p - kCenter).head<2>().norm() < kTube ? 200.0 : 800.0;
  });
  const Eigen::Vector3d lo = kCenter - Eigen::Vector3d::Constant(50), hi = kCenter + Eigen::Vector3d(50, 50, 8);
  const ImageF cut = cropToWorldBox(whole, lo, hi);
  const ImageFeatures fCut = computeImageFeatures(cut, 1.0), fWhole = computeImageFeatures(whole, 1.0);
  // Rings of the tube every 2 mm from −24 to +24 mm, and its top cap; radial normals (the cap's point up).
  std::vector<Eigen::Vector3d> at, normal;
  for (int k = -12; k <= 12; ++k)
    for (int a = 0; a < 36; ++a) {
      const Eigen::Vector3d n(std::cos(a * 10 * kDegree), std::sin(a * 10 * kDegree), 0);
      at.push_back(kCenter + kTube * n + Eigen::Vector3d(0, 0, 2.0 * k));
      normal.push_back(n);
    }
  const int capFrom = static_cast<int>(at.size());
  for (int a = 0; a < 36; ++a) {
    const Eigen::Vector3d r(std::cos(a * 10 * kDegree), std::sin(a * 10 * kDegree), 0);
    at.push_back(kCenter + 7.0 * r + Eigen::Vector3d(0, 0, 24));
    normal.push_back(Eigen::Vector3d::UnitZ());
  }
  Points positions(at.size(), 3), normals(at.size(), 3), start(at.size(), 3);
  for (size_t v = 0; v < at.size(); ++v) {
    positions.row(v) = at[v].transpose();
    normals.row(v) = normal[v].transpose();
    start.row(v) = (at[v] + 2.0 * normal[v]).transpose();  // 2 mm out
  }
  TargetSearchOptions opts;
  opts.mode = TargetMode::Profile;
  opts.regularisationRings = 0;
  const LearnedProfiles own = learnProfiles(fCut, positions, normals, opts, whole.grid, false);
  const LearnedProfiles lp = learnProfiles(fCut, positions, normals, opts, whole.grid);
  const TargetSearchResult res =
      searchTargets(fWhole, start, normals, NeighborTable(), opts, Polarity::DarkInside, whole.grid, &lp);
  const double minCos = std::cos(kProfileBorrowDegrees * kDegree);
  int borrowed = 0, none = 0, near = 0;
  for (int v = 0; v < positions.rows(); ++v) {
    if (own.profiles.row(v).squaredNorm() > 0) {
      EXPECT_EQ(lp.profiles.row(v), own.profiles.row(v)) << "vertex " << v;
      continue;
    }
    const Eigen::Vector3d n = normals.row(v).transpose();
    // Only a vertex beyond the crop's voxel centres with its normal at least 60° from the axis it is beyond along.
    const Eigen::Vector3d voxel = cut.grid.toVoxel(positions.row(v).transpose());
    bool beyond = false, facingOut = false;
    for (int a = 0; a < 3; ++a)
      if (voxel[a] < 0 || voxel[a] > cut.grid.dims[a] - 1) {
        beyond = true;
        facingOut = facingOut || std::abs(n.dot(cut.grid.direction.col(a))) > 0.5;
      }
    beyond = beyond && !facingOut;
    if (!beyond || v >= capFrom) {
      ++(v >= capFrom ? none : near);
      EXPECT_EQ(lp.profiles.row(v).squaredNorm(), 0.0) << "vertex " << v;
      continue;
    }
    // Its profile is that of the nearest vertex with one and a normal close enough (or of one as near).
    double best = kProfileBorrowMm * kProfileBorrowMm;
    for (int u = 0; u < positions.rows(); ++u) {
      const double d2 = (positions.row(u) - positions.row(v)).squaredNorm();
      if (own.profiles.row(u).squaredNorm() > 0 && normals.row(u).dot(n) >= minCos && d2 < best) best = d2;
    }
    bool fromNearest = false;
    for (int u = 0; u < positions.rows(); ++u)
      fromNearest = fromNearest || (own.profiles.row(u).squaredNorm() > 0 && normals.row(u).dot(n) >= minCos &&
                                    (positions.row(u) - positions.row(v)).squaredNorm() <= best + 1e-9 &&
                                    lp.profiles.row(v) == own.profiles.row(u));
    EXPECT_TRUE(fromNearest) << "vertex " << v;
    ++borrowed;
    // It finds the wall, 2 mm in from where the search started.
    EXPECT_GT(res.scores[v], 0.5) << "vertex " << v;
    EXPECT_NEAR(res.offsets[v], -2.0, 0.5) << "vertex " << v;
  }
  RecordProperty("borrowed_cap_near",
                 std::to_string(borrowed) + "/" + std::to_string(none) + "/" + std::to_string(near));
  EXPECT_GT(borrowed, 36);  // the crop of the oblique grid reaches above +8 mm in places
  EXPECT_EQ(none, 36);
  EXPECT_GT(near, 0);
}

TEST(ImageForcesProfile, RequiresMatchingProfiles) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere s = makeSphere(kRadius, 1);
  TargetSearchOptions opts;
  opts.mode = TargetMode::Profile;
  EXPECT_THROW(searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside, image.grid), Error);
  LearnedProfiles lp = learnProfiles(f, s.positions, s.normals, opts, image.grid);
  lp.profiles.conservativeResize(lp.profiles.rows() - 1, Eigen::NoChange);
  EXPECT_THROW(searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside, image.grid, &lp),
               ParameterError);
  EXPECT_THROW(searchTargets(f, s.positions, s.normals, s.neighbors, {}, Polarity::Auto, image.grid), ParameterError);
}

TEST(ImageForcesRobustness, RejectsInconsistentInput) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  EXPECT_THROW(computeImageFeatures(image, -1.0), ParameterError);
  Sphere s = makeSphere(kRadius, 1);
  const Points fewerNormals = s.normals.topRows(3);
  EXPECT_THROW(estimatePolarity(f, s.positions, fewerNormals), ParameterError);
  EXPECT_THROW(searchTargets(f, s.positions, fewerNormals, s.neighbors, {}, Polarity::DarkInside, image.grid),
               ParameterError);
  TargetSearchOptions negative;
  negative.rangeMm = -1;
  EXPECT_THROW(searchTargets(f, s.positions, s.normals, s.neighbors, negative, Polarity::DarkInside, image.grid),
               ParameterError);
  s.neighbors(0, 0) = static_cast<int>(s.positions.rows());
  EXPECT_THROW(searchTargets(f, s.positions, s.normals, s.neighbors, {}, Polarity::DarkInside, image.grid),
               ParameterError);
}

TEST(ImageForcesRegularisation, PullsOutliersFromADistractingShellTowardTheirNeighbours) {
  // A bright thin shell fragment (2500, 1.2 mm thick) at r = 23 over a 10° cap: searched from r = 22 at a fine scale,
  // it out-scores the true edge at 20 for the few vertices under the cap.
  const Eigen::Vector3d axis = Grid::rotationXYZ({10, -5, 20}) * Eigen::Vector3d(0.8, 0.6, 0.0);  // in-slice
  const double capCos = std::cos(10.0 * kDegree);
  const ImageF image = makeImage({1.2, 1.2, 3.0}, {10, -5, 20}, 36, [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d d = p - kCenter;
    const double r = d.norm();
    if (r < kRadius) return 200.0;
    if (std::abs(r - 23.0) < 0.6 && d.dot(axis) > capCos * r) return 2500.0;
    return 800.0;
  });
  const ImageFeatures f = computeImageFeatures(image, 0.5);
  const Sphere s = makeSphere(22.0);
  std::vector<int> affected;
  for (int v = 0; v < s.positions.rows(); ++v)
    if ((s.positions.row(v).transpose() - kCenter).normalized().dot(axis) > capCos) affected.push_back(v);
  ASSERT_GE(affected.size(), 3u);

  TargetSearchOptions raw;
  raw.regularisationRings = 0;
  TargetSearchOptions smooth;
  smooth.regularisationRings = 4;  // on the simplex mesh, about the reach of two rings of its triangle mesh
  const TargetSearchResult a =
      searchTargets(f, s.positions, s.normals, s.neighbors, raw, Polarity::DarkInside, image.grid);
  const TargetSearchResult b =
      searchTargets(f, s.positions, s.normals, s.neighbors, smooth, Polarity::DarkInside, image.grid);
  ASSERT_TRUE(allFinite(b));
  const RadialError ea = radialError(a.targets, affected), eb = radialError(b.targets, affected);
  RecordProperty("raw_mean_abs_error_affected", std::to_string(ea.meanAbs));
  RecordProperty("regularised_mean_abs_error_affected", std::to_string(eb.meanAbs));
  RecordProperty("raw_max_abs_error_affected", std::to_string(ea.maxAbs));
  RecordProperty("regularised_max_abs_error_affected", std::to_string(eb.maxAbs));
  EXPECT_GT(ea.maxAbs, 1.5);  // the distractor wins without regularisation
  EXPECT_LT(eb.meanAbs, 0.8 * ea.meanAbs);
  EXPECT_LT(eb.maxAbs, ea.maxAbs);
  auto outliers = [&](const Points& t) {
    int n = 0;
    for (int v = 0; v < t.rows(); ++v) n += std::abs((t.row(v).transpose() - kCenter).norm() - kRadius) > 1.0;
    return n;
  };
  RecordProperty("raw_outliers", outliers(a.targets));
  RecordProperty("regularised_outliers", outliers(b.targets));
  EXPECT_LT(outliers(b.targets), outliers(a.targets));
  // Away from the cap the smoothing keeps the targets on the edge.
  for (int v = 0; v < s.positions.rows(); ++v) {
    const bool farFromCap =
        (s.positions.row(v).transpose() - kCenter).normalized().dot(axis) < std::cos(30.0 * kDegree);
    const double err = std::abs((b.targets.row(v).transpose() - kCenter).norm() - kRadius);
    EXPECT_TRUE(!farFromCap || err < 0.6) << "vertex " << v << " error " << err;
  }
  // Raw residuals are recorded before smoothing; regularisation does not change the scores.
  EXPECT_TRUE(a.residual.isApprox(b.residual));
  EXPECT_TRUE(a.scores.isApprox(b.scores));
}

TEST(ImageForcesRobustness, VerticesOutsideTheImageGetNoForce) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  Sphere s = makeSphere(kRadius, 1);
  s.positions.array().rowwise() += Eigen::Array3d(500, -400, 300).transpose();  // far outside
  s.normals.row(0).setZero();                                                   // and a degenerate normal
  for (TargetMode mode : {TargetMode::Gradient, TargetMode::Profile}) {
    TargetSearchOptions opts;
    opts.mode = mode;
    const LearnedProfiles lp = learnProfiles(f, s.positions, s.normals, opts, image.grid);
    EXPECT_TRUE(lp.profiles.allFinite());
    const TargetSearchResult res =
        searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside, image.grid, &lp);
    ASSERT_TRUE(allFinite(res));
    EXPECT_EQ(res.scores.maxCoeff(), 0.0);
    EXPECT_EQ(res.targets, s.positions);
    EXPECT_EQ(res.residual.maxCoeff(), 0.0);
  }
}

TEST(ImageForcesRobustness, SearchLinesLeavingTheImageGetNoTarget) {
  // The ball's image cut to ±26 mm: lines from r = 22 mm reaching 8 mm outward leave the image near the faces of the
  // cube and stay inside toward its corners. A line that leaves gets no target (the edge found on its inner part
  // could be a different edge than the one beyond the image); a line inside finds the ball.
  const ImageF image = ballImage({1.2, 1.2, 3.0}, 26, 200.f, 800.f);
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere truth = makeSphere(kRadius, 3), start = makeSphere(22.0, 3);
  const Grid& g = image.grid;
  // Distance (voxels) by which a point lies inside the voxel-centre box (negative: outside).
  auto depth = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d v = g.toVoxel(p);
    double d = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) d = std::min({d, v[a], g.dims[a] - 1 - v[a]});
    return d;
  };
  for (TargetMode mode : {TargetMode::Gradient, TargetMode::Profile}) {
    SCOPED_TRACE(mode == TargetMode::Gradient ? "gradient" : "profile");
    TargetSearchOptions opts;
    opts.mode = mode;
    opts.rangeMm = 8;
    opts.stepMm = 0.5;  // 16 steps: leaving the image counts over the whole range
    opts.profileHalfLengthMm = 3;
    opts.regularisationRings = 0;
    const LearnedProfiles lp = learnProfiles(f, truth.positions, truth.normals, opts, g);
    const TargetSearchResult res =
        searchTargets(f, start.positions, start.normals, start.neighbors, opts, Polarity::DarkInside, g, &lp);
    ASSERT_TRUE(allFinite(res));
    // The line's candidate positions reach ±range (samples a window needs beyond them do not count).
    const double reach = opts.rangeMm;
    int leaving = 0, inside = 0;
    for (int v = 0; v < start.positions.rows(); ++v) {
      const Eigen::Vector3d p = start.positions.row(v).transpose(), n = start.normals.row(v).transpose().normalized();
      const double outer = depth(p + reach * n), inner = depth(p - reach * n);
      if (outer < -0.1) {  // the line leaves the image outward
        ++leaving;
        EXPECT_EQ(res.scores[v], 0.0) << "vertex " << v;
        EXPECT_EQ(res.targets.row(v), start.positions.row(v)) << "vertex " << v;
      } else if (outer > 0.1 && inner > 0.1) {
        ++inside;
        EXPECT_GT(res.scores[v], 0.0) << "vertex " << v;
        EXPECT_LT(std::abs((res.targets.row(v).transpose() - kCenter).norm() - kRadius), 0.6) << "vertex " << v;
      }
    }
    RecordProperty(std::string(mode == TargetMode::Gradient ? "gradient" : "profile") + "_leaving_inside",
                   std::to_string(leaving) + "/" + std::to_string(inside));
    EXPECT_GT(leaving, start.positions.rows() / 10);
    EXPECT_GT(inside, start.positions.rows() / 10);
  }
}

TEST(ImageForcesRobustness, ConstantImageGivesNoForce) {
  const ImageF image = makeImage({1.2, 1.2, 3.0}, {10, -5, 20}, 30, [](const Eigen::Vector3d&) { return 350.0; });
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  EXPECT_TRUE(std::all_of(f.smoothed.data.begin(), f.smoothed.data.end(), [](float v) { return std::isfinite(v); }));
  const Sphere s = makeSphere(kRadius, 2);
  for (TargetMode mode : {TargetMode::Gradient, TargetMode::Profile}) {
    TargetSearchOptions opts;
    opts.mode = mode;
    const LearnedProfiles lp = learnProfiles(f, s.positions, s.normals, opts, image.grid);
    EXPECT_EQ(lp.profiles.cwiseAbs().maxCoeff(), 0.0);  // flat profiles → zeros
    for (Polarity p : {Polarity::DarkInside, Polarity::BrightInside}) {
      const TargetSearchResult res = searchTargets(f, s.positions, s.normals, s.neighbors, opts, p, image.grid, &lp);
      ASSERT_TRUE(allFinite(res));
      EXPECT_EQ(res.scores.maxCoeff(), 0.0);
      EXPECT_EQ(res.targets, s.positions);
    }
  }
}

TEST(ImageForcesGradient, CtBallAtThreeMillimetresIsotropic) {
  const ImageF image = ballImage({3.0, 3.0, 3.0}, 42, 1200.f, 40.f, 1.0);
  expectEdgeFound(image, Polarity::BrightInside, 3.0, 0.75);
}

// CT-like bone at 1 mm: a 2 mm cortical shell (1000) around marrow (100) in muscle (40), outer surface r = 20 mm. Seen
// at a coarse σ = 3 mm the shell's outer edge lies about 1.5 mm too far out (a blurred thin shell is a bump, whose
// falling side is at its centre + ~σ); edge focusing relocates each coarse target to the σ = 0.5 mm edge next to it.
TEST(ImageForcesGradient, EdgeFocusingRemovesTheCoarseScaleShiftOfAThinShell) {
  const ImageF image = makeImage({1.0, 1.0, 1.0}, {10, -5, 20}, 30, [](const Eigen::Vector3d& p) {
    const double r = (p - kCenter).norm();
    return r < kRadius - 2 ? 100.0 : r < kRadius ? 1000.0 : 40.0;
  });
  const ImageFeatures coarse = computeImageFeatures(image, 3.0), fine = computeImageFeatures(image, 0.5);
  TargetSearchOptions opts;
  opts.rangeMm = 6;
  opts.regularisationRings = 0;
  for (double r0 : {18.5, 20.0, 22.0}) {
    SCOPED_TRACE("start radius " + std::to_string(r0));
    const Sphere s = makeSphere(r0);
    const TargetSearchResult blurred =
        searchTargets(coarse, s.positions, s.normals, s.neighbors, opts, Polarity::BrightInside, image.grid);
    const TargetSearchResult focused = searchTargets(coarse, s.positions, s.normals, s.neighbors, opts,
                                                     Polarity::BrightInside, image.grid, nullptr, &fine);
    ASSERT_TRUE(allFinite(focused));
    const RadialError before = radialError(blurred.targets), after = radialError(focused.targets);
    ::testing::Test::RecordProperty("coarse_mean_error_r" + std::to_string(static_cast<int>(r0 * 10)),
                                    std::to_string(before.mean));
    ::testing::Test::RecordProperty("focused_mean_error_r" + std::to_string(static_cast<int>(r0 * 10)),
                                    std::to_string(after.mean));
    // Where the fine scale alone puts the edge (within its ±6 mm, from a start this close).
    const RadialError fineAlone = radialError(
        searchTargets(fine, s.positions, s.normals, s.neighbors, opts, Polarity::BrightInside, image.grid).targets);
    ::testing::Test::RecordProperty("fine_mean_error_r" + std::to_string(static_cast<int>(r0 * 10)),
                                    std::to_string(fineAlone.mean));
    EXPECT_GT(before.mean, 1.0);  // the shift this is about
    EXPECT_NEAR(after.mean, fineAlone.mean, 0.05);
    EXPECT_LT(std::abs(after.mean), 0.3);
    EXPECT_LT(after.maxAbs, 0.6);
    EXPECT_EQ((focused.scores - blurred.scores).cwiseAbs().maxCoeff(), 0.0);  // the coarse scale still decides
  }
  // Focusing needs a finer scale: with the same scale (or a coarser one) the search is unchanged.
  const Sphere s = makeSphere(20.0);
  const TargetSearchResult same = searchTargets(coarse, s.positions, s.normals, s.neighbors, opts,
                                                Polarity::BrightInside, image.grid, nullptr, &coarse);
  const TargetSearchResult plain =
      searchTargets(coarse, s.positions, s.normals, s.neighbors, opts, Polarity::BrightInside, image.grid);
  EXPECT_EQ((same.targets - plain.targets).cwiseAbs().maxCoeff(), 0.0);
}

// CT-like bone seen in its surroundings: bone (300) to r = 20 mm, a 4 mm muscle layer (100), then fat (−150). The
// muscle–fat edge at r = 24 mm falls further (250) than the bone's own edge (200) and has its polarity, so from a
// surface 2.5 mm out the strongest edge is the wrong one. The edge level, estimated where the template lies (r = 20
// mm), is about midway between bone and muscle: the muscle–fat edge stays below it and no longer counts.
TEST(ImageForcesGradient, EdgeLevelIgnoresAStrongerEdgeOfAnotherBoundary) {
  const ImageF image = makeImage({1.0, 1.0, 1.0}, {10, -5, 20}, 30, [](const Eigen::Vector3d& p) {
    const double r = (p - kCenter).norm();
    return r < kRadius ? 300.0 : r < kRadius + 4 ? 100.0 : -150.0;
  });
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere at = makeSphere(kRadius);
  const double level = estimateEdgeLevel(f, at.positions, at.normals);
  // Intensities are normalised (1–99 %) to [0, 1]: bone 1, muscle ≈ 0.56, fat 0; the level sits between bone and
  // muscle.
  const double bone = f.sample(kCenter).value(),
               muscle = f.sample(kCenter + Eigen::Vector3d(kRadius + 1.5, 0, 0)).value();
  EXPECT_GT(level, muscle + 0.1 * (bone - muscle));
  EXPECT_LT(level, bone - 0.1 * (bone - muscle));
  TargetSearchOptions opts;
  opts.rangeMm = 5;
  opts.regularisationRings = 0;
  const Sphere out = makeSphere(kRadius + 2.5);
  const TargetSearchResult any =
      searchTargets(f, out.positions, out.normals, out.neighbors, opts, Polarity::BrightInside, image.grid);
  opts.edgeLevel = level;
  const TargetSearchResult crossing =
      searchTargets(f, out.positions, out.normals, out.neighbors, opts, Polarity::BrightInside, image.grid);
  ASSERT_TRUE(allFinite(crossing));
  const RadialError without = radialError(any.targets), with = radialError(crossing.targets);
  ::testing::Test::RecordProperty("mean_error_without_level", std::to_string(without.mean));
  ::testing::Test::RecordProperty("mean_error_with_level", std::to_string(with.mean));
  EXPECT_GT(without.mean, 2.5);  // the muscle–fat edge
  EXPECT_GT(crossing.scores.minCoeff(), 0.0);
  EXPECT_LT(std::abs(with.mean), 0.2);
  EXPECT_LT(with.maxAbs, 0.6);
  // From inside (r = 18 mm) both find the bone's edge: the level only removes edges, it moves none.
  const Sphere in = makeSphere(kRadius - 2);
  EXPECT_LT(std::abs(radialError(searchTargets(f, in.positions, in.normals, in.neighbors, opts, Polarity::BrightInside,
                                               image.grid)
                                     .targets)
                         .mean),
            0.2);
  // A level no edge crosses leaves no target.
  opts.edgeLevel = bone + 1;
  EXPECT_EQ(searchTargets(f, out.positions, out.normals, out.neighbors, opts, Polarity::BrightInside, image.grid)
                .scores.maxCoeff(),
            0.0);
}

TEST(ImageForcesGradient, DefaultsFollowTheVoxelSize) {
  // On a grid twice as coarse the default range doubles: an edge 6 mm away is found on 2.4 mm voxels.
  const ImageF image = ballImage({2.4, 2.4, 2.4}, 42, 200.f, 800.f);
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere s = makeSphere(26.0, 2);
  const TargetSearchResult res =
      searchTargets(f, s.positions, s.normals, s.neighbors, {}, Polarity::DarkInside, image.grid);
  EXPECT_GT(res.scores.minCoeff(), 0.0);
  EXPECT_LT(radialError(res.targets).maxAbs, 0.6);
  TargetSearchOptions shortRange;
  shortRange.rangeMm = 4.0;  // explicit: the edge is out of reach, targets stay within the range
  shortRange.regularisationRings = 0;
  const TargetSearchResult near =
      searchTargets(f, s.positions, s.normals, s.neighbors, shortRange, Polarity::DarkInside, image.grid);
  EXPECT_LE(near.residual.maxCoeff(), 4.0 + 1e-9);
  EXPECT_GT(radialError(near.targets).meanAbs, 1.5);
}

// Many vertices (BM_TargetSearch in bench/segment_bench.cpp times the search on the bundled femur).
TEST(ImageForcesGradient, ManyVerticesFindTheEdge) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere s = makeSphere(22.0, 4);  // 5120 vertices, 81 samples each
  const TargetSearchResult res =
      searchTargets(f, s.positions, s.normals, s.neighbors, {}, Polarity::DarkInside, image.grid);
  const RadialError e = radialError(res.targets);
  EXPECT_LT(std::abs(e.mean), 0.15);
  EXPECT_LT(e.maxAbs, 0.6);
}

TEST(ImageForcesReuse, AVertexThatBarelyMovedKeepsItsTargetPoint) {
  const ImageF image = darkBall();
  const ImageFeatures f = computeImageFeatures(image, 1.0);
  const Sphere s = makeSphere(23.0);
  const Eigen::Index nv = s.positions.rows();
  TargetSearchOptions opts;
  opts.regularisationRings = 0;  // the raw offsets, as kept
  SearchReuse reuse;
  reuse.moveMm = 0.12;
  reuse.turnDegrees = 2;

  // The first search searches every vertex and answers as a search without a record.
  const TargetSearchResult first = searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside,
                                                 image.grid, nullptr, nullptr, &reuse);
  const TargetSearchResult plain =
      searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside, image.grid);
  EXPECT_EQ(reuse.searched, nv);
  EXPECT_EQ(reuse.reused, 0);
  EXPECT_TRUE(first.targets == plain.targets);
  EXPECT_TRUE(first.scores == plain.scores);

  // Even vertices move 0.05 mm along their normal (kept), odd ones 0.5 mm (searched again).
  Sphere moved = s;
  for (Eigen::Index v = 0; v < nv; ++v) moved.positions.row(v) += (v % 2 == 0 ? 0.05 : 0.5) * s.normals.row(v);
  const TargetSearchResult second = searchTargets(f, moved.positions, moved.normals, moved.neighbors, opts,
                                                  Polarity::DarkInside, image.grid, nullptr, nullptr, &reuse);
  const TargetSearchResult fresh =
      searchTargets(f, moved.positions, moved.normals, moved.neighbors, opts, Polarity::DarkInside, image.grid);
  EXPECT_EQ(reuse.reused, (nv + 1) / 2);
  EXPECT_EQ(reuse.searched, nv + nv / 2);
  double worst = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (v % 2 == 0) {
      // The same target point, its offset measured from where the vertex is now.
      EXPECT_LT((second.targets.row(v) - first.targets.row(v)).norm(), 1e-9) << "vertex " << v;
      EXPECT_NEAR(second.offsets[v], first.offsets[v] - 0.05, 1e-9);
      worst = std::max(worst, (second.targets.row(v) - fresh.targets.row(v)).norm());
    } else {
      EXPECT_TRUE(second.targets.row(v) == fresh.targets.row(v)) << "vertex " << v;
    }
  }
  // What keeping costs: the kept targets lie within a tenth of a millimetre of a new search's.
  EXPECT_LT(worst, 0.1);

  // A normal turned by 5 degrees is searched again even where the vertex has not moved.
  Sphere turned = moved;
  const Eigen::AngleAxisd turn(5 * kDegree, Eigen::Vector3d::UnitZ());
  for (Eigen::Index v = 0; v < nv; ++v)
    turned.normals.row(v) = (turn * Eigen::Vector3d(moved.normals.row(v).transpose())).transpose();
  const long before = reuse.reused;
  searchTargets(f, turned.positions, turned.normals, turned.neighbors, opts, Polarity::DarkInside, image.grid, nullptr,
                nullptr, &reuse);
  // Only normals (nearly) along the turn's axis stay within 2 degrees.
  long alongAxis = 0;
  for (Eigen::Index v = 0; v < nv; ++v)
    if (moved.normals.row(v).dot(turned.normals.row(v)) >= std::cos(2 * kDegree)) ++alongAxis;
  EXPECT_EQ(reuse.reused - before, alongAxis);
  EXPECT_LT(alongAxis, nv / 10);

  // Without a tolerance nothing is kept.
  SearchReuse off;
  searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside, image.grid, nullptr, nullptr, &off);
  searchTargets(f, s.positions, s.normals, s.neighbors, opts, Polarity::DarkInside, image.grid, nullptr, nullptr, &off);
  EXPECT_EQ(off.reused, 0);
}

}  // namespace
}  // namespace msk
