#include "msk/bench/tradeoff_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "msk/core/error.h"
#include "msk/segmentation/png_file.h"
#include "plot_drawing.h"

namespace msk {

namespace {
bool usable(const TradeoffPoint& p) { return std::isfinite(p.seconds) && p.seconds > 0 && std::isfinite(p.error); }
using plot::text;
using plot::tickStep;
}  // namespace

std::vector<size_t> paretoFront(const std::vector<TradeoffPoint>& points) {
  std::vector<size_t> front;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!usable(points[i])) continue;
    bool dominated = false;
    for (size_t j = 0; j < points.size() && !dominated; ++j)
      if (j != i && usable(points[j]))
        dominated = points[j].seconds <= points[i].seconds && points[j].error <= points[i].error &&
                    (points[j].seconds < points[i].seconds || points[j].error < points[i].error);
    if (!dominated) front.push_back(i);
  }
  std::sort(front.begin(), front.end(), [&](size_t a, size_t b) { return points[a].seconds < points[b].seconds; });
  return front;
}

void writeTradeoffPlot(const std::string& path, const std::vector<TradeoffPoint>& points, const std::string& title,
                       const std::string& timeLabel, const std::string& errorLabel) {
  std::vector<size_t> shown;
  for (size_t i = 0; i < points.size(); ++i)
    if (usable(points[i])) shown.push_back(i);
  if (shown.empty()) throw ParameterError("tradeoff plot", path, "needs a point with finite positive time and error");
  const int width = 900, height = 620, left = 80, right = 230, top = 50, bottom = 70;
  const int plotW = width - left - right, plotH = height - top - bottom;
  // Axes: log10 time (padded to whole decades' fractions), linear error from 0 (or the least error) up.
  double tMin = 1e300, tMax = -1e300, eMin = 1e300, eMax = -1e300;
  for (size_t i : shown) {
    tMin = std::min(tMin, std::log10(points[i].seconds));
    tMax = std::max(tMax, std::log10(points[i].seconds));
    eMin = std::min(eMin, points[i].error);
    eMax = std::max(eMax, points[i].error);
  }
  const double tPad = std::max(0.1, 0.08 * (tMax - tMin));
  tMin -= tPad;
  tMax += tPad;
  const double eSpan = std::max(1e-6, eMax - eMin);
  double eLo = std::max(0.0, eMin - 0.1 * eSpan), eHi = eMax + 0.1 * eSpan;
  if (eHi - eLo < 1e-9) eHi = eLo + 1e-3;
  auto px = [&](double seconds) {
    return left + static_cast<int>(std::lround((std::log10(seconds) - tMin) / (tMax - tMin) * plotW));
  };
  auto py = [&](double error) { return top + static_cast<int>(std::lround((eHi - error) / (eHi - eLo) * plotH)); };

  cv::Mat pic(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar grid(225, 225, 225), axis(0, 0, 0);
  // Time ticks at 1, 2, 5 × 10^k seconds inside the range.
  char buf[64];
  for (int k = static_cast<int>(std::floor(tMin)) - 1; k <= static_cast<int>(std::ceil(tMax)); ++k)
    for (double m : {1.0, 2.0, 5.0}) {
      const double s = m * std::pow(10.0, k), lg = std::log10(s);
      if (lg < tMin || lg > tMax) continue;
      const int x = px(s);
      cv::line(pic, {x, top}, {x, top + plotH}, grid, 1);
      cv::line(pic, {x, top + plotH}, {x, top + plotH + 5}, axis, 1);
      std::snprintf(buf, sizeof buf, "%g", s);
      text(pic, buf, {x - 10, top + plotH + 22});
    }
  const double eStep = tickStep(eHi - eLo, 6);
  for (double e = std::ceil(eLo / eStep) * eStep; e <= eHi + 1e-12; e += eStep) {
    const int y = py(e);
    cv::line(pic, {left, y}, {left + plotW, y}, grid, 1);
    cv::line(pic, {left - 5, y}, {left, y}, axis, 1);
    std::snprintf(buf, sizeof buf, "%.3g", e);
    text(pic, buf, {left - 55, y + 5});
  }
  cv::rectangle(pic, {left, top}, {left + plotW, top + plotH}, axis, 1);
  text(pic, timeLabel, {left + plotW / 2 - 120, height - 22}, 0.55);
  text(pic, errorLabel, {10, top - 8}, 0.5);
  text(pic, title, {10, 20}, 0.6);

  // Pareto front: a red line through its points, each ringed.
  const std::vector<size_t> front = paretoFront(points);
  const cv::Scalar red(40, 40, 220);
  for (size_t k = 1; k < front.size(); ++k)
    cv::line(pic, {px(points[front[k - 1]].seconds), py(points[front[k - 1]].error)},
             {px(points[front[k]].seconds), py(points[front[k]].error)}, red, 2, cv::LINE_AA);
  for (size_t i : front) cv::circle(pic, {px(points[i].seconds), py(points[i].error)}, 10, red, 2, cv::LINE_AA);

  // Markers, numbered; the legend on the right names each number.
  const cv::Scalar blue(180, 90, 30), green(40, 150, 40);
  int legendY = top + 10;
  for (size_t n = 0; n < shown.size(); ++n) {
    const TradeoffPoint& p = points[shown[n]];
    const cv::Point c(px(p.seconds), py(p.error));
    if (p.preset)
      cv::rectangle(pic, {c.x - 5, c.y - 5}, {c.x + 5, c.y + 5}, green, cv::FILLED);
    else
      cv::circle(pic, c, 5, blue, cv::FILLED, cv::LINE_AA);
    std::snprintf(buf, sizeof buf, "%zu", n + 1);
    text(pic, buf, {c.x + 8, c.y - 6}, 0.45);
    const bool onFront = std::find(front.begin(), front.end(), shown[n]) != front.end();
    std::snprintf(buf, sizeof buf, "%zu %s%s", n + 1, p.label.c_str(), onFront ? " *" : "");
    text(pic, buf, {left + plotW + 15, legendY}, 0.42, p.preset ? green : blue);
    legendY += 18;
  }
  legendY += 10;
  text(pic, "square: preset", {left + plotW + 15, legendY}, 0.42, green);
  text(pic, "circle: scheme", {left + plotW + 15, legendY + 18}, 0.42, blue);
  text(pic, "red, *: Pareto front", {left + plotW + 15, legendY + 36}, 0.42, red);

  writePngAtomically(path, pic);
}

}  // namespace msk
