// Property tests of the segmentation pipeline on synthetic images with known answers.
#include "msk/segmentation/segmenter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/grid.h"
#include "msk/segmentation/segment_report.h"
#include "msk/test/volumes.h"

namespace {

msk::Grid cubeGrid(double spacing, double halfWidthMm, const Eigen::Vector3d& rotDeg = Eigen::Vector3d::Zero()) {
  msk::Grid g;
  const int n = static_cast<int>(std::ceil(2 * halfWidthMm / spacing));
  g.dims = {n, n, n};
  g.spacing = Eigen::Vector3d::Constant(spacing);
  g.direction = msk::Grid::rotationXYZ(rotDeg);
  g.origin = -g.direction * g.spacing.cwiseProduct(Eigen::Vector3d::Constant((n - 1) / 2.0));
  return g;
}

/// The ball most tests segment: radius 20 mm about a point off the grid's centre, 800 inside and 200 outside, on a cube
/// grid of 1 mm voxels 64 mm wide turned by `rotDeg`.
const double kBallRadius = 20.0;
const Eigen::Vector3d kBallCentre(0.7, -0.4, 0.3);
msk::ImageF offCentreBall(const Eigen::Vector3d& rotDeg = Eigen::Vector3d::Zero()) {
  return msk::test::ballImage(cubeGrid(1.0, 32, rotDeg), kBallCentre, kBallRadius, 200.f, 800.f);
}

msk::Scene oneObjectScene(const msk::TriangleMesh& templ, msk::ObjectKind kind = msk::ObjectKind::Generic) {
  msk::Scene s;
  msk::SceneObject o;
  o.name = "ball";
  o.label = 1;
  o.kind = kind;
  o.templ = templ;
  s.objects.push_back(o);
  return s;
}

double meanRadialError(const msk::TriangleMesh& m, const Eigen::Vector3d& c, double r, double* maxErr = nullptr) {
  double sum = 0, mx = 0;
  for (int i = 0; i < m.vertexCount(); ++i) {
    const double e = std::fabs((m.vertices.row(i).transpose() - c).norm() - r);
    sum += e;
    mx = std::max(mx, e);
  }
  if (maxErr) *maxErr = mx;
  return sum / m.vertexCount();
}

}  // namespace

// A simplex sphere started 3 mm inside or outside a ball converges to its radius within 0.25 voxel.
TEST(Segmenter, SphereConvergesToTheBallFromThreeMillimetres) {
  const double spacing = 1.0, r = kBallRadius;
  const Eigen::Vector3d& c = kBallCentre;
  const msk::ImageF img = offCentreBall({10, -5, 20});
  for (double start : {r - 3.0, r + 3.0}) {
    msk::SegmentOptions opts;
    const msk::SegmentationResult res = msk::segmentScene(img, oneObjectScene(msk::makeIcosphere(start, 3, c)), opts);
    double mx = 0;
    const double mean = meanRadialError(res.objects[0].mesh, c, r, &mx);
    EXPECT_LT(mean, 0.25 * spacing) << "start radius " << start;
    EXPECT_LT(mx, 1.0 * spacing) << "start radius " << start;
    EXPECT_EQ(msk::closedMeshProblem(res.objects[0].mesh), "");
  }
}

// The profile force with nothing to learn its profiles on ("profiles_from" unset) would learn them on the template
// where it starts, whose targets are then its own vertices: the object falls back to the gradient force with a warning
// naming it, and reaches the ball from 3 mm as the gradient force does. With a source it keeps the profile force.
TEST(Segmenter, ProfileForceWithoutAProfileSourceFallsBackToTheGradientWithAWarning) {
  const double r = kBallRadius;
  const Eigen::Vector3d& c = kBallCentre;
  const msk::ImageF img = offCentreBall();
  msk::Scene scene = oneObjectScene(msk::makeIcosphere(r + 3.0, 3, c));
  scene.objects[0].hasForce = true;
  scene.objects[0].force = scene.objects[0].model.imageForce = msk::TargetMode::Profile;
  std::vector<std::string> warnings;
  const msk::LogSink old = msk::log::setSink([&](msk::LogLevel l, const std::string& m) {
    if (l == msk::LogLevel::Warn) warnings.push_back(m);
  });
  const msk::SegmentationResult res = msk::segmentScene(img, scene, msk::SegmentOptions{});
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("ball"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("gradient"), std::string::npos) << warnings[0];
  EXPECT_EQ(res.objects[0].force, msk::TargetMode::Gradient);
  EXPECT_LT(meanRadialError(res.objects[0].mesh, c, r), 0.25);

  // With a source (here the identity: the template lies where its profiles are learned) no warning, profile force.
  warnings.clear();
  scene.objects[0].profileSource = Eigen::Matrix4d::Identity();
  const msk::SegmentationResult withSource = msk::segmentScene(img, scene, msk::SegmentOptions{});
  msk::log::setSink(old);
  EXPECT_TRUE(warnings.empty());
  EXPECT_EQ(withSource.objects[0].force, msk::TargetMode::Profile);
}

// A level's "converged" says whether the surface has settled: its mean net displacement per step over the last steps
// is below the tolerance. The largest single move of a step stays above the tolerance for good (vertices hop between
// neighbouring target samples), so it cannot say so. A run cut after 3 steps from 3 mm out has not settled; the
// default run has, on every level.
TEST(Segmenter, ConvergedMeansTheSurfaceHasSettled) {
  const double r = kBallRadius;
  const Eigen::Vector3d& c = kBallCentre;
  const msk::ImageF img = offCentreBall({10, -5, 20});
  const msk::Scene scene = oneObjectScene(msk::makeIcosphere(r + 3.0, 3, c));
  const msk::SegmentationResult full = msk::segmentScene(img, scene, msk::SegmentOptions{});
  for (const msk::LevelReport& l : full.objects[0].levels) {
    EXPECT_TRUE(l.converged) << "drift " << l.driftMmPerStep << " mm/step";
    if (!l.stoppedOnTolerance) {
      EXPECT_LT(l.driftMmPerStep, l.settleToleranceMm);
    }
    EXPECT_DOUBLE_EQ(l.settleToleranceMm, full.settings.toleranceMm);
  }
  msk::SegmentOptions cut;
  cut.evolution.maxStepsPerLevel = 3;
  const msk::SegmentationResult early = msk::segmentScene(img, scene, cut);
  const msk::LevelReport& coarse = early.objects[0].levels.front();
  EXPECT_FALSE(coarse.converged) << "drift " << coarse.driftMmPerStep << " mm/step";
  EXPECT_GT(coarse.driftMmPerStep, 0.1);
}

// A template already on the boundary of its own image stays put.
TEST(Segmenter, StaticTemplateInItsOwnImageMovesLessThanATenthOfAMillimetre) {
  const msk::Grid g = cubeGrid(1.0, 30);
  const Eigen::Vector3d axes(22, 16, 12);
  const msk::ImageF img = msk::test::ellipsoidImage(g, Eigen::Vector3d::Zero(), axes, 900.f, 100.f);
  msk::TriangleMesh templ = msk::makeIcosphere(1.0, 4);
  for (int i = 0; i < templ.vertexCount(); ++i)
    templ.vertices.row(i) = templ.vertices.row(i).cwiseProduct(axes.transpose());
  msk::SegmentOptions opts;
  const msk::SegmentationResult res = msk::segmentScene(img, oneObjectScene(templ), opts);
  const Eigen::VectorXd& disp = res.objects[0].mesh.pointData.at("displacement_mm");
  EXPECT_LT(disp.mean(), 0.1);
}

// Stiffness at the ends of its range stays stable: γ = 0 (no shape memory) and γ = 1 (full projection).
TEST(Segmenter, ExtremeInternalStiffnessStaysStable) {
  const msk::Grid g = cubeGrid(1.2, 30);
  const Eigen::Vector3d c(0.5, 0.2, -0.3);
  const msk::ImageF img = msk::test::ballImage(g, c, 18.0, 900.f, 150.f);
  for (double gamma : {0.0, 1e-12, 1.0}) {
    for (double image : {0.0, 1.0}) {
      msk::SegmentOptions opts;
      opts.shape.internalStiffness = gamma;
      opts.image.stiffness = image;
      const msk::SegmentationResult res = msk::segmentScene(img, oneObjectScene(msk::makeIcosphere(16.0, 3, c)), opts);
      const msk::TriangleMesh& m = res.objects[0].mesh;
      ASSERT_TRUE(m.vertices.allFinite());
      double mx = 0;
      const double mean = meanRadialError(m, c, image > 0 ? 18.0 : 16.0, &mx);
      if (image == 0.0)
        EXPECT_LT(mx, 0.5);  // no image force: the template barely moves
      else if (gamma > 0.5)
        EXPECT_LT(mean, 0.3);  // stiff shape memory still reaches the edge
      else
        EXPECT_LT(mean, 1.0);  // no memory: noisy but bounded
    }
  }
}

TEST(Segmenter, RefusesBadParametersAndNaNImages) {
  const msk::Grid g = cubeGrid(2.0, 10);
  msk::ImageF img(g, 1.f);
  const msk::Scene s = oneObjectScene(msk::makeIcosphere(5, 2));
  msk::SegmentOptions bad;
  bad.shape.internalStiffness = 1.5;
  EXPECT_THROW(msk::segmentScene(img, s, bad), msk::ParameterError);
  bad = {};
  bad.evolution.dt = -1;
  EXPECT_THROW(msk::segmentScene(img, s, bad), msk::ParameterError);
  bad = {};
  bad.image.muscleTargetStepEdges = -1;
  EXPECT_THROW(msk::segmentScene(img, s, bad), msk::ParameterError);
  bad = {};
  bad.image.reuseTargetVoxels = 1.5;
  EXPECT_THROW(msk::segmentScene(img, s, bad), msk::ParameterError);
  bad.image.reuseTargetVoxels = std::nan("");
  EXPECT_THROW(msk::segmentScene(img, s, bad), msk::ParameterError);
  img.data[5] = NAN;
  EXPECT_THROW(msk::segmentScene(img, s, {}), msk::Error);
  EXPECT_THROW(msk::parseQuality("ultra"), msk::ParameterError);
}

// An image with one value everywhere, or one the template does not lie in, is refused before any work: the problem
// says why and names the object; a template half out of the image is still accepted.
TEST(Segmenter, RefusesConstantImagesAndTemplatesOutsideTheImage) {
  const msk::Grid g = cubeGrid(2.0, 10);
  msk::ImageF img(g, 0.f);
  const msk::Scene s = oneObjectScene(msk::makeIcosphere(5, 2));
  EXPECT_NE(msk::imageProblem(img).find("every voxel is 0"), std::string::npos) << msk::imageProblem(img);
  EXPECT_THROW(msk::segmentScene(img, s, {}), msk::Error);
  img.data[7] = 1.f;
  EXPECT_EQ(msk::imageProblem(img), "");
  EXPECT_EQ(msk::templateShareInImage(g, s), std::vector<double>{1.0});
  EXPECT_EQ(msk::coverageProblem(g, s), "");

  msk::Scene far = oneObjectScene(msk::makeIcosphere(5, 2, {0, 0, 40}));
  EXPECT_EQ(msk::templateShareInImage(g, far), std::vector<double>{0.0});
  EXPECT_NE(msk::coverageProblem(g, far).find("ball: 0 % of its template lies inside the image"), std::string::npos)
      << msk::coverageProblem(g, far);
  EXPECT_THROW(msk::segmentScene(img, far, {}), msk::Error);

  const msk::Scene half = oneObjectScene(msk::makeIcosphere(5, 2, {0, 0, 10}));  // centred on the image's face
  const double share = msk::templateShareInImage(g, half)[0];
  EXPECT_GT(share, 0.4);
  EXPECT_LT(share, 0.6);
  EXPECT_EQ(msk::coverageProblem(g, half), "");
}

// The --quality presets map to the settings docs/method.md and `mskseg segment --help` document, and explicit scheme
// settings override them; bad scheme settings are refused.
TEST(Segmenter, QualityPresetsMapToTheDocumentedSettings) {
  msk::Grid g;
  g.spacing = Eigen::Vector3d(1.0, 2.0, 4.0);  // tolerance is a share of the smallest spacing
  struct Expected {
    msk::Quality q;
    int levels, steps;
    double tolerance;
    msk::Scheme scheme;
    int substeps, iterations;
    double sigmaFine;  // × the smallest spacing
  };
  const Expected presets[] = {{msk::Quality::Fast, 1, 15, 0.04, msk::Scheme::Xpbd, 2, 2, 0.5},
                              {msk::Quality::Balanced, 2, 50, 0.02, msk::Scheme::GaussSeidel, 1, 1, 0.5},
                              {msk::Quality::Accurate, 3, 200, 0.004, msk::Scheme::Xpbd, 2, 2, 0.25}};
  for (const Expected& e : presets) {
    msk::SegmentOptions o;
    o.evolution.quality = e.q;
    const msk::ResolvedSettings s = msk::resolveSettings(o, g);
    EXPECT_EQ(s.levels, e.levels) << msk::qualityName(e.q);
    EXPECT_EQ(s.maxStepsPerLevel, e.steps) << msk::qualityName(e.q);
    EXPECT_DOUBLE_EQ(s.toleranceMm, e.tolerance) << msk::qualityName(e.q);
    EXPECT_EQ(s.solver.scheme, e.scheme) << msk::qualityName(e.q);
    EXPECT_EQ(s.solver.substeps, e.substeps) << msk::qualityName(e.q);
    EXPECT_EQ(s.solver.iterations, e.iterations) << msk::qualityName(e.q);
    EXPECT_EQ(s.sigmaMm.size(), static_cast<size_t>(e.levels));
    EXPECT_DOUBLE_EQ(s.sigmaMm.back(), e.sigmaFine * 1.0) << msk::qualityName(e.q);
    msk::SegmentationResult r;
    r.settings = s;
    const msk::Json j = msk::settingsJson(o, r);
    EXPECT_DOUBLE_EQ(j.at("sigma_fine_voxels").get<double>(), e.sigmaFine);
    EXPECT_EQ(j.at("scheme").get<std::string>(), msk::schemeName(e.scheme));
    EXPECT_EQ(j.at("substeps").get<int>(), e.substeps);
    EXPECT_EQ(j.at("iterations").get<int>(), e.iterations);
    EXPECT_EQ(j.at("threads").get<int>(), 1);
  }
  // XPBD in mass-relative units, k = 4.
  msk::SegmentOptions o;
  o.evolution.quality = msk::Quality::Accurate;
  EXPECT_EQ(msk::resolveSettings(o, g).solver.xpbdStiffness, msk::XpbdStiffness::MassRelative);
  EXPECT_DOUBLE_EQ(msk::resolveSettings(o, g).solver.stiffness, 4.0);
  // Explicit settings win over the preset.
  o.evolution.scheme = msk::Scheme::Implicit;
  o.evolution.substeps = 3;
  o.evolution.iterations = 5;
  o.evolution.threads = 2;
  o.evolution.levels = 2;
  o.image.sigmaFine = 0.7;
  const msk::ResolvedSettings s = msk::resolveSettings(o, g);
  EXPECT_DOUBLE_EQ(s.sigmaMm.back(), 0.7);
  EXPECT_EQ(s.solver.scheme, msk::Scheme::Implicit);
  EXPECT_EQ(s.solver.substeps, 3);
  EXPECT_EQ(s.solver.iterations, 5);
  EXPECT_EQ(s.solver.threads, 2);
  EXPECT_EQ(s.levels, 2);
  EXPECT_EQ(s.maxStepsPerLevel, 200);
  // Another scheme than the preset's brings the substeps × iterations it needs.
  msk::SegmentOptions other;
  other.evolution.scheme = msk::Scheme::Explicit;
  EXPECT_EQ(msk::resolveSettings(other, g).solver.substeps, 4);
  other.evolution.scheme = msk::Scheme::Jacobi;
  EXPECT_EQ(msk::resolveSettings(other, g).solver.iterations, 2);
  EXPECT_DOUBLE_EQ(msk::resolveSettings(other, g).solver.omega, 1.5);
  // Time step, damping and drag reach the solver whatever the scheme.
  msk::SegmentOptions damped;
  damped.evolution.drag = 0.25;
  damped.evolution.damping = 0.75;
  damped.evolution.dt = 2.0;
  EXPECT_DOUBLE_EQ(msk::resolveSettings(damped, g).solver.drag, 0.25);
  EXPECT_DOUBLE_EQ(msk::resolveSettings(damped, g).solver.damping, 0.75);
  EXPECT_DOUBLE_EQ(msk::resolveSettings(damped, g).solver.dt, 2.0);
  // Bad scheme settings are refused before any work.
  const msk::Grid cube = cubeGrid(2.0, 10);
  const msk::ImageF img(cube, 1.f);
  const msk::Scene scene = oneObjectScene(msk::makeIcosphere(5, 2));
  msk::SegmentOptions bad;
  bad.evolution.threads = -1;
  EXPECT_THROW(msk::segmentScene(img, scene, bad), msk::ParameterError);
  bad = {};
  bad.evolution.jacobiOmega = 2.5;
  bad.evolution.scheme = msk::Scheme::Jacobi;
  EXPECT_THROW(msk::segmentScene(img, scene, bad), msk::ParameterError);
  bad = {};
  bad.evolution.xpbdStiffness = -1;
  EXPECT_THROW(msk::segmentScene(img, scene, bad), msk::ParameterError);
}

// A volumetric object (3-simplex model coupled to the surface: the surface's simplex vertices are the model's ghosts)
// keeps its volume within 2 % while the image moves it 3 mm into place, and is built only when its model asks.
TEST(Segmenter, VolumeModelKeepsTheVolumeWhileTheImageMovesIt) {
  const msk::Grid g = cubeGrid(1.0, 30);
  const Eigen::Vector3d axes(20, 14, 11);
  const msk::ImageF img = msk::test::ellipsoidImage(g, Eigen::Vector3d::Zero(), axes, 900.f, 100.f);
  msk::TriangleMesh templ = msk::makeIcosphere(1.0, 3);
  for (int i = 0; i < templ.vertexCount(); ++i)
    templ.vertices.row(i) = templ.vertices.row(i).cwiseProduct(axes.transpose()) + Eigen::RowVector3d(3, -2, 1);
  msk::Scene scene = oneObjectScene(templ, msk::ObjectKind::Muscle);
  msk::SegmentOptions opts;
  const msk::SegmentationResult plain = msk::segmentScene(img, scene, opts);
  EXPECT_EQ(plain.volumeModelsBuilt, 0);
  EXPECT_EQ(plain.objects[0].volumeMesh.tetCount(), 0);
  scene.objects[0].model.volumetric = true;
  const msk::SegmentationResult res = msk::segmentScene(img, scene, opts);
  ASSERT_EQ(res.volumeModelsBuilt, 1);
  const msk::ObjectResult& o = res.objects[0];
  ASSERT_GT(o.volumeMesh.tetCount(), 100);
  EXPECT_EQ(msk::tetMeshProblem(o.volumeMesh), "");
  const double change = o.volumeModelMm3 / o.volumeModelTemplateMm3 - 1.0;
  // The surface reached the ellipsoid (which has the template's volume), as without the volume model.
  const Eigen::Vector3d centre = o.mesh.vertices.colwise().mean();
  EXPECT_LT(std::abs(change), 0.02);
  EXPECT_LT(centre.norm(), 0.5);  // moved the 3.7 mm back to the ellipsoid's centre
  EXPECT_NEAR(o.volumeMm3, 4.0 / 3.0 * M_PI * axes.prod(), 0.03 * 4.0 / 3.0 * M_PI * axes.prod());
  EXPECT_EQ(msk::closedMeshProblem(o.mesh), "");
}

// Collision detection (its sets) and the image search (its objects, and ranges of an object's vertices with the
// threads the objects leave free) run on --threads threads; the result is the same as on one, bit for bit, for two
// threads and for more threads than objects (5 threads, 2 objects: each object's search on 2).
TEST(Segmenter, ThreadsGiveIdenticalMeshes) {
  const msk::Grid g = cubeGrid(1.0, 30);
  const msk::ImageF img =
      msk::test::ellipsoidImage(g, Eigen::Vector3d(-9, 0, 0), Eigen::Vector3d(10, 12, 12), 900.f, 100.f);
  msk::Scene scene = oneObjectScene(msk::makeIcosphere(10, 3, {-7, 0, 0}));
  msk::SceneObject other = scene.objects[0];
  other.name = "other";
  other.label = 2;
  other.templ = msk::makeIcosphere(10, 3, {11, 0, 0});
  scene.objects.push_back(other);
  msk::CollisionPair pair;
  pair.a = 0;
  pair.b = 1;
  scene.collisions.push_back(pair);
  msk::SegmentOptions one;
  const msk::SegmentationResult a = msk::segmentScene(img, scene, one);
  ASSERT_EQ(a.collisionSetsBuilt, 2 * a.settings.levels);
  for (int threads : {2, 5}) {
    msk::SegmentOptions more;
    more.evolution.threads = threads;
    const msk::SegmentationResult b = msk::segmentScene(img, scene, more);
    for (size_t i = 0; i < 2; ++i)
      EXPECT_EQ((a.objects[i].mesh.vertices - b.objects[i].mesh.vertices).cwiseAbs().maxCoeff(), 0.0) << threads;
    EXPECT_EQ(a.overlapVoxels, b.overlapVoxels);
  }
}

// The refinement pass (object model "refine"): a template whose shape differs from the object's (an ellipsoid for a
// ball) keeps part of its shape through the levels (shape memory and prior hold it); the refinement pass takes the
// converged surface as the reference and the image's own edges finish it. An object that does not refine stays
// exactly where the levels left it.
TEST(Segmenter, RefinementPassFinishesTheRefiningObjectAndLeavesTheOthers) {
  const msk::Grid g = cubeGrid(1.0, 36);
  const Eigen::Vector3d ca(-18, 0, 0), cb(18, 0, 0);
  const double r = 12.0;
  const msk::ImageF img = msk::test::partialVolumeImage(
      g, [&](const Eigen::Vector3d& x) { return (x - ca).norm() <= r || (x - cb).norm() <= r; }, 900.f, 100.f);
  msk::Scene scene = oneObjectScene(msk::makeIcosphere(1.0, 3, Eigen::Vector3d::Zero()));
  msk::TriangleMesh& ellipsoid = scene.objects[0].templ;
  for (int i = 0; i < ellipsoid.vertexCount(); ++i)
    ellipsoid.vertices.row(i) = ellipsoid.vertices.row(i).cwiseProduct(Eigen::RowVector3d(15, 10, 11)) + ca.transpose();
  msk::SceneObject other = scene.objects[0];
  other.name = "other";
  other.label = 2;
  other.templ = msk::makeIcosphere(14.0, 3, cb);
  scene.objects.push_back(other);
  const msk::SegmentOptions opts;
  const msk::SegmentationResult plain = msk::segmentScene(img, scene, opts);
  scene.objects[0].model.refine = true;
  const msk::SegmentationResult refined = msk::segmentScene(img, scene, opts);
  double maxPlain = 0, maxRefined = 0;
  const double errPlain = meanRadialError(plain.objects[0].mesh, ca, r, &maxPlain);
  const double errRefined = meanRadialError(refined.objects[0].mesh, ca, r, &maxRefined);
  EXPECT_LT(errRefined, 0.5 * errPlain);
  EXPECT_LT(maxRefined, maxPlain);
  ASSERT_EQ(refined.objects[0].levels.size(), plain.objects[0].levels.size() + 1);
  EXPECT_TRUE(refined.objects[0].levels.back().refinement);
  EXPECT_FALSE(plain.objects[0].levels.back().refinement);
  // The other object: not refined, not moved.
  EXPECT_EQ(refined.objects[1].levels.size(), plain.objects[1].levels.size());
  EXPECT_EQ((refined.objects[1].mesh.vertices - plain.objects[1].mesh.vertices).cwiseAbs().maxCoeff(), 0.0);
}

// Coarse levels only (EvolutionOptions::coarseOnly): the coarse level evolves, the finest is entered (its surface
// carries the coarse level's displacement, at the finest resolution) and not evolved, and nothing is refined. From 3 mm
// outside a ball the surface ends near it at the template's own resolution, at a fraction of the steps, and no labels
// are rasterised; with one level the option changes nothing.
TEST(Segmenter, CoarseLevelsOnlyEvolveTheCoarseLevelAndCarryItToTheFinest) {
  const double r = kBallRadius;
  const Eigen::Vector3d& c = kBallCentre;
  const msk::ImageF img = offCentreBall();
  msk::Scene scene = oneObjectScene(msk::makeIcosphere(r + 3.0, 3, c));
  scene.objects[0].model.refine = true;
  msk::SegmentOptions opts;
  const msk::SegmentationResult full = msk::segmentScene(img, scene, opts);
  opts.evolution.coarseOnly = true;
  const msk::SegmentationResult coarse = msk::segmentScene(img, scene, opts);
  ASSERT_EQ(full.objects[0].levels.size(), 3u);  // two levels and the refinement
  ASSERT_EQ(coarse.objects[0].levels.size(), 2u);
  EXPECT_GT(coarse.objects[0].levels[0].steps, 0);
  EXPECT_EQ(coarse.objects[0].levels[0].steps, full.objects[0].levels[0].steps);
  EXPECT_EQ(coarse.objects[0].levels[1].steps, 0);
  EXPECT_EQ(coarse.objects[0].mesh.vertexCount(), full.objects[0].mesh.vertexCount());
  const double coarseErr = meanRadialError(coarse.objects[0].mesh, c, r);
  EXPECT_LT(coarseErr, 1.0);  // from 3 mm
  EXPECT_GT(coarseErr, meanRadialError(full.objects[0].mesh, c, r));
  // A look, not an output: no labels; the quality figures measured.
  EXPECT_TRUE(coarse.labels.data.empty());
  EXPECT_FALSE(full.labels.data.empty());
  EXPECT_GT(coarse.objects[0].quality.edgeShare, 0.0);
  opts.evolution.quality = msk::Quality::Fast;  // one level
  const msk::SegmentationResult oneLevel = msk::segmentScene(img, scene, opts);
  opts.evolution.coarseOnly = false;
  const msk::SegmentationResult oneLevelFull = msk::segmentScene(img, scene, opts);
  EXPECT_EQ((oneLevel.objects[0].mesh.vertices - oneLevelFull.objects[0].mesh.vertices).cwiseAbs().maxCoeff(), 0.0);
}

// A feature store kept between runs on one image: the second run computes no image features (it reads the first's)
// and gives the same surfaces as a run without the store.
TEST(Segmenter, AFeatureStoreServesTheNextRunOnTheSameImage) {
  const double r = kBallRadius;
  const Eigen::Vector3d& c = kBallCentre;
  const msk::ImageF img = offCentreBall();
  const msk::Scene near = oneObjectScene(msk::makeIcosphere(r + 2.0, 3, c));
  const msk::Scene far = oneObjectScene(msk::makeIcosphere(r - 3.0, 3, c));
  const msk::SegmentOptions opts;
  msk::FeatureStore store;
  const msk::SegmentationResult first = msk::segmentScene(img, near, opts, {}, &store);
  const msk::SegmentationResult second = msk::segmentScene(img, far, opts, {}, &store);
  const msk::SegmentationResult alone = msk::segmentScene(img, far, opts);
  EXPECT_GT(first.secondsPerStage.at("features"), 0.0);
  EXPECT_EQ(second.secondsPerStage.at("features"), 0.0);
  EXPECT_GT(alone.secondsPerStage.at("features"), 0.0);
  EXPECT_EQ((second.objects[0].mesh.vertices - alone.objects[0].mesh.vertices).cwiseAbs().maxCoeff(), 0.0);
}
