#pragma once
/// The speed/accuracy trade as a picture: error against time, one marker per setting, the Pareto front drawn
/// (`mskseg bench tradeoff`).
#include <string>
#include <vector>

namespace msk {

/// One setting's averaged figures.
struct TradeoffPoint {
  std::string label;    ///< e.g. "xpbd 2x2" or "preset fast"
  double seconds = 0;   ///< mean time per run, s (wall or CPU)
  double error = 0;     ///< mean error (lower is better), e.g. ASSD in mm
  bool preset = false;  ///< drawn as a filled square instead of a circle
};

/// Indices of the points no other point beats in both time and error (ties kept), by increasing time.
std::vector<size_t> paretoFront(const std::vector<TradeoffPoint>& points);

/// Writes a PNG (atomically): time on a log x axis (`timeLabel`), error on y (`errorLabel`), one numbered marker per
/// point named in a legend, the Pareto front joined by a line and its markers ringed. Throws IoError if the file
/// cannot be written, ParameterError if no point has a finite positive time and a finite error.
void writeTradeoffPlot(const std::string& path, const std::vector<TradeoffPoint>& points, const std::string& title,
                       const std::string& timeLabel, const std::string& errorLabel);

}  // namespace msk
