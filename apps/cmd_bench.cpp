// mskseg bench: benchmarks that print figures (time per stage, accuracy, memory). One subcommand per benchmark,
// dispatched on the first positional word; `mskseg bench --help` lists them.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "args.h"
#include "commands.h"
#include "msk/core/error.h"
#include "msk/core/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/multi_phantom.h"
#include "msk/segmentation/phantom.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"
#include "msk/segmentation/tradeoff_plot.h"

namespace msk::cli {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// CPU time of this process (user + system, all threads), seconds.
double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Peak resident set size of this process, MiB (Linux reports ru_maxrss in KiB).
double peakRssMiB() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

// The scene a phantom declares: its templates as objects, its touching structures as collision pairs.
Scene phantomScene(const Phantom& ph) {
  Scene scene;
  scene.path = "(generated phantom)";
  for (const PhantomObject& o : ph.objects) {
    SceneObject so;
    so.name = o.name;
    so.label = o.label;
    so.kind = o.kind == "bone" ? ObjectKind::Bone : o.kind == "muscle" ? ObjectKind::Muscle : ObjectKind::Generic;
    so.templatePath = "template_" + o.name + ".vtk";
    so.templ = o.templ;
    scene.objects.push_back(std::move(so));
  }
  for (size_t a = 0; a < ph.objects.size(); ++a)
    for (size_t b = a + 1; b < ph.objects.size(); ++b) {
      const auto& t = ph.objects[a].touching;
      if (std::find(t.begin(), t.end(), ph.objects[b].name) != t.end())
        scene.collisions.push_back(CollisionPair{static_cast<int>(a), static_cast<int>(b)});
    }
  return scene;
}

// "a|b" names of the k-th collision pair.
std::string pairName(const Scene& scene, size_t k, const char* sep) {
  const CollisionPair& p = scene.collisions[k];
  return scene.objects[static_cast<size_t>(p.a)].name + sep + scene.objects[static_cast<size_t>(p.b)].name;
}

struct ObjectFigures {
  std::string name, kind;
  int label = 0;
  double dice = 0, assdMm = 0, meshAssdMm = 0, templateDice = 0;
  size_t selfIntersections = 0;  ///< face pairs of the output surface that cross each other
};

void writeCsv(const std::string& path, const std::vector<ObjectFigures>& objects) {
  std::ofstream f(path);
  if (!f) throw IoError(path, "cannot write");
  f << "name,label,kind,dice,assd_mm,mesh_assd_mm,template_dice,self_intersections\n";
  char line[256];
  for (const ObjectFigures& o : objects) {
    std::snprintf(line, sizeof line, "%s,%d,%s,%.4f,%.3f,%.3f,%.4f,%zu\n", o.name.c_str(), o.label, o.kind.c_str(),
                  o.dice, o.assdMm, o.meshAssdMm, o.templateDice, o.selfIntersections);
    f << line;
  }
  if (!f) throw IoError(path, "write failed");
}

int benchScene(const std::vector<std::string>& argv) {
  Args args(argv, {"structures", "quality", "seed", "out", "spacing", "vertices", "threads"}, {"help", "no-collisions"});
  if (args.has("help")) {
    std::cout << "usage: mskseg bench scene [--structures 24|4] [--quality fast|balanced|accurate] [--seed N]\n"
                 "                          [--spacing 1.2,1.2,3] [--vertices N] [--threads N] [--no-collisions] [--out DIR]\n\n"
                 "Generates a synthetic phantom scene (24: both thighs and lower legs, 4 bones + 20 muscles; 4: the\n"
                 "thigh), segments it from its mean-anatomy templates with the scene's collision pairs and prints the\n"
                 "time per stage (generation, features, evolution, collision detection, rasterise), the constraint\n"
                 "projection time per family, the whole time, the peak memory, per-object Dice and ASSD against the\n"
                 "exact labels and truth meshes, overlapping voxels and per-pair penetration.\n"
                 "  --structures  scene size                               (default 24)\n"
                 "  --quality     segmentation preset                      (default balanced)\n"
                 "  --seed        phantom seed                             (default 1)\n"
                 "  --spacing     voxel size in mm                         (default 1.2,1.2,3)\n"
                 "  --vertices    vertices of each template/truth mesh     (default 3000)\n"
                 "  --threads     threads of collision detection and the parallel schemes (default 1; 0 = all)\n"
                 "  --no-collisions  ignore the collision pairs\n"
                 "  --out         also write bench.json, objects.csv, the result label map (labels.nii.gz) and\n"
                 "                surfaces (result_<name>.vtk, LPS) into DIR, atomically; `mskseg phantom\n"
                 "                --structures N --seed S` writes the matching image, truth and templates\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  const long structures = args.integer("structures", kMultiPhantomStructures);
  if (structures != 4 && structures != kMultiPhantomStructures)
    throw ParameterError("--structures", std::to_string(structures),
                         "must be " + std::to_string(kMultiPhantomStructures) + " (thighs and lower legs) or 4 (thigh)");
  SegmentOptions sopts;
  sopts.quality = parseQuality(args.str("quality", "balanced"));
  sopts.collisions = !args.has("no-collisions");
  const long threads = args.integer("threads", 1);
  if (threads < 0 || threads > 1024) throw ParameterError("--threads", args.str("threads"), "must be 0..1024");
  sopts.threads = static_cast<int>(threads);
  PhantomOptions popts;
  const long seed = args.integer("seed", 1);
  if (seed < 0 || seed > 0xffffffffL) throw ParameterError("--seed", std::to_string(seed), "must be in [0, 2^32)");
  popts.seed = static_cast<uint32_t>(seed);
  popts.spacing = args.vec3("spacing", popts.spacing);
  const long vertices = args.integer("vertices", popts.meshVertices);
  if (vertices < 100 || vertices > 1000000)
    throw ParameterError("--vertices", std::to_string(vertices), "must be in 100..1000000");
  popts.meshVertices = static_cast<int>(vertices);
  const std::string out = args.str("out", "");
  if (!out.empty()) checkOutputFolder(out);

  const Clock::time_point start = Clock::now();
  const double cpuStart = cpuSeconds();
  const Phantom ph = structures == 4 ? makePhantom(popts, stderrProgress("phantom"))
                                     : makeMultiPhantom(popts, stderrProgress("phantom"));
  const double generationSeconds = secondsSince(start);
  const double generationCpu = cpuSeconds() - cpuStart;
  const Scene scene = phantomScene(ph);

  const Clock::time_point segStart = Clock::now();
  const SegmentationResult res = segmentScene(ph.image, scene, sopts, stderrProgress("segment"));
  const double segmentSeconds = secondsSince(segStart);
  const double segmentCpu = cpuSeconds() - cpuStart - generationCpu;

  const Clock::time_point scoreStart = Clock::now();
  std::vector<ObjectFigures> figures;
  for (size_t i = 0; i < ph.objects.size(); ++i) {
    const PhantomObject& o = ph.objects[i];
    ObjectFigures f;
    f.name = o.name;
    f.kind = o.kind;
    f.label = o.label;
    const SegmentationMetrics m = labelMetrics(res.labels, o.label, ph.labels, o.label);
    f.dice = m.dice;
    f.assdMm = m.assd;
    f.meshAssdMm = meshMetrics(res.objects[i].mesh, o.truth, 1.0, 1.0).assd;
    f.templateDice = meshMetrics(o.templ, o.truth, 1.0, 0.05).dice;
    f.selfIntersections = res.objects[i].selfIntersections;
    figures.push_back(f);
  }
  const double scoreSeconds = secondsSince(scoreStart);
  const double peak = peakRssMiB();

  // Projection time per family over the scene. Objects evolved together in one stacked solver each carry the
  // solver's whole time for a family (the same value in every object): counted once; per-object times (image
  // search) are summed.
  std::map<std::string, double> families;
  {
    std::map<std::string, std::vector<double>> perObject;
    for (const ObjectResult& o : res.objects)
      for (const auto& [family, s] : o.secondsPerFamily) perObject[family].push_back(s);
    for (const auto& [family, values] : perObject) {
      const bool shared = values.size() == res.objects.size() && values.size() > 1 &&
                          std::all_of(values.begin(), values.end(), [&](double v) { return v == values.front(); });
      double sum = 0;
      for (double v : values) sum += v;
      families[family] = shared ? values.front() : sum;
    }
  }
  size_t vertexCount = 0;
  for (const ObjectResult& o : res.objects)
    if (!o.levels.empty()) vertexCount += static_cast<size_t>(o.levels.back().vertices);

  // Report.
  const Grid& g = ph.image.grid;
  std::printf("scene: %zu objects, %zu collision pairs, grid %dx%dx%d (%.2f Mvoxels) at %.2fx%.2fx%.2f mm, seed %u\n",
              scene.objects.size(), scene.collisions.size(), g.dims[0], g.dims[1], g.dims[2],
              static_cast<double>(g.voxelCount()) * 1e-6, g.spacing[0], g.spacing[1], g.spacing[2], popts.seed);
  std::printf("quality %s: %d levels, %zu simplex vertices at the finest level, collisions %s\n",
              qualityName(sopts.quality), res.settings.levels, vertexCount, sopts.collisions ? "on" : "off");
  std::printf("\ntime per stage (s, wall)\n");
  std::printf("  %-22s %8.2f  (cpu %.2f)\n", "generation", generationSeconds, generationCpu);
  // The pipeline's stages in run order (collision detection is timed inside the evolution), then any others.
  std::map<std::string, double> stagesLeft = res.secondsPerStage;
  for (const char* stage : {"features", "evolution", "collision-detection", "separation", "rasterise"}) {
    const auto it = stagesLeft.find(stage);
    if (it == stagesLeft.end()) continue;
    const bool inner = it->first == "collision-detection";
    std::printf("  %s%-*s %8.2f%s\n", inner ? "  " : "", inner ? 20 : 22, it->first.c_str(), it->second,
                inner ? "  (part of evolution)" : "");
    stagesLeft.erase(it);
  }
  for (const auto& [stage, s] : stagesLeft) std::printf("  %-22s %8.2f\n", stage.c_str(), s);
  std::printf("  %-22s %8.2f  (segmentScene; cpu %.2f)\n", "segmentation total", res.seconds, segmentCpu);
  std::printf("  %-22s %8.2f\n", "scoring", scoreSeconds);
  std::printf("  %-22s %8.2f  (generation + segmentation, wall)\n", "whole", generationSeconds + segmentSeconds);
  std::printf("built: %d image scales, %d directed collision sets; output separation: %d sweeps, %ld corrections\n",
              res.featureScalesBuilt, res.collisionSetsBuilt, res.separationSweeps, res.separationCorrections);
  std::printf("\nprojection time per constraint family (s, wall; a stacked solver's time once, per-object times summed)\n");
  for (const auto& [family, s] : families) std::printf("  %-22s %8.2f\n", family.c_str(), s);
  std::printf("\npeak memory (RSS): %.0f MiB\n", peak);
  std::printf("\n%-26s %5s  %6s  %8s  %9s  %8s\n", "object", "label", "Dice", "ASSD mm", "mesh ASSD", "tmpl Dice");
  double diceSum = 0, assdSum = 0, meshSum = 0, diceMin = 1;
  for (const ObjectFigures& f : figures) {
    std::printf("%-26s %5d  %6.3f  %8.2f  %9.2f  %8.3f\n", f.name.c_str(), f.label, f.dice, f.assdMm, f.meshAssdMm,
                f.templateDice);
    diceSum += f.dice;
    assdSum += f.assdMm;
    meshSum += f.meshAssdMm;
    diceMin = std::min(diceMin, f.dice);
  }
  const double n = static_cast<double>(std::max<size_t>(1, figures.size()));
  std::printf("%-26s %5s  %6.3f  %8.2f  %9.2f   (min Dice %.3f)\n", "mean", "", diceSum / n, assdSum / n, meshSum / n,
              diceMin);
  double deepest = 0;
  size_t crossings = 0, crossing = 0;  // face pairs of the output surfaces that cross, and objects with any
  for (const ObjectFigures& f : figures) crossings += f.selfIntersections, crossing += f.selfIntersections > 0;
  std::printf(
      "\noverlap voxels: %zu\nself-intersecting face pairs: %zu (in %zu of %zu surfaces)\npenetration per pair (mm):",
      res.overlapVoxels, crossings, crossing, figures.size());
  for (size_t k = 0; k < scene.collisions.size() && k < res.pairPenetrationMm.size(); ++k) {
    if (k % 4 == 0) std::printf("\n ");
    std::printf(" %s %.2f", pairName(scene, k, "|").c_str(), res.pairPenetrationMm[k]);
    deepest = std::max(deepest, res.pairPenetrationMm[k]);
  }
  if (res.pairPenetrationMm.empty())
    std::printf(" not measured (no collision response)\n");
  else
    std::printf("\n  deepest %.2f mm\n", deepest);
  std::fflush(stdout);

  if (!out.empty()) {
    Json j = Json::object();
    j["structures"] = static_cast<int>(scene.objects.size());
    j["collision_pairs"] = static_cast<int>(scene.collisions.size());
    j["seed"] = static_cast<unsigned long>(popts.seed);
    j["quality"] = qualityName(sopts.quality);
    j["collisions"] = sopts.collisions;
    j["threads"] = sopts.threads;
    j["voxels"] = static_cast<unsigned long>(g.voxelCount());
    j["simplex_vertices"] = static_cast<unsigned long>(vertexCount);
    Json stages = Json::object();
    stages["generation"] = generationSeconds;
    for (const auto& [stage, s] : res.secondsPerStage) stages[stage] = s;
    stages["segmentation_total"] = res.seconds;
    stages["generation_cpu"] = generationCpu;
    stages["segmentation_cpu"] = segmentCpu;
    stages["scoring"] = scoreSeconds;
    stages["whole"] = generationSeconds + segmentSeconds;
    j["seconds_per_stage"] = std::move(stages);
    Json fam = Json::object();
    for (const auto& [family, s] : families) fam[family] = s;
    j["seconds_per_family"] = std::move(fam);
    j["peak_rss_mib"] = peak;
    j["overlap_voxels"] = static_cast<unsigned long>(res.overlapVoxels);
    j["self_intersections"] = static_cast<unsigned long>(crossings);
    j["feature_scales_built"] = res.featureScalesBuilt;
    j["collision_sets_built"] = res.collisionSetsBuilt;
    j["separation_sweeps"] = res.separationSweeps;
    j["separation_corrections"] = static_cast<long>(res.separationCorrections);
    Json objs = Json::array();
    for (const ObjectFigures& f : figures) {
      Json o = Json::object();
      o["name"] = f.name;
      o["label"] = f.label;
      o["kind"] = f.kind;
      o["dice"] = f.dice;
      o["assd_mm"] = f.assdMm;
      o["mesh_assd_mm"] = f.meshAssdMm;
      o["template_dice"] = f.templateDice;
      o["self_intersections"] = static_cast<unsigned long>(f.selfIntersections);
      objs.push(std::move(o));
    }
    j["objects"] = std::move(objs);
    Json pairs = Json::array();
    for (size_t k = 0; k < scene.collisions.size() && k < res.pairPenetrationMm.size(); ++k) {
      Json p = Json::object();
      p["a"] = scene.objects[static_cast<size_t>(scene.collisions[k].a)].name;
      p["b"] = scene.objects[static_cast<size_t>(scene.collisions[k].b)].name;
      p["penetration_mm"] = res.pairPenetrationMm[k];
      pairs.push(std::move(p));
    }
    j["pairs"] = std::move(pairs);
    writeFolderAtomically(out, [&](const std::string& staging) {
      j.writeFile(staging + "/bench.json");
      writeCsv(staging + "/objects.csv", figures);
      int maxLabel = 0;
      for (const ObjectResult& o : res.objects) maxLabel = std::max(maxLabel, o.label);
      writeNifti(staging + "/labels.nii.gz", res.labels, maxLabel <= 255 ? DataType::UInt8 : DataType::Int16);
      for (const ObjectResult& o : res.objects) writeMesh(staging + "/result_" + o.name + ".vtk", o.mesh, MeshSpace::LPS);
    });
    std::printf("figures written to %s (bench.json, objects.csv, labels.nii.gz, result_<name>.vtk)\n", out.c_str());
  }
  return 0;
}

// ---- bench tradeoff ----------------------------------------------------------------------------------------------

// One setting of the trade: a scheme on the balanced schedule, or a preset as shipped.
struct TradeoffConfig {
  std::string name;      // "xpbd 2x2", "preset fast"
  std::string scheme;    // scheme name, or "" for the preset's own
  std::string preset;    // fast | balanced | accurate
  int substeps = 0, iterations = 0;  // 0 = the preset's
  bool isPreset = false;
};

// What a forked run sends back through its pipe.
struct TradeoffRunResult {
  int ok = 0;
  int steps = 0, levels = 0, maxSteps = 0, substeps = 0, iterations = 0;
  double seconds = 0, dice = 0, assdMm = 0, toleranceMm = 0;
  double featureSeconds = 0, evolutionSeconds = 0;  // image features; evolution (collision detection included)
  double cpuSeconds = 0;  // CPU time of segmentScene (all threads): robust to other load on a shared machine
  char scheme[32] = {0};
  char error[256] = {0};
};

struct TradeoffRow {
  TradeoffConfig config;
  uint32_t seed = 0;
  TradeoffRunResult run;
  double peakRssMiB = 0;
};

// The schemes on the balanced schedule (2 levels × 50 steps), each at the substeps × iterations it needs.
std::vector<TradeoffConfig> tradeoffSchemeConfigs() {
  return {{"gauss-seidel 1x1", "gauss-seidel", "balanced", 1, 1, false},
          {"coloured-gauss-seidel 1x1", "coloured-gauss-seidel", "balanced", 1, 1, false},
          {"jacobi 1x2", "jacobi", "balanced", 1, 2, false},
          {"xpbd 2x2", "xpbd", "balanced", 2, 2, false},
          {"explicit 4x1", "explicit", "balanced", 4, 1, false},
          {"implicit 1x1", "implicit", "balanced", 1, 1, false}};
}

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (!item.empty()) out.push_back(item);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

// Runs one configuration on one phantom in a forked child, so each run's peak memory is its own (wait4's
// ru_maxrss; the child starts as a copy of this process, phantom included). Time is segmentScene's own.
TradeoffRow runTradeoff(const Phantom& ph, uint32_t seed, const TradeoffConfig& config, int threads) {
  TradeoffRow row;
  row.config = config;
  row.seed = seed;
  int fds[2];
  if (pipe(fds) != 0) throw Error("bench tradeoff: cannot create a pipe");
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) throw Error("bench tradeoff: cannot fork");
  if (pid == 0) {
    close(fds[0]);
    TradeoffRunResult r;
    try {
      Scene scene;
      scene.path = "(generated phantom: femur)";
      SceneObject femur;
      femur.name = ph.objects[0].name;
      femur.label = ph.objects[0].label;
      femur.kind = ObjectKind::Bone;
      femur.templ = ph.objects[0].templ;
      scene.objects.push_back(femur);
      SegmentOptions o;
      o.quality = parseQuality(config.preset);
      if (!config.scheme.empty()) o.scheme = parseScheme(config.scheme);
      o.substeps = config.substeps;
      o.iterations = config.iterations;
      o.threads = threads;
      const double cpu0 = cpuSeconds();
      const SegmentationResult res = segmentScene(ph.image, scene, o);
      r.cpuSeconds = cpuSeconds() - cpu0;
      r.seconds = res.seconds;
      const auto stage = [&](const char* name) {
        const auto it = res.secondsPerStage.find(name);
        return it == res.secondsPerStage.end() ? 0.0 : it->second;
      };
      r.featureSeconds = stage("features");
      r.evolutionSeconds = stage("evolution");
      r.levels = res.settings.levels;
      r.maxSteps = res.settings.maxStepsPerLevel;
      r.toleranceMm = res.settings.toleranceMm;
      r.substeps = res.settings.solver.substeps;
      r.iterations = res.settings.solver.iterations;
      std::snprintf(r.scheme, sizeof r.scheme, "%s", schemeName(res.settings.solver.scheme).c_str());
      for (const LevelReport& l : res.objects[0].levels) r.steps += l.steps;
      r.dice = labelMetrics(res.labels, femur.label, ph.labels, femur.label).dice;
      r.assdMm = meshMetrics(res.objects[0].mesh, ph.objects[0].truth).assd;
      r.ok = 1;
    } catch (const std::exception& e) {
      std::snprintf(r.error, sizeof r.error, "%s", e.what());
    }
    const char* p = reinterpret_cast<const char*>(&r);
    size_t left = sizeof r;
    while (left > 0) {
      const ssize_t n = write(fds[1], p, left);
      if (n <= 0) break;
      p += n;
      left -= static_cast<size_t>(n);
    }
    close(fds[1]);
    _exit(0);
  }
  close(fds[1]);
  char* p = reinterpret_cast<char*>(&row.run);
  size_t got = 0;
  while (got < sizeof row.run) {
    const ssize_t n = read(fds[0], p + got, sizeof row.run - got);
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  close(fds[0]);
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  row.peakRssMiB = static_cast<double>(usage.ru_maxrss) / 1024.0;
  if (got != sizeof row.run) {
    row.run = TradeoffRunResult{};
    std::snprintf(row.run.error, sizeof row.run.error, "run ended abnormally (status %d)", status);
  }
  return row;
}

int benchTradeoff(const std::vector<std::string>& argv) {
  Args args(argv, {"phantoms", "out", "seed", "threads", "schemes", "presets"}, {"help"});
  if (args.has("help")) {
    std::cout << "usage: mskseg bench tradeoff --phantoms N --out DIR [--seed S] [--threads N]\n\n"
                 "The speed/accuracy trade (issue 5): generates N thigh phantoms (seeds S..S+N-1, voxel size and grid\n"
                 "obliquity varied), segments the femur of each from its mean template with every scheme (on the\n"
                 "balanced schedule: 2 levels x 50 steps) and every --quality preset, each run in a child process, and\n"
                 "writes atomically into DIR:\n"
                 "  tradeoff.csv  one row per run and one mean row per setting: scheme, preset, levels, steps cap,\n"
                 "                tolerance (first phantom's, mm), substeps, iterations, steps taken, seconds (wall)\n"
                 "                and CPU seconds of the segmentation, Dice, mesh ASSD (mm) against the truth\n"
                 "                surface, peak RSS of the run (MiB, the child process: phantom included)\n"
                 "  tradeoff.png  mean ASSD against mean CPU time per setting, the Pareto front marked\n"
                 "Prints the table and checks the issue's demands (fast >= 5x faster than accurate, on CPU time, which\n"
                 "other load on the machine does not inflate; accurate at least as accurate as every row, on ASSD).\n"
                 "Progress on stderr.\n"
                 "  --phantoms  number of phantoms, 1..50\n"
                 "  --seed      first phantom seed (default 1)\n"
                 "  --threads   threads of the coloured, Jacobi and CG schemes (default 1)\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  if (!args.has("phantoms")) throw UsageError("missing --phantoms N");
  if (!args.has("out")) throw UsageError("missing --out DIR");
  const long phantoms = args.integer("phantoms", 1);
  if (phantoms < 1 || phantoms > 50) throw ParameterError("--phantoms", args.str("phantoms"), "must be 1..50");
  const long seed0 = args.integer("seed", 1);
  if (seed0 < 0 || seed0 + phantoms > 0xffffffffL) throw ParameterError("--seed", args.str("seed"), "must be in [0, 2^32 - N)");
  const long threads = args.integer("threads", 1);
  if (threads < 0 || threads > 1024) throw ParameterError("--threads", args.str("threads"), "must be 0..1024");
  const std::string out = args.str("out");
  checkOutputFolder(out);
  // Hidden subset options (tests, quick looks): --schemes a,b (scheme names or "none") and --presets x,y ("none").
  std::vector<TradeoffConfig> configs;
  {
    std::vector<std::string> schemes, presets = {"fast", "balanced", "accurate"};
    for (const TradeoffConfig& c : tradeoffSchemeConfigs()) schemes.push_back(c.scheme);
    if (args.has("schemes")) schemes = splitList(args.str("schemes"));
    if (args.has("presets")) presets = splitList(args.str("presets"));
    for (const std::string& s : schemes) {
      if (s == "none") continue;
      const std::string name = schemeName(parseScheme(s));  // validates (ParameterError names the choices)
      for (const TradeoffConfig& c : tradeoffSchemeConfigs())
        if (c.scheme == name) configs.push_back(c);
    }
    for (const std::string& p : presets) {
      if (p == "none") continue;
      TradeoffConfig c;
      c.preset = qualityName(parseQuality(p));
      c.name = "preset " + c.preset;
      c.isPreset = true;
      configs.push_back(c);
    }
    if (configs.empty()) throw UsageError("nothing to run (--schemes and --presets both empty)");
  }

  // Phantoms vary a little in voxel size and obliquity (as the femur acceptance test does).
  const Eigen::Vector3d spacings[] = {{1.2, 1.2, 3}, {1, 1.5, 2.5}, {0.9, 0.9, 4}, {1.5, 1.5, 1.5}};
  const Eigen::Vector3d obliques[] = {{0, 0, 0}, {10, -15, 20}, {0, 0, 0}, {-20, 10, 5}, {0, 0, 30}};
  std::vector<TradeoffRow> rows;
  const Clock::time_point start = Clock::now();
  for (long k = 0; k < phantoms; ++k) {
    PhantomOptions po;
    po.seed = static_cast<uint32_t>(seed0 + k);
    po.spacing = spacings[k % 4];
    po.obliqueDegrees = obliques[k % 5];
    std::fprintf(stderr, "tradeoff: phantom %ld/%ld (seed %u, %gx%gx%g mm, oblique %g,%g,%g deg)\n", k + 1, phantoms,
                 po.seed, po.spacing[0], po.spacing[1], po.spacing[2], po.obliqueDegrees[0], po.obliqueDegrees[1],
                 po.obliqueDegrees[2]);
    const Phantom ph = makePhantom(po);
    for (size_t c = 0; c < configs.size(); ++c) {
      TradeoffRow row = runTradeoff(ph, po.seed, configs[c], static_cast<int>(threads));
      if (row.run.ok)
        std::fprintf(stderr,
                     "tradeoff:   %-28s %6.2f s (features %.2f, evolution %.2f; cpu %.2f)  %4d steps  Dice %.4f  "
                     "ASSD %.3f mm  peak %.0f MiB\n",
                     configs[c].name.c_str(), row.run.seconds, row.run.featureSeconds, row.run.evolutionSeconds,
                     row.run.cpuSeconds,
                     row.run.steps, row.run.dice, row.run.assdMm, row.peakRssMiB);
      else
        std::fprintf(stderr, "tradeoff:   %-28s failed: %s\n", configs[c].name.c_str(), row.run.error);
      rows.push_back(row);
    }
  }

  // Means per setting over the phantoms (failed runs count as missing; a setting with any failure is flagged).
  struct Mean {
    TradeoffConfig config;
    TradeoffRunResult first;
    double seconds = 0, cpu = 0, dice = 0, assd = 0, steps = 0, peak = 0;
    int ok = 0, failed = 0;
  };
  std::vector<Mean> means(configs.size());
  for (size_t c = 0; c < configs.size(); ++c) {
    means[c].config = configs[c];
    for (size_t r = c; r < rows.size(); r += configs.size()) {
      const TradeoffRow& row = rows[r];
      if (!row.run.ok) {
        ++means[c].failed;
        continue;
      }
      if (means[c].ok == 0) means[c].first = row.run;
      ++means[c].ok;
      means[c].seconds += row.run.seconds;
      means[c].cpu += row.run.cpuSeconds;
      means[c].dice += row.run.dice;
      means[c].assd += row.run.assdMm;
      means[c].steps += row.run.steps;
      means[c].peak = std::max(means[c].peak, row.peakRssMiB);
    }
    if (means[c].ok > 0) {
      const double n = means[c].ok;
      means[c].seconds /= n;
      means[c].cpu /= n;
      means[c].dice /= n;
      means[c].assd /= n;
      means[c].steps /= n;
    }
  }

  // Table.
  std::printf("speed/accuracy trade: femur of %ld thigh phantom(s) (seeds %ld..%ld), from the mean template; %.0f s in all\n",
              phantoms, seed0, seed0 + phantoms - 1, secondsSince(start));
  std::printf("%-26s %-21s %3s %5s %7s %3s %4s %9s %7s %7s %8s %8s %8s\n", "setting", "scheme", "lev", "steps", "tol mm",
              "sub", "iter", "steps run", "s/run", "cpu s", "Dice", "ASSD mm", "peak MiB");
  for (const Mean& m : means) {
    if (m.ok == 0) {
      std::printf("%-26s failed on every phantom\n", m.config.name.c_str());
      continue;
    }
    std::printf("%-26s %-21s %3d %5d %7.4f %3d %4d %9.1f %7.2f %7.2f %8.4f %8.3f %8.0f%s\n", m.config.name.c_str(),
                m.first.scheme, m.first.levels, m.first.maxSteps, m.first.toleranceMm, m.first.substeps,
                m.first.iterations, m.steps, m.seconds, m.cpu, m.dice, m.assd, m.peak,
                m.failed ? (" (" + std::to_string(m.failed) + " failed)").c_str() : "");
  }
  // The demands, checked on the means.
  const auto find = [&](const std::string& name) -> const Mean* {
    for (const Mean& m : means)
      if (m.config.name == name && m.ok > 0) return &m;
    return nullptr;
  };
  const Mean* fast = find("preset fast");
  const Mean* accurate = find("preset accurate");
  if (fast && accurate) {
    const double ratio = accurate->cpu / fast->cpu, wallRatio = accurate->seconds / fast->seconds;
    std::printf("check fast >= 5x faster than accurate (CPU time): %s (%.2f s vs %.2f s, %.1fx; wall %.2f s vs %.2f s, "
                "%.1fx)\n",
                ratio >= 5 ? "holds" : "NOT MET", fast->cpu, accurate->cpu, ratio, fast->seconds, accurate->seconds,
                wallRatio);
  } else {
    std::printf("check fast >= 5x faster than accurate: not run (needs both presets)\n");
  }
  if (!accurate) std::printf("check accurate at least as accurate as every row: not run (needs the accurate preset)\n");
  if (accurate) {
    const Mean* best = nullptr;
    for (const Mean& m : means)
      if (m.ok > 0 && &m != accurate && (!best || m.assd < best->assd)) best = &m;
    if (best)
      std::printf("check accurate at least as accurate as every row (ASSD): %s (accurate %.3f mm Dice %.4f; best other "
                  "%s %.3f mm Dice %.4f)\n",
                  accurate->assd <= best->assd ? "holds" : "NOT MET", accurate->assd, accurate->dice,
                  best->config.name.c_str(), best->assd, best->dice);
  }
  // Accuracy from fast to accurate (issue 5): on the mean over the phantoms, and for each step per phantom (paired:
  // the mean gain in ASSD, its t statistic, and on how many phantoms the slower preset is the more accurate).
  const Mean* balanced = find("preset balanced");
  if (fast && balanced && accurate) {
    const bool rises = fast->assd > balanced->assd && balanced->assd > accurate->assd;
    std::printf("check accuracy rises fast -> balanced -> accurate (mean ASSD): %s (%.3f -> %.3f -> %.3f mm; Dice "
                "%.4f -> %.4f -> %.4f)\n",
                rises ? "holds" : "NOT MET", fast->assd, balanced->assd, accurate->assd, fast->dice, balanced->dice,
                accurate->dice);
    const size_t nc = configs.size();
    for (const auto& [a, b] : {std::pair{fast, balanced}, std::pair{balanced, accurate}, std::pair{fast, accurate}}) {
      const size_t ca = static_cast<size_t>(a - means.data()), cb = static_cast<size_t>(b - means.data());
      std::vector<double> gain;  // ASSD of a minus ASSD of b, per phantom where both ran
      for (size_t k = 0; k + nc <= rows.size(); k += nc)
        if (rows[k + ca].run.ok && rows[k + cb].run.ok) gain.push_back(rows[k + ca].run.assdMm - rows[k + cb].run.assdMm);
      const double n = static_cast<double>(gain.size());
      double mean = 0, var = 0;
      for (double g : gain) mean += g / n;
      for (double g : gain) var += (g - mean) * (g - mean) / std::max(1.0, n - 1);
      const double se = std::sqrt(var / std::max(1.0, n));
      std::printf("  per phantom, %s -> %s: ASSD %.3f mm lower on average (paired t %.1f), lower on %ld of %zu "
                  "(largest rise %.3f mm)\n",
                  a->config.preset.c_str(), b->config.preset.c_str(), mean, se > 0 ? mean / se : 0.0,
                  std::count_if(gain.begin(), gain.end(), [](double g) { return g > 0; }), gain.size(),
                  gain.empty() ? 0.0 : std::max(0.0, -*std::min_element(gain.begin(), gain.end())));
    }
  }
  std::fflush(stdout);

  std::vector<TradeoffPoint> points;
  for (const Mean& m : means)
    if (m.ok > 0) points.push_back({m.config.name, m.cpu, m.assd, m.config.isPreset});
  writeFolderAtomically(out, [&](const std::string& staging) {
    const std::string csv = staging + "/tradeoff.csv";
    std::ofstream f(csv);
    if (!f) throw IoError(csv, "cannot write");
    f << "phantom,seed,setting,scheme,preset,levels,max_steps_per_level,tolerance_mm,substeps,iterations,steps,seconds,"
         "cpu_seconds,dice,assd_mm,peak_rss_mib,ok\n";
    char line[512];
    for (const TradeoffRow& r : rows) {
      std::snprintf(line, sizeof line, "%u,%u,%s,%s,%s,%d,%d,%.4f,%d,%d,%d,%.3f,%.3f,%.4f,%.4f,%.1f,%d\n", r.seed,
                    r.seed, r.config.name.c_str(), r.run.ok ? r.run.scheme : r.config.scheme.c_str(),
                    r.config.preset.c_str(), r.run.levels, r.run.maxSteps, r.run.toleranceMm, r.run.substeps,
                    r.run.iterations, r.run.steps, r.run.seconds, r.run.cpuSeconds, r.run.dice, r.run.assdMm,
                    r.peakRssMiB, r.run.ok);
      f << line;
    }
    for (const Mean& m : means) {
      if (m.ok == 0) continue;
      std::snprintf(line, sizeof line, "mean,,%s,%s,%s,%d,%d,%.4f,%d,%d,%.1f,%.3f,%.3f,%.4f,%.4f,%.1f,%d\n",
                    m.config.name.c_str(), m.first.scheme, m.config.preset.c_str(), m.first.levels, m.first.maxSteps,
                    m.first.toleranceMm, m.first.substeps, m.first.iterations, m.steps, m.seconds, m.cpu, m.dice,
                    m.assd, m.peak, m.failed == 0 ? 1 : 0);
      f << line;
    }
    f.close();
    if (!f) throw IoError(csv, "write failed");
    char title[160];
    std::snprintf(title, sizeof title, "femur, %ld phantom(s): mean mesh ASSD vs mean CPU time per run", phantoms);
    writeTradeoffPlot(staging + "/tradeoff.png", points, title, "CPU time per run (s, log scale)",
                      "mesh ASSD to truth (mm)");
  });
  std::printf("written %s/tradeoff.csv and %s/tradeoff.png\n", out.c_str(), out.c_str());
  return 0;
}

struct Subcommand {
  std::function<int(const std::vector<std::string>&)> run;
  const char* summary;
};

const std::map<std::string, Subcommand>& subcommands() {
  static const std::map<std::string, Subcommand> table = {
      {"scene", {benchScene, "segment a synthetic multi-structure phantom scene; time per stage, accuracy, memory"}},
      {"tradeoff", {benchTradeoff, "every scheme and preset on N phantoms: time vs accuracy CSV and plot"}},
  };
  return table;
}

void printBenchHelp() {
  std::cout << "usage: mskseg bench <benchmark> [options]     (mskseg bench <benchmark> --help for its options)\n\n"
               "benchmarks:\n";
  for (const auto& [name, sub] : subcommands()) std::printf("  %-10s %s\n", name.c_str(), sub.summary);
}

}  // namespace

int cmdBench(const std::vector<std::string>& args) {
  if (args.empty()) throw UsageError("missing benchmark name (one of: scene, tradeoff)");
  if (args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    printBenchHelp();
    return 0;
  }
  const auto it = subcommands().find(args[0]);
  if (it == subcommands().end()) throw UsageError("unknown benchmark '" + args[0] + "'");
  return it->second.run(std::vector<std::string>(args.begin() + 1, args.end()));
}

}  // namespace msk::cli
