// mskseg bench: benchmarks that print figures (time per stage, accuracy, memory). One subcommand per benchmark,
// dispatched on the first positional word; `mskseg bench --help` lists them.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
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
        scene.collisions.push_back({static_cast<int>(a), static_cast<int>(b)});
    }
  return scene;
}

// Object indices of a collision pair (the scene's pair type is being extended with contact settings; this accepts
// both the plain index pair and the struct with members a, b).
[[maybe_unused]] std::pair<int, int> pairIndices(const std::pair<int, int>& p) { return p; }
template <class Pair>
std::pair<int, int> pairIndices(const Pair& p) {
  return {p.a, p.b};
}

// "a|b" names of the k-th collision pair.
std::string pairName(const Scene& scene, size_t k, const char* sep) {
  const auto [a, b] = pairIndices(scene.collisions[k]);
  return scene.objects[static_cast<size_t>(a)].name + sep + scene.objects[static_cast<size_t>(b)].name;
}

struct ObjectFigures {
  std::string name, kind;
  int label = 0;
  double dice = 0, assdMm = 0, meshAssdMm = 0, templateDice = 0;
};

void writeCsv(const std::string& path, const std::vector<ObjectFigures>& objects) {
  std::ofstream f(path);
  if (!f) throw IoError(path, "cannot write");
  f << "name,label,kind,dice,assd_mm,mesh_assd_mm,template_dice\n";
  char line[256];
  for (const ObjectFigures& o : objects) {
    std::snprintf(line, sizeof line, "%s,%d,%s,%.4f,%.3f,%.3f,%.4f\n", o.name.c_str(), o.label, o.kind.c_str(), o.dice,
                  o.assdMm, o.meshAssdMm, o.templateDice);
    f << line;
  }
  if (!f) throw IoError(path, "write failed");
}

int benchScene(const std::vector<std::string>& argv) {
  Args args(argv, {"structures", "quality", "seed", "out", "spacing", "vertices"}, {"help", "no-collisions"});
  if (args.has("help")) {
    std::cout << "usage: mskseg bench scene [--structures 24|4] [--quality fast|balanced|accurate] [--seed N]\n"
                 "                          [--spacing 1.2,1.2,3] [--vertices N] [--no-collisions] [--out DIR]\n\n"
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
    figures.push_back(f);
  }
  const double scoreSeconds = secondsSince(scoreStart);
  const double peak = peakRssMiB();

  std::map<std::string, double> families;
  for (const ObjectResult& o : res.objects)
    for (const auto& [family, s] : o.secondsPerFamily) families[family] += s;
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
  std::printf("\nprojection time per constraint family, summed over objects (s)\n");
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
  std::printf("\noverlap voxels: %zu\npenetration per pair (mm):", res.overlapVoxels);
  for (size_t k = 0; k < scene.collisions.size() && k < res.pairPenetrationMm.size(); ++k) {
    if (k % 4 == 0) std::printf("\n ");
    std::printf(" %s %.2f", pairName(scene, k, "|").c_str(), res.pairPenetrationMm[k]);
    deepest = std::max(deepest, res.pairPenetrationMm[k]);
  }
  std::printf("\n  deepest %.2f mm\n", deepest);
  std::fflush(stdout);

  if (!out.empty()) {
    Json j = Json::object();
    j["structures"] = static_cast<int>(scene.objects.size());
    j["collision_pairs"] = static_cast<int>(scene.collisions.size());
    j["seed"] = static_cast<unsigned long>(popts.seed);
    j["quality"] = qualityName(sopts.quality);
    j["collisions"] = sopts.collisions;
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
      objs.push(std::move(o));
    }
    j["objects"] = std::move(objs);
    Json pairs = Json::array();
    for (size_t k = 0; k < scene.collisions.size() && k < res.pairPenetrationMm.size(); ++k) {
      Json p = Json::object();
      const auto [a, b] = pairIndices(scene.collisions[k]);
      p["a"] = scene.objects[static_cast<size_t>(a)].name;
      p["b"] = scene.objects[static_cast<size_t>(b)].name;
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

struct Subcommand {
  std::function<int(const std::vector<std::string>&)> run;
  const char* summary;
};

const std::map<std::string, Subcommand>& subcommands() {
  static const std::map<std::string, Subcommand> table = {
      {"scene", {benchScene, "segment a synthetic multi-structure phantom scene; time per stage, accuracy, memory"}},
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
  if (args.empty()) throw UsageError("missing benchmark name (one of: scene)");
  if (args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    printBenchHelp();
    return 0;
  }
  const auto it = subcommands().find(args[0]);
  if (it == subcommands().end()) throw UsageError("unknown benchmark '" + args[0] + "'");
  return it->second.run(std::vector<std::string>(args.begin() + 1, args.end()));
}

}  // namespace msk::cli
