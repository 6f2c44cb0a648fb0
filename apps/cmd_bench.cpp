// mskseg bench: benchmarks that print figures (time per stage, accuracy, memory), one subcommand per benchmark; the
// benchmarks themselves are in msk::bench.
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "msk/bench/scaling_bench.h"
#include "msk/bench/scene_bench.h"
#include "msk/bench/tradeoff_bench.h"
#include "msk/phantom/multi_phantom.h"

namespace msk::cli {

namespace {

/// Comma-separated words.
std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

int benchScene(CLI::App& app, const std::vector<std::string>& argv) {
  SceneBenchOptions o;
  std::string out;
  app.add_option("--structures", o.structures,
                 "24: both thighs and lower legs, 4 bones + 20 muscles (default); 4: the thigh");
  app.add_option_function<std::string>(
      "--quality", [&o](const std::string& s) { o.segment.evolution.quality = parseQuality(s); },
      "segmentation preset (default balanced)");
  app.add_option("--seed", o.phantom.seed, "phantom seed (default 1)");
  addVec3(app, "--spacing", o.phantom.spacing, "voxel size in mm (default 1.2,1.2,3)");
  app.add_option("--vertices", o.phantom.meshVertices, "vertices of each template and truth mesh (default 3000)");
  app.add_option("--threads", o.segment.evolution.threads,
                 "threads of collision detection and the parallel schemes (default 1; 0 = all cores)");
  app.add_flag_function(
      "--no-collisions", [&o](std::int64_t) { o.segment.collision.enabled = false; }, "ignore the collision pairs");
  app.add_option("--out", out,
                 "also write bench.json, objects.csv, the result label map (labels.nii.gz) and surfaces "
                 "(result_<name>.vtk, LPS) into DIR, atomically; `mskseg phantom --structures N --seed S` writes the "
                 "matching image, truth and templates");
  if (!parseArgs(app, argv)) return 0;
  checkPhantomOptions(o.phantom);
  checkSegmentOptions(o.segment);
  if (!out.empty()) checkOutputFolder(out);
  const SceneBenchFigures f = runSceneBench(o, stderrProgress("bench scene"));
  printSceneBench(f);
  if (!out.empty()) {
    writeFolderAtomically(out, [&](const std::string& staging) { writeSceneBench(staging, f); });
    std::cout << "figures written to " << out << " (bench.json, objects.csv, labels.nii.gz, result_<name>.vtk)\n";
  }
  return 0;
}

int benchScaling(CLI::App& app, const std::vector<std::string>& argv) {
  ScalingBenchOptions o;
  o.segment.evolution.quality = Quality::Fast;
  o.phantom.meshVertices = 1500;
  std::string out, quality = "fast";
  app.add_option("--subdivisions", o.subdivisions,
                 "runs with the templates subdivided 0..N times (x4 vertices each), 0..5 (default 3: about 1.2e4 to "
                 "7.7e5 simplex vertices)");
  app.add_option("--quality", quality, "segmentation preset (default fast)")
      ->check(CLI::IsMember({"fast", "balanced", "accurate"}));
  app.add_option("--vertices", o.phantom.meshVertices, "vertices of each template before subdivision (default 1500)");
  app.add_option("--seed", o.phantom.seed, "phantom seed (default 1)");
  app.add_option("--threads", o.segment.evolution.threads, "threads of the run (default 1; 0 = all cores)");
  app.add_option("--repeat", o.repeat,
                 "runs at each resolution, 1..20 (default 1): the fastest run's figures are kept, the slowest run's "
                 "seconds shown beside them");
  app.add_option("--out", out, "also write scaling.csv and scaling.png into DIR, atomically");
  app.footer(
      "The bundled thigh's anatomy (the 4-structure phantom) segmented at each resolution; prints each stage's seconds "
      "over the run's vertex-steps (simplex vertices x steps, summed over objects and levels; the separation, done "
      "once, divided the same way), the peak memory per vertex and the mean Dice, and how the evolution's cost per "
      "vertex-step at the largest size compares with the smallest (1x: linear growth).");
  if (!parseArgs(app, argv)) return 0;
  o.segment.evolution.quality = parseQuality(quality);
  checkPhantomOptions(o.phantom);
  checkSegmentOptions(o.segment);
  if (o.subdivisions < 0 || o.subdivisions > 5)
    throw ParameterError("--subdivisions", std::to_string(o.subdivisions), "must be 0..5");
  if (o.repeat < 1 || o.repeat > 20) throw ParameterError("--repeat", std::to_string(o.repeat), "must be 1..20");
  if (!out.empty()) checkOutputFolder(out);
  const std::vector<ScalingPoint> points = runScalingBench(o, stderrProgress("bench scaling"));
  printScalingBench(points);
  if (!out.empty()) {
    const std::string title = "mskseg bench scaling: thigh phantom, " + quality + ", " +
                              std::to_string(o.segment.evolution.threads) + " thread(s)" +
                              (o.repeat > 1 ? ", fastest of " + std::to_string(o.repeat) + " runs" : "");
    writeFolderAtomically(out, [&](const std::string& staging) { writeScalingBench(staging, points, title); });
    std::cout << "written " << out << "/scaling.csv and " << out << "/scaling.png\n";
  }
  return 0;
}

int benchTradeoff(CLI::App& app, const std::vector<std::string>& argv) {
  int phantoms = 0, threads = 1;
  long seed = 1;
  std::string out, schemes, presets = "fast,balanced,accurate";
  for (const std::string& s : tradeoffSchemes()) schemes += (schemes.empty() ? "" : ",") + s;
  app.add_option("--phantoms", phantoms, "number of phantoms, 1..50")->required();
  app.add_option("--out", out, "output folder: tradeoff.csv and tradeoff.png")->required();
  app.add_option("--seed", seed, "first phantom seed (default 1)");
  app.add_option("--threads", threads, "threads of the coloured, Jacobi and CG schemes (default 1)");
  app.add_option("--schemes", schemes, "schemes to run, comma-separated, or none (default: all)");
  app.add_option("--presets", presets, "presets to run, comma-separated, or none (default fast,balanced,accurate)");
  app.footer(
      "tradeoff.csv: one row per run and one mean row per setting: scheme, preset, levels, steps cap, tolerance, "
      "substeps, iterations, steps taken, wall and CPU seconds of the segmentation, Dice, mesh ASSD to the truth "
      "surface, peak memory of the run. tradeoff.png: mean ASSD against mean CPU time per setting, the Pareto front "
      "marked. Prints the table and checks that fast is >= 5x faster than accurate (CPU time) and accurate the most "
      "accurate, and how accuracy rises fast -> balanced -> accurate.");
  if (!parseArgs(app, argv)) return 0;
  if (phantoms < 1 || phantoms > 50) throw ParameterError("--phantoms", std::to_string(phantoms), "must be 1..50");
  if (seed < 0 || seed + phantoms > 0xffffffffL)
    throw ParameterError("--seed", std::to_string(seed), "must be in [0, 2^32 - N)");
  if (threads < 0 || threads > 1024) throw ParameterError("--threads", std::to_string(threads), "must be 0..1024");
  const std::vector<TradeoffConfig> configs = tradeoffConfigs(splitList(schemes), splitList(presets));
  if (configs.empty()) throw UsageError("nothing to run (--schemes and --presets both empty)");
  checkOutputFolder(out);
  const TradeoffFigures f = runTradeoffBench(phantoms, static_cast<uint32_t>(seed), threads, configs);
  printTradeoffBench(f);
  writeFolderAtomically(out, [&](const std::string& staging) { writeTradeoffBench(staging, f); });
  std::cout << "written " << out << "/tradeoff.csv and " << out << "/tradeoff.png\n";
  return 0;
}

}  // namespace

int cmdBench(const std::vector<std::string>& argv) {
  struct Benchmark {
    int (*run)(CLI::App&, const std::vector<std::string>&);
    const char* description;
  };
  const std::map<std::string, Benchmark> benchmarks = {
      {"scene",
       {benchScene,
        "Generates a synthetic phantom scene (24: both thighs and lower legs; 4: the thigh), segments it from its "
        "mean-anatomy templates with the scene's collision pairs and prints the time per stage, the projection time "
        "per constraint family, the peak memory, per-object Dice and ASSD against the exact labels and truth meshes, "
        "overlapping voxels and per-pair penetration."}},
      {"scaling",
       {benchScaling,
        "How the cost grows with resolution: the thigh phantom segmented from its templates subdivided 0..N times; "
        "time per stage per vertex and step, peak memory per vertex, a plot."}},
      {"tradeoff",
       {benchTradeoff,
        "The speed/accuracy trade: generates N thigh phantoms (seeds S..S+N-1, voxel size and grid obliquity varied), "
        "segments the femur of each from its mean template with every scheme (on the balanced schedule) and every "
        "preset, each run in a child process, and writes the figures into OUT."}},
  };
  if (argv.empty()) throw UsageError("missing benchmark name (one of: scaling, scene, tradeoff)");
  if (argv[0] == "--help" || argv[0] == "-h" || argv[0] == "help") {
    std::cout << "Usage: mskseg bench <benchmark> [OPTIONS]   (mskseg bench <benchmark> --help for its options)\n\n"
                 "Benchmarks:\n";
    for (const auto& [name, b] : benchmarks) std::cout << "  " << name << ": " << b.description << "\n";
    return 0;
  }
  const auto it = benchmarks.find(argv[0]);
  if (it == benchmarks.end())
    throw UsageError("unknown benchmark '" + argv[0] + "' (one of: scaling, scene, tradeoff)");
  CommandLine app("bench " + it->first, it->second.description);
  return it->second.run(app, std::vector<std::string>(argv.begin() + 1, argv.end()));
}

}  // namespace msk::cli
