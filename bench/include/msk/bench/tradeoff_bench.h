#pragma once
/// The speed/accuracy trade (`mskseg bench tradeoff`): the femur of N thigh phantoms segmented from its mean template
/// with every scheme on the balanced schedule and every preset, each run in a child process of its own.
#include <cstdint>
#include <string>
#include <vector>

namespace msk {

/// One setting of the trade: a scheme on the balanced schedule, or a preset as shipped.
struct TradeoffConfig {
  std::string name;                  ///< "xpbd 2x2", "preset fast"
  std::string scheme;                ///< scheme name, or "" for the preset's own
  std::string preset;                ///< fast | balanced | accurate
  int substeps = 0, iterations = 0;  ///< 0 = the preset's
  bool isPreset = false;
};

/// The settings to compare: the schemes named in `schemes` (scheme names; "none" for none) on the balanced schedule at
/// the substeps × iterations each needs, then the presets named in `presets`. Throws ParameterError for an unknown
/// name.
std::vector<TradeoffConfig> tradeoffConfigs(const std::vector<std::string>& schemes,
                                            const std::vector<std::string>& presets);

/// Every scheme's name, in the order tradeoffConfigs() lists them.
std::vector<std::string> tradeoffSchemes();

/// What one run measured (sent back from its child process).
struct TradeoffRun {
  int ok = 0;
  int steps = 0, levels = 0, maxSteps = 0, substeps = 0, iterations = 0;
  double seconds = 0, dice = 0, assdMm = 0, toleranceMm = 0;
  double featureSeconds = 0, evolutionSeconds = 0;  ///< image features; evolution (collision detection included)
  double cpuSeconds = 0;  ///< CPU time of segmentScene (all threads): robust to other load on a shared machine
  char scheme[32] = {0};
  char error[256] = {0};
};

/// One run of one setting on one phantom.
struct TradeoffRow {
  TradeoffConfig config;
  uint32_t seed = 0;
  TradeoffRun run;
  double peakRssMiB = 0;  ///< of the run's child process (phantom included)
};

/// One setting's means over the phantoms (failed runs count as missing).
struct TradeoffMean {
  TradeoffConfig config;
  TradeoffRun first;  ///< its first successful run (schedule, scheme)
  double seconds = 0, cpu = 0, dice = 0, assd = 0, steps = 0, peak = 0;
  int ok = 0, failed = 0;
};

/// What the trade measured.
struct TradeoffFigures {
  int phantoms = 0;
  uint32_t firstSeed = 1;
  std::vector<TradeoffConfig> configs;
  std::vector<TradeoffRow> rows;    ///< phantom after phantom, each with every setting in `configs` order
  std::vector<TradeoffMean> means;  ///< per setting
  double seconds = 0;               ///< the whole benchmark, wall
};

/// Runs every setting on `phantoms` phantoms (seeds firstSeed.., voxel size and grid obliquity varied), with
/// `threads` threads for the parallel schemes; progress on stderr.
TradeoffFigures runTradeoffBench(int phantoms, uint32_t firstSeed, int threads,
                                 const std::vector<TradeoffConfig>& configs);

/// The table and the checks on the means (fast ≥ 5× faster than accurate on CPU time; accurate the most accurate;
/// accuracy rising fast → balanced → accurate, with paired figures per phantom) on stdout.
void printTradeoffBench(const TradeoffFigures& f);

/// tradeoff.csv (every run and each setting's mean) and tradeoff.png (mean ASSD against mean CPU time, the Pareto
/// front marked) into the existing folder `dir`.
void writeTradeoffBench(const std::string& dir, const TradeoffFigures& f);

}  // namespace msk
