#include "msk/bench/tradeoff_bench.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "msk/bench/scene_bench.h"
#include "msk/bench/tradeoff_plot.h"
#include "msk/core/error.h"
#include "msk/phantom/phantom.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/segmenter.h"

namespace msk {

namespace {

// Runs one configuration on one phantom in a forked child, so each run's peak memory is its own (wait4's
// ru_maxrss; the child starts as a copy of this process, phantom included). Time is segmentScene's own.
TradeoffRow runOne(const Phantom& ph, uint32_t seed, const TradeoffConfig& config, int threads) {
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
    TradeoffRun r;
    try {
      Scene scene;
      scene.path = "(generated phantom: femur)";
      SceneObject femur;
      femur.name = ph.objects[0].name;
      femur.label = ph.objects[0].label;
      femur.kind = ObjectKind::Bone;
      femur.templ = ph.objects[0].templ;
      femur.model = defaultModel(femur.kind);
      scene.objects.push_back(femur);
      SegmentOptions o;
      o.evolution.quality = parseQuality(config.preset);
      if (!config.scheme.empty()) o.evolution.scheme = parseScheme(config.scheme);
      o.evolution.substeps = config.substeps;
      o.evolution.iterations = config.iterations;
      o.evolution.threads = threads;
      const double cpu0 = processCpuSeconds();
      const SegmentationResult res = segmentScene(ph.image, scene, o);
      r.cpuSeconds = processCpuSeconds() - cpu0;
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
    row.run = TradeoffRun{};
    std::snprintf(row.run.error, sizeof row.run.error, "run ended abnormally (status %d)", status);
  }
  return row;
}

}  // namespace

std::vector<std::string> tradeoffSchemes() {
  return {"gauss-seidel", "coloured-gauss-seidel", "jacobi", "xpbd", "explicit", "implicit"};
}

std::vector<TradeoffConfig> tradeoffConfigs(const std::vector<std::string>& schemes,
                                            const std::vector<std::string>& presets) {
  // The schemes on the balanced schedule (2 levels x 50 steps), each at the substeps x iterations it needs.
  const std::vector<TradeoffConfig> all = {
      {"gauss-seidel 1x1", "gauss-seidel", "balanced", 1, 1, false},
      {"coloured-gauss-seidel 1x1", "coloured-gauss-seidel", "balanced", 1, 1, false},
      {"jacobi 1x2", "jacobi", "balanced", 1, 2, false},
      {"xpbd 2x2", "xpbd", "balanced", 2, 2, false},
      {"explicit 4x1", "explicit", "balanced", 4, 1, false},
      {"implicit 1x1", "implicit", "balanced", 1, 1, false}};
  std::vector<TradeoffConfig> configs;
  for (const std::string& s : schemes) {
    if (s == "none") continue;
    const std::string name = schemeName(parseScheme(s));  // validates (ParameterError names the choices)
    for (const TradeoffConfig& c : all)
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
  return configs;
}

TradeoffFigures runTradeoffBench(int phantoms, uint32_t firstSeed, int threads,
                                 const std::vector<TradeoffConfig>& configs) {
  TradeoffFigures f;
  f.phantoms = phantoms;
  f.firstSeed = firstSeed;
  f.configs = configs;
  const auto start = std::chrono::steady_clock::now();
  // Phantoms vary a little in voxel size and obliquity (as the femur acceptance test does).
  const Eigen::Vector3d spacings[] = {{1.2, 1.2, 3}, {1, 1.5, 2.5}, {0.9, 0.9, 4}, {1.5, 1.5, 1.5}};
  const Eigen::Vector3d obliques[] = {{0, 0, 0}, {10, -15, 20}, {0, 0, 0}, {-20, 10, 5}, {0, 0, 30}};
  for (int k = 0; k < phantoms; ++k) {
    PhantomOptions po;
    po.seed = firstSeed + static_cast<uint32_t>(k);
    po.spacing = spacings[k % 4];
    po.obliqueDegrees = obliques[k % 5];
    std::fprintf(stderr, "tradeoff: phantom %d/%d (seed %u, %gx%gx%g mm, oblique %g,%g,%g deg)\n", k + 1, phantoms,
                 po.seed, po.spacing[0], po.spacing[1], po.spacing[2], po.obliqueDegrees[0], po.obliqueDegrees[1],
                 po.obliqueDegrees[2]);
    const Phantom ph = makePhantom(po);
    for (size_t c = 0; c < configs.size(); ++c) {
      TradeoffRow row = runOne(ph, po.seed, configs[c], threads);
      if (row.run.ok)
        std::fprintf(stderr,
                     "tradeoff:   %-28s %6.2f s (features %.2f, evolution %.2f; cpu %.2f)  %4d steps  Dice %.4f  "
                     "ASSD %.3f mm  peak %.0f MiB\n",
                     configs[c].name.c_str(), row.run.seconds, row.run.featureSeconds, row.run.evolutionSeconds,
                     row.run.cpuSeconds, row.run.steps, row.run.dice, row.run.assdMm, row.peakRssMiB);
      else
        std::fprintf(stderr, "tradeoff:   %-28s failed: %s\n", configs[c].name.c_str(), row.run.error);
      f.rows.push_back(row);
    }
  }
  // Means per setting over the phantoms (failed runs count as missing; a setting with any failure is flagged).
  std::vector<TradeoffMean>& means = f.means;
  means.resize(configs.size());
  for (size_t c = 0; c < configs.size(); ++c) {
    means[c].config = configs[c];
    for (size_t r = c; r < f.rows.size(); r += configs.size()) {
      const TradeoffRow& row = f.rows[r];
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
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

void printTradeoffBench(const TradeoffFigures& f) {
  // Table.
  std::printf(
      "speed/accuracy trade: femur of %d thigh phantom(s) (seeds %u..%u), from the mean template; %.0f s in all\n",
      f.phantoms, f.firstSeed, f.firstSeed + static_cast<uint32_t>(f.phantoms) - 1, f.seconds);
  std::printf("%-26s %-21s %3s %5s %7s %3s %4s %9s %7s %7s %8s %8s %8s\n", "setting", "scheme", "lev", "steps",
              "tol mm", "sub", "iter", "steps run", "s/run", "cpu s", "Dice", "ASSD mm", "peak MiB");
  for (const TradeoffMean& m : f.means) {
    if (m.ok == 0) {
      std::printf("%-26s failed on every phantom\n", m.config.name.c_str());
      continue;
    }
    std::printf("%-26s %-21s %3d %5d %7.4f %3d %4d %9.1f %7.2f %7.2f %8.4f %8.3f %8.0f%s\n", m.config.name.c_str(),
                m.first.scheme, m.first.levels, m.first.maxSteps, m.first.toleranceMm, m.first.substeps,
                m.first.iterations, m.steps, m.seconds, m.cpu, m.dice, m.assd, m.peak,
                m.failed ? (" (" + std::to_string(m.failed) + " failed)").c_str() : "");
  }
  // The presets' promises, checked on the means.
  const auto find = [&](const std::string& name) -> const TradeoffMean* {
    for (const TradeoffMean& m : f.means)
      if (m.config.name == name && m.ok > 0) return &m;
    return nullptr;
  };
  const TradeoffMean* fast = find("preset fast");
  const TradeoffMean* accurate = find("preset accurate");
  if (fast && accurate) {
    const double ratio = accurate->cpu / fast->cpu, wallRatio = accurate->seconds / fast->seconds;
    std::printf(
        "check fast >= 5x faster than accurate (CPU time): %s (%.2f s vs %.2f s, %.1fx; wall %.2f s vs %.2f s, "
        "%.1fx)\n",
        ratio >= 5 ? "holds" : "NOT MET", fast->cpu, accurate->cpu, ratio, fast->seconds, accurate->seconds, wallRatio);
  } else {
    std::printf("check fast >= 5x faster than accurate: not run (needs both presets)\n");
  }
  if (!accurate) std::printf("check accurate at least as accurate as every row: not run (needs the accurate preset)\n");
  if (accurate) {
    const TradeoffMean* best = nullptr;
    for (const TradeoffMean& m : f.means)
      if (m.ok > 0 && &m != accurate && (!best || m.assd < best->assd)) best = &m;
    if (best)
      std::printf(
          "check accurate at least as accurate as every row (ASSD): %s (accurate %.3f mm Dice %.4f; best other "
          "%s %.3f mm Dice %.4f)\n",
          accurate->assd <= best->assd ? "holds" : "NOT MET", accurate->assd, accurate->dice, best->config.name.c_str(),
          best->assd, best->dice);
  }
  // Accuracy from fast to accurate: on the mean over the phantoms, and for each step per phantom (paired:
  // the mean gain in ASSD, its t statistic, and on how many phantoms the slower preset is the more accurate).
  const TradeoffMean* balanced = find("preset balanced");
  if (fast && balanced && accurate) {
    const bool rises = fast->assd > balanced->assd && balanced->assd > accurate->assd;
    std::printf(
        "check accuracy rises fast -> balanced -> accurate (mean ASSD): %s (%.3f -> %.3f -> %.3f mm; Dice "
        "%.4f -> %.4f -> %.4f)\n",
        rises ? "holds" : "NOT MET", fast->assd, balanced->assd, accurate->assd, fast->dice, balanced->dice,
        accurate->dice);
    const size_t nc = f.configs.size();
    for (const auto& [a, b] : {std::pair{fast, balanced}, std::pair{balanced, accurate}, std::pair{fast, accurate}}) {
      const size_t ca = static_cast<size_t>(a - f.means.data()), cb = static_cast<size_t>(b - f.means.data());
      std::vector<double> gain;  // ASSD of a minus ASSD of b, per phantom where both ran
      for (size_t k = 0; k + nc <= f.rows.size(); k += nc)
        if (f.rows[k + ca].run.ok && f.rows[k + cb].run.ok)
          gain.push_back(f.rows[k + ca].run.assdMm - f.rows[k + cb].run.assdMm);
      const double n = static_cast<double>(gain.size());
      double mean = 0, var = 0;
      for (double g : gain) mean += g / n;
      for (double g : gain) var += (g - mean) * (g - mean) / std::max(1.0, n - 1);
      const double se = std::sqrt(var / std::max(1.0, n));
      std::printf(
          "  per phantom, %s -> %s: ASSD %.3f mm lower on average (paired t %.1f), lower on %ld of %zu "
          "(largest rise %.3f mm)\n",
          a->config.preset.c_str(), b->config.preset.c_str(), mean, se > 0 ? mean / se : 0.0,
          std::count_if(gain.begin(), gain.end(), [](double g) { return g > 0; }), gain.size(),
          gain.empty() ? 0.0 : std::max(0.0, -*std::min_element(gain.begin(), gain.end())));
    }
  }
  std::fflush(stdout);
}

void writeTradeoffBench(const std::string& dir, const TradeoffFigures& f) {
  std::vector<TradeoffPoint> points;
  for (const TradeoffMean& m : f.means)
    if (m.ok > 0) points.push_back({m.config.name, m.cpu, m.assd, m.config.isPreset});
  {
    const std::string csv = dir + "/tradeoff.csv";
    std::ofstream file(csv);
    if (!file) throw IoError(csv, "cannot write");
    file << "phantom,seed,setting,scheme,preset,levels,max_steps_per_level,tolerance_mm,substeps,iterations,steps,"
            "seconds,"
            "cpu_seconds,dice,assd_mm,peak_rss_mib,ok\n";
    char line[512];
    for (const TradeoffRow& r : f.rows) {
      std::snprintf(line, sizeof line, "%u,%u,%s,%s,%s,%d,%d,%.4f,%d,%d,%d,%.3f,%.3f,%.4f,%.4f,%.1f,%d\n", r.seed,
                    r.seed, r.config.name.c_str(), r.run.ok ? r.run.scheme : r.config.scheme.c_str(),
                    r.config.preset.c_str(), r.run.levels, r.run.maxSteps, r.run.toleranceMm, r.run.substeps,
                    r.run.iterations, r.run.steps, r.run.seconds, r.run.cpuSeconds, r.run.dice, r.run.assdMm,
                    r.peakRssMiB, r.run.ok);
      file << line;
    }
    for (const TradeoffMean& m : f.means) {
      if (m.ok == 0) continue;
      std::snprintf(line, sizeof line, "mean,,%s,%s,%s,%d,%d,%.4f,%d,%d,%.1f,%.3f,%.3f,%.4f,%.4f,%.1f,%d\n",
                    m.config.name.c_str(), m.first.scheme, m.config.preset.c_str(), m.first.levels, m.first.maxSteps,
                    m.first.toleranceMm, m.first.substeps, m.first.iterations, m.steps, m.seconds, m.cpu, m.dice,
                    m.assd, m.peak, m.failed == 0 ? 1 : 0);
      file << line;
    }
    file.close();
    if (!file) throw IoError(csv, "write failed");
    char title[160];
    std::snprintf(title, sizeof title, "femur, %d phantom(s): mean mesh ASSD vs mean CPU time per run", f.phantoms);
    writeTradeoffPlot(dir + "/tradeoff.png", points, title, "CPU time per run (s, log scale)",
                      "mesh ASSD to truth (mm)");
  }
}

}  // namespace msk
