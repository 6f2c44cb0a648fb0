#include "msk/bench/scene_bench.h"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>

#include "msk/core/error.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/phantom/multi_phantom.h"
#include "msk/segmentation/metrics.h"

namespace msk {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// "a|b" names of the k-th collision pair.
std::string pairName(const Scene& scene, size_t k, const char* sep) {
  const CollisionPair& p = scene.collisions[k];
  return scene.objects[static_cast<size_t>(p.a)].name + sep + scene.objects[static_cast<size_t>(p.b)].name;
}

/// Projection time per family over the scene (the run's, every object's constraints of a family together), and the
/// objects' image search summed as "image-search".
std::map<std::string, double> familySeconds(const SegmentationResult& res) {
  std::map<std::string, double> families = res.secondsPerFamily;
  double search = 0;
  for (const ObjectResult& o : res.objects) search += o.imageSearchSeconds;
  families["image-search"] = search;
  return families;
}

void writeCsv(const std::string& path, const std::vector<SceneBenchObject>& objects) {
  std::ofstream f(path);
  if (!f) throw IoError(path, "cannot write");
  f << "name,label,kind,dice,assd_mm,mesh_assd_mm,template_dice,self_intersections\n";
  char line[256];
  for (const SceneBenchObject& o : objects) {
    std::snprintf(line, sizeof line, "%s,%d,%s,%.4f,%.3f,%.3f,%.4f,%zu\n", o.name.c_str(), o.label, o.kind.c_str(),
                  o.dice, o.assdMm, o.meshAssdMm, o.templateDice, o.selfIntersections);
    f << line;
  }
  if (!f) throw IoError(path, "write failed");
}

}  // namespace

double processCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double processPeakRssMiB() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux reports KiB
}

SceneBenchFigures runSceneBench(const SceneBenchOptions& opts, const ProgressFn& progress) {
  if (opts.structures != 4 && opts.structures != kMultiPhantomStructures)
    throw ParameterError(
        "--structures", std::to_string(opts.structures),
        "must be " + std::to_string(kMultiPhantomStructures) + " (thighs and lower legs) or 4 (thigh)");
  SceneBenchFigures f;
  f.options = opts;
  const Clock::time_point start = Clock::now();
  const double cpuStart = processCpuSeconds();
  const Phantom ph =
      opts.structures == 4 ? makePhantom(opts.phantom, progress) : makeMultiPhantom(opts.phantom, progress);
  f.generationSeconds = secondsSince(start);
  f.generationCpu = processCpuSeconds() - cpuStart;
  f.scene = phantomScene(ph);
  f.grid = ph.image.grid;

  const Clock::time_point segStart = Clock::now();
  f.result = segmentScene(ph.image, f.scene, opts.segment, progress);
  f.segmentSeconds = secondsSince(segStart);
  f.segmentCpu = processCpuSeconds() - cpuStart - f.generationCpu;

  const Clock::time_point scoreStart = Clock::now();
  for (size_t i = 0; i < ph.objects.size(); ++i) {
    const PhantomObject& o = ph.objects[i];
    SceneBenchObject b;
    b.name = o.name;
    b.kind = o.kind;
    b.label = o.label;
    const SegmentationMetrics m = labelMetrics(f.result.labels, o.label, ph.labels, o.label);
    b.dice = m.dice;
    b.assdMm = m.assd;
    b.meshAssdMm = meshMetrics(f.result.objects[i].mesh, o.truth, 1.0, 1.0).assd;
    b.templateDice = meshMetrics(o.templ, o.truth, 1.0, 0.05).dice;
    b.selfIntersections = f.result.objects[i].selfIntersections;
    f.objects.push_back(b);
  }
  f.scoreSeconds = secondsSince(scoreStart);
  f.peakRssMiB = processPeakRssMiB();
  f.secondsPerFamily = familySeconds(f.result);
  for (const ObjectResult& o : f.result.objects)
    if (!o.levels.empty()) f.simplexVertices += static_cast<size_t>(o.levels.back().vertices);
  return f;
}

void printSceneBench(const SceneBenchFigures& f) {
  const Grid& g = f.grid;
  std::printf("scene: %zu objects, %zu collision pairs, grid %dx%dx%d (%.2f Mvoxels) at %.2fx%.2fx%.2f mm, seed %u\n",
              f.scene.objects.size(), f.scene.collisions.size(), g.dims[0], g.dims[1], g.dims[2],
              static_cast<double>(g.voxelCount()) * 1e-6, g.spacing[0], g.spacing[1], g.spacing[2],
              f.options.phantom.seed);
  std::printf("quality %s: %d levels, %zu simplex vertices at the finest level, collisions %s\n",
              qualityName(f.options.segment.evolution.quality), f.result.settings.levels, f.simplexVertices,
              f.options.segment.collision.enabled ? "on" : "off");
  std::printf("\ntime per stage (s, wall)\n");
  std::printf("  %-22s %8.2f  (cpu %.2f)\n", "generation", f.generationSeconds, f.generationCpu);
  // The pipeline's stages in run order (the templates' preparation and collision detection are timed inside the
  // evolution), then any others.
  std::map<std::string, double> stagesLeft = f.result.secondsPerStage;
  for (const char* stage : {"features", "evolution", "preparation", "collision-detection", "separation", "rasterise"}) {
    const auto it = stagesLeft.find(stage);
    if (it == stagesLeft.end()) continue;
    const bool inner = it->first == "collision-detection" || it->first == "preparation";
    std::printf("  %s%-*s %8.2f%s\n", inner ? "  " : "", inner ? 20 : 22, it->first.c_str(), it->second,
                inner ? "  (part of evolution)" : "");
    stagesLeft.erase(it);
  }
  for (const auto& [stage, s] : stagesLeft) std::printf("  %-22s %8.2f\n", stage.c_str(), s);
  std::printf("  %-22s %8.2f  (segmentScene; cpu %.2f)\n", "segmentation total", f.result.seconds, f.segmentCpu);
  std::printf("  %-22s %8.2f\n", "scoring", f.scoreSeconds);
  std::printf("  %-22s %8.2f  (generation + segmentation, wall)\n", "whole", f.generationSeconds + f.segmentSeconds);
  std::printf("built: %d image scales, %d directed collision sets; output separation: %d sweeps, %ld corrections\n",
              f.result.featureScalesBuilt, f.result.collisionSetsBuilt, f.result.separationSweeps,
              f.result.separationCorrections);
  std::printf(
      "\nprojection time per constraint family (s, wall; a stacked solver's time once, per-object times summed)\n");
  for (const auto& [family, s] : f.secondsPerFamily) std::printf("  %-22s %8.2f\n", family.c_str(), s);
  std::printf("\npeak memory (RSS): %.0f MiB\n", f.peakRssMiB);
  std::printf("\n%-26s %5s  %6s  %8s  %9s  %8s\n", "object", "label", "Dice", "ASSD mm", "mesh ASSD", "tmpl Dice");
  double diceSum = 0, assdSum = 0, meshSum = 0, diceMin = 1;
  for (const SceneBenchObject& o : f.objects) {
    std::printf("%-26s %5d  %6.3f  %8.2f  %9.2f  %8.3f\n", o.name.c_str(), o.label, o.dice, o.assdMm, o.meshAssdMm,
                o.templateDice);
    diceSum += o.dice;
    assdSum += o.assdMm;
    meshSum += o.meshAssdMm;
    diceMin = std::min(diceMin, o.dice);
  }
  const double n = static_cast<double>(std::max<size_t>(1, f.objects.size()));
  std::printf("%-26s %5s  %6.3f  %8.2f  %9.2f   (min Dice %.3f)\n", "mean", "", diceSum / n, assdSum / n, meshSum / n,
              diceMin);
  double deepest = 0;
  size_t crossings = 0, crossing = 0;  // face pairs of the output surfaces that cross, and objects with any
  for (const SceneBenchObject& o : f.objects) crossings += o.selfIntersections, crossing += o.selfIntersections > 0;
  std::printf(
      "\noverlap voxels: %zu\nself-intersecting face pairs: %zu (in %zu of %zu surfaces)\npenetration per pair (mm):",
      f.result.overlapVoxels, crossings, crossing, f.objects.size());
  for (size_t k = 0; k < f.scene.collisions.size() && k < f.result.pairPenetrationMm.size(); ++k) {
    if (k % 4 == 0) std::printf("\n ");
    std::printf(" %s %.2f", pairName(f.scene, k, "|").c_str(), f.result.pairPenetrationMm[k]);
    deepest = std::max(deepest, f.result.pairPenetrationMm[k]);
  }
  if (f.result.pairPenetrationMm.empty())
    std::printf(" not measured (no collision response)\n");
  else
    std::printf("\n  deepest %.2f mm\n", deepest);
  std::fflush(stdout);
}

void writeSceneBench(const std::string& dir, const SceneBenchFigures& f) {
  const SegmentationResult& res = f.result;
  size_t crossings = 0;
  for (const SceneBenchObject& o : f.objects) crossings += o.selfIntersections;
  Json j = Json::object();
  j["structures"] = f.scene.objects.size();
  j["collision_pairs"] = f.scene.collisions.size();
  j["seed"] = f.options.phantom.seed;
  j["quality"] = qualityName(f.options.segment.evolution.quality);
  j["collisions"] = f.options.segment.collision.enabled;
  j["threads"] = f.options.segment.evolution.threads;
  j["voxels"] = f.grid.voxelCount();
  j["simplex_vertices"] = f.simplexVertices;
  Json stages = Json::object();
  stages["generation"] = f.generationSeconds;
  for (const auto& [stage, s] : res.secondsPerStage) stages[stage] = s;
  stages["segmentation_total"] = res.seconds;
  stages["generation_cpu"] = f.generationCpu;
  stages["segmentation_cpu"] = f.segmentCpu;
  stages["scoring"] = f.scoreSeconds;
  stages["whole"] = f.generationSeconds + f.segmentSeconds;
  j["seconds_per_stage"] = std::move(stages);
  Json fam = Json::object();
  for (const auto& [family, s] : f.secondsPerFamily) fam[family] = s;
  j["seconds_per_family"] = std::move(fam);
  j["peak_rss_mib"] = f.peakRssMiB;
  j["overlap_voxels"] = res.overlapVoxels;
  j["self_intersections"] = crossings;
  j["feature_scales_built"] = res.featureScalesBuilt;
  j["collision_sets_built"] = res.collisionSetsBuilt;
  j["separation_sweeps"] = res.separationSweeps;
  j["separation_corrections"] = res.separationCorrections;
  Json objs = Json::array();
  for (const SceneBenchObject& b : f.objects) {
    Json o = Json::object();
    o["name"] = b.name;
    o["label"] = b.label;
    o["kind"] = b.kind;
    o["dice"] = b.dice;
    o["assd_mm"] = b.assdMm;
    o["mesh_assd_mm"] = b.meshAssdMm;
    o["template_dice"] = b.templateDice;
    o["self_intersections"] = b.selfIntersections;
    objs.push_back(std::move(o));
  }
  j["objects"] = std::move(objs);
  Json pairs = Json::array();
  for (size_t k = 0; k < f.scene.collisions.size() && k < res.pairPenetrationMm.size(); ++k) {
    Json p = Json::object();
    p["a"] = f.scene.objects[static_cast<size_t>(f.scene.collisions[k].a)].name;
    p["b"] = f.scene.objects[static_cast<size_t>(f.scene.collisions[k].b)].name;
    p["penetration_mm"] = res.pairPenetrationMm[k];
    pairs.push_back(std::move(p));
  }
  j["pairs"] = std::move(pairs);
  writeJsonFile(dir + "/bench.json", j);
  writeCsv(dir + "/objects.csv", f.objects);
  int maxLabel = 0;
  for (const ObjectResult& o : res.objects) maxLabel = std::max(maxLabel, o.label);
  writeNifti(dir + "/labels.nii.gz", res.labels, maxLabel <= 255 ? DataType::UInt8 : DataType::Int16);
  for (const ObjectResult& o : res.objects) writeMesh(dir + "/result_" + o.name + ".vtk", o.mesh, MeshSpace::LPS);
}

}  // namespace msk
