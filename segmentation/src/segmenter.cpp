#include "msk/segmentation/segmenter.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>

#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/filters.h"
#include "msk/segmentation/quality_check.h"
#include "msk/segmentation/surface_quality.h"
#include "parallel_each.h"
#include "segment_stages.h"

namespace msk {

namespace {

using namespace detail;

/// Throws Error for an image or scene no run can use.
void checkInput(const ImageF& image, const Scene& scene) {
  const std::string problem = imageProblem(image);
  if (!problem.empty()) throw Error("image: " + problem);
  if (scene.objects.empty()) throw Error("scene has no objects");
  const std::string coverage = coverageProblem(image.grid, scene);
  if (!coverage.empty()) throw Error("image: " + coverage);
}

/// Refuses a run whose requested work is absurd before it starts: an estimate of its time from its vertex-steps (each
/// object's vertices at every level, ×4 fewer per coarser level, × the step cap), about 2 µs each at one substep and
/// one sweep and 0.1 µs more per further substep or sweep (measured on the bundled scene), against six hours.
void checkWorkload(const Scene& scene, const ResolvedSettings& rs) {
  constexpr double kSecondsPerVertexStep = 2e-6, kSecondsPerExtraSweep = 1e-7, kMaxSeconds = 6 * 3600;
  double vertices = 0;
  for (const SceneObject& o : scene.objects)
    for (int l = 0; l < rs.levels; ++l) vertices += o.templ.vertexCount() / std::pow(4.0, l);
  const double sweeps = static_cast<double>(rs.solver.substeps) * std::max(1, rs.solver.iterations);
  const double seconds =
      vertices * rs.maxStepsPerLevel * (kSecondsPerVertexStep + kSecondsPerExtraSweep * (sweeps - 1));
  if (seconds > kMaxSeconds)
    throw ParameterError("--steps/--substeps/--iterations",
                         std::to_string(rs.maxStepsPerLevel) + "/" + std::to_string(rs.solver.substeps) + "/" +
                             std::to_string(rs.solver.iterations),
                         "the run would take about " + std::to_string(static_cast<long long>(seconds / 3600)) +
                             " hours (" + std::to_string(static_cast<long long>(vertices)) +
                             " vertices over the levels); lower them");
}

/// The axis-first coarse stage of every object that asks for it, at the coarsest level `l`, each followed by the
/// level's sets again about the template the stage bent (same particle counts and places).
void runAxisFirstStages(std::vector<ObjectState>& objs, SegmentationResult& res, int l, const SegmentOptions& opts,
                        const ImageFeatures& feat, const Grid& grid) {
  for (ObjectState& st : objs) {
    if (!st.runsAxisFirst(opts)) continue;
    const auto ta = Clock::now();
    res.axisFirst.push_back(runAxisFirst(st, l, opts, res.settings, feat, grid));
    enterLevel(st, l, l, opts, feat, grid);
    buildAxisSets(st, opts);
    res.axisFirst.back().seconds = since(ta);
    res.secondsPerStage["axis-first"] += res.axisFirst.back().seconds;
  }
}

/// Every pass of the evolution, all objects stacked in one particle system (the ground for collision corrections
/// between declared pairs, which must move both partners and conserve momentum): the levels, coarsest first, then the
/// refinement pass at the finest level again if an object refines; in that pass the objects that do not refine stay
/// where they are (fixed, still collision partners). Returns the contact detection time, s.
double evolve(std::vector<ObjectState>& objs, SegmentationResult& res, const Scene& scene,
              const std::vector<PairContact>& contacts, const SegmentOptions& opts, FeatureCache& features,
              const Grid& grid, const ProgressFn& progress) {
  const ResolvedSettings& rs = res.settings;
  const int coarsest = rs.levels - 1;
  const bool anyRefines =
      std::any_of(objs.begin(), objs.end(), [&](const ObjectState& st) { return st.refines(opts); });
  const bool coarseOnly = opts.evolution.coarseOnly && rs.levels > 1;
  const int passes = coarseOnly ? rs.levels : rs.levels + (anyRefines ? 1 : 0);
  const int totalSteps = (coarseOnly ? rs.levels - 1 : passes) * rs.maxStepsPerLevel;  // the steps progress counts
  const int rampSteps = rs.levels * rs.maxStepsPerLevel;  // the prior's ramp spans the levels; refinement is at its end
  int stepsDone = 0;
  double detectSeconds = 0;
  for (int pass = 0; pass < passes; ++pass) {
    const bool refine = pass == rs.levels;
    const int l = refine ? 0 : coarsest - pass;
    const int order = coarsest - l;  // 0 for the coarsest level
    std::vector<char> fixed(objs.size(), 0);
    for (size_t i = 0; i < objs.size(); ++i) fixed[i] = refine && !objs[i].refines(opts);
    const double sigmaMm = refine ? opts.image.refineSigma * grid.spacing.minCoeff() : rs.sigmaMm[order];
    const ImageFeatures& feat = features.at(sigmaMm);
    const bool focusing = opts.image.edgeFocusing && order + 1 < rs.levels;
    const ImageFeatures* focus = focusing ? &features.at(rs.sigmaMm.back()) : nullptr;
    LevelSystem system(objs, l, coarsest, refine, fixed, opts, rs, feat, grid);
    if (pass == 0) {
      for (const ObjectState& st : objs) res.medialAxesBuilt += st.hasAxis() ? 1 : 0;
      runAxisFirstStages(objs, res, l, opts, feat, grid);
      for (const ObjectState& st : objs) res.volumeModelsBuilt += st.volume ? 1 : 0;
    }
    res.collisionSetsBuilt += system.assemble(scene, contacts, opts);
    Solver solver(rs.solver);
    solver.prepare(system.positions(), system.inverseMass());
    const std::string stage =
        refine ? std::string("refinement") : "level " + std::to_string(order + 1) + "/" + std::to_string(rs.levels);
    // Coarse levels only: the finest level is entered (its surface carries the coarser displacement), not evolved.
    LevelReport rep;
    rep.settleToleranceMm = rs.toleranceMm;
    if (!(coarseOnly && l == 0))
      rep = runSteps(objs, fixed, system, solver, opts, rs, feat, focus, grid, stepsDone, rampSteps, totalSteps, stage,
                     progress, detectSeconds);
    rep.sigmaMm = sigmaMm;
    rep.rangeMm = rs.rangeMm[order];
    rep.refinement = refine;
    stepsDone = (pass + 1) * rs.maxStepsPerLevel;
    if (pass + 1 == passes && system.hasContacts()) {
      // Clean-up: collision-only sweeps on the final positions, so no vertex is left inside a partner (the seed's
      // robust practice: position first).
      const auto tc = Clock::now();
      Points p = solver.positions();
      rep.cleanUpSweeps =
          system.cleanUpContacts(p, solver.inverseMass(), opts.collision.finalSweeps, scene, opts.evolution.threads);
      solver.reset(p, solver.inverseMass());
      detectSeconds += since(tc);
    }
    collectPass(objs, fixed, solver, l, order, rep);
    for (const auto& [family, s] : solver.secondsPerFamily()) res.secondsPerFamily[family] += s;
  }
  return detectSeconds;
}

}  // namespace

std::string imageProblem(const ImageF& image) {
  const std::string gridProblem = image.grid.problem();
  if (!gridProblem.empty()) return gridProblem;
  if (image.data.empty()) return "no voxels";
  size_t nonFinite = 0;
  for (float v : image.data) nonFinite += std::isfinite(v) ? 0 : 1;
  if (nonFinite > 0) return std::to_string(nonFinite) + " NaN/Inf voxels";
  const auto [lo, hi] = std::minmax_element(image.data.begin(), image.data.end());
  if (*lo == *hi) {
    std::ostringstream value;
    value << *lo;
    return "every voxel is " + value.str() + ": a constant image has no edge for a surface to find";
  }
  return "";
}

std::vector<double> templateShareInImage(const Grid& grid, const Scene& scene) {
  std::vector<double> shares;
  for (const SceneObject& o : scene.objects) {
    const int n = o.templ.vertexCount();
    int inside = 0;
    for (int v = 0; v < n; ++v) {
      const Eigen::Vector3d ijk = grid.toVoxel(o.templ.vertices.row(v).transpose());
      bool in = true;
      for (int a = 0; a < 3; ++a) in = in && ijk[a] >= -0.5 && ijk[a] <= grid.dims[a] - 0.5;
      inside += in ? 1 : 0;
    }
    shares.push_back(n > 0 ? static_cast<double>(inside) / n : 0.0);
  }
  return shares;
}

std::string coverageProblem(const Grid& grid, const Scene& scene) {
  const std::vector<double> shares = templateShareInImage(grid, scene);
  std::string problem;
  for (size_t i = 0; i < shares.size(); ++i) {
    if (shares[i] >= kMinTemplateShareInImage) continue;
    std::ostringstream s;
    s << (problem.empty() ? "" : "; ") << scene.objects[i].name << ": " << std::lround(100 * shares[i])
      << " % of its template lies inside the image";
    problem += s.str();
  }
  if (problem.empty()) return "";
  return problem + " (at least " + std::to_string(std::lround(100 * kMinTemplateShareInImage)) +
         " % must): the templates are not where these structures are in this image's world coordinates (place them "
         "there, or segment with --atlas)";
}

struct FeatureStore::Impl {
  std::map<const ImageF*, std::unique_ptr<detail::FeatureCache>> caches;
};

FeatureStore::FeatureStore() : impl_(std::make_unique<Impl>()) {}
FeatureStore::~FeatureStore() = default;

SegmentationResult segmentScene(const ImageF& image, const Scene& scene, const SegmentOptions& opts,
                                const ProgressFn& progress, FeatureStore* store) {
  const auto t0 = Clock::now();
  checkSegmentOptions(opts);
  checkInput(image, scene);
  SegmentationResult res;
  res.settings = resolveSettings(opts, image.grid);
  checkWorkload(scene, res.settings);
  const std::vector<PairContact> contacts = pairContacts(scene, opts, image.grid);
  if (opts.collision.enabled)
    for (size_t k = 0; k < scene.collisions.size(); ++k)
      res.collisionResponses.push_back({scene.objects[static_cast<size_t>(scene.collisions[k].a)].name,
                                        scene.objects[static_cast<size_t>(scene.collisions[k].b)].name,
                                        contacts[k].response});
  // The features of every image the run reads (this image; the images objects learn profiles on), per image, kept in
  // the caller's store if it gave one.
  FeatureStore own;
  std::map<const ImageF*, std::unique_ptr<FeatureCache>>& caches = (store ? *store : own).impl().caches;
  const auto cacheOf = [&caches](const ImageF& im) -> FeatureCache& {
    std::unique_ptr<FeatureCache>& cache = caches[&im];
    if (!cache) cache = std::make_unique<FeatureCache>(im);
    return *cache;
  };
  const auto featureSecondsSoFar = [&caches] {
    double s = 0;
    for (const auto& kv : caches) s += kv.second->seconds();
    return s;
  };
  const double featureSecondsBefore = featureSecondsSoFar();
  FeatureCache& features = cacheOf(image);
  const auto te = Clock::now();  // the evolution's time, less that of the image features (counted apart)
  features.prepare(res.settings.sigmaMm, opts.evolution.threads);  // every level's scale, in parallel
  std::set<FeatureCache*> profileCaches;                           // of the images objects learn profiles on
  std::vector<ObjectState> objs(scene.objects.size());
  const auto tp = Clock::now();
  for (size_t i = 0; i < objs.size(); ++i) {
    objs[i].obj = &scene.objects[i];
    if (const ImageF* profiles = scene.objects[i].profileImage.get()) {
      objs[i].profileFeatures = &cacheOf(*profiles);
      profileCaches.insert(objs[i].profileFeatures);
    }
    for (const SceneObject::Subject& s : scene.objects[i].profileSubjects) {
      objs[i].subjectFeatures.push_back(&cacheOf(*s.image));
      profileCaches.insert(objs[i].subjectFeatures.back());
    }
  }
  // The objects' templates (remeshing, levels, tets, polarity) are prepared on the threads: each reads the prepared
  // scales and writes only its own state.
  for (FeatureCache* cache : profileCaches) cache->prepare({res.settings.sigmaMm[0]}, opts.evolution.threads);
  std::unique_ptr<MeshCache> templateCache;
  if (!opts.surface.templateCache.empty()) templateCache = std::make_unique<MeshCache>(opts.surface.templateCache);
  parallelEach(objs.size(), opts.evolution.threads,
               [&](size_t i) { prepareObject(objs[i], opts, res.settings, features, templateCache.get()); });
  if (templateCache) {
    res.templateCacheHits = templateCache->hits();
    res.templateCacheMisses = templateCache->misses();
  }
  for (const ObjectState& st : objs)
    for (const std::string& w : st.warnings) log::warn(w);
  res.secondsPerStage["preparation"] = since(tp);
  const double detectSeconds = evolve(objs, res, scene, contacts, opts, features, image.grid, progress);
  // A run of the coarse levels only is a look at where they lead, not an output: its surfaces are neither unfolded nor
  // separated, and no labels are rasterised (EvolutionOptions::coarseOnly).
  const bool look = opts.evolution.coarseOnly && res.settings.levels > 1;
  // Each object's output surface on the threads (each writes only its own state).
  parallelEach(objs.size(), opts.evolution.threads,
               [&](size_t i) { finishObject(objs[i], opts.surface.unfoldSurfaces && !look); });
  for (ObjectState& st : objs) res.objects.push_back(std::move(st.out));
  const double featureSeconds = featureSecondsSoFar() - featureSecondsBefore;
  res.secondsPerStage["evolution"] = since(te) - featureSeconds;
  std::vector<std::vector<size_t>> inside;  // each object's voxels, once its output surface is final
  bool crossingsCounted = opts.surface.unfoldSurfaces || look;  // finishObject()'s unfolding counted them
  if (opts.collision.enabled && !scene.collisions.empty() && !look)
    inside = separateOutputs(res, objs, scene, contacts, opts, image.grid, crossingsCounted);
  if (res.collisionSetsBuilt > 0) res.secondsPerStage["collision-detection"] = detectSeconds;
  // What is written out: does any surface cross itself? (Counted already by an unfolding that left the surfaces as
  // they are written.)
  if (!crossingsCounted) {
    const auto tq = Clock::now();
    parallelEach(res.objects.size(), opts.evolution.threads,
                 [&](size_t i) { res.objects[i].selfIntersections = selfIntersections(res.objects[i].mesh); });
    res.secondsPerStage["surface-check"] = since(tq);
  }
  if (!look) rasteriseLabels(res, scene, inside, image.grid);
  // The quality check of every written surface, in the image at the finest level's scale (quality_check.h).
  const auto tc = Clock::now();
  const ImageFeatures& finest = features.at(res.settings.sigmaMm.back());
  const double noise = imageNoiseSigma(finest.smoothed);
  for (size_t i = 0; i < res.objects.size(); ++i) {
    ObjectResult& o = res.objects[i];
    const SceneObject& so = scene.objects[i];
    std::function<bool(const Eigen::Vector3d&)> unseen;
    if (so.profileImage) {
      // Where the profiles' source image (an atlas's reference) ends, a continued template is not expected in view.
      const Eigen::Matrix4d toSource = so.profileSource.value_or(Eigen::Matrix4d::Identity());
      unseen = [&so, toSource](const Eigen::Vector3d& p) {
        return !sampleTrilinear(*so.profileImage, toSource.topLeftCorner<3, 3>() * p + toSource.topRightCorner<3, 1>());
      };
    }
    o.quality = measureQuality(finest, o.mesh, o.polarity, objs[i].search.mode, noise, {}, unseen);
    o.quality.crossingFacePairs = o.selfIntersections;
    const ObjectState& st = objs[i];
    if (st.force == TargetMode::Profile && st.profiles.profiles.rows() == st.current.vertexCount()) {
      const LearnedProfiles now =
          learnProfiles(finest, st.current.positions, simplexVertexNormals(st.current), st.search, image.grid, false);
      // Over the vertices with a profile on both sides (a zero row has none).
      double sum = 0;
      int counted = 0;
      for (Eigen::Index v = 0; v < now.profiles.rows(); ++v)
        if (now.profiles.row(v).squaredNorm() > 0 && st.profiles.profiles.row(v).squaredNorm() > 0) {
          sum += now.profiles.row(v).dot(st.profiles.profiles.row(v));
          ++counted;
        }
      o.quality.profileMatch = counted > 0 ? sum / counted : 0.0;
    }
    judgeQuality(o.quality);  // again, with the figures measureQuality() does not take
    res.status = worseStatus(res.status, o.quality.status);
  }
  res.secondsPerStage["quality-check"] = since(tc);
  res.secondsPerStage["features"] = featureSeconds;
  res.featureScalesBuilt = features.built();
  res.seconds = since(t0);
  if (progress) progress(1.0, "done");
  return res;
}

}  // namespace msk
