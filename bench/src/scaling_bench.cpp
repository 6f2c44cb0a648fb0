#include "msk/bench/scaling_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>

#include "msk/bench/scene_bench.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/png_file.h"
#include "plot_drawing.h"

namespace msk {

namespace {

/// The stages drawn and tabled per vertex-step, in order, with their colours (BGR); short names for the table.
const char* shortName(const std::string& stage) {
  static const std::map<std::string, const char*> names = {{"segmentation", "total"},
                                                           {"evolution", "evolution"},
                                                           {"collision-detection", "collision"},
                                                           {"image-search", "search"},
                                                           {"constraint-projection", "projection"},
                                                           {"separation", "separation"}};
  return names.at(stage);
}

const std::vector<std::pair<std::string, cv::Scalar>>& stages() {
  static const std::vector<std::pair<std::string, cv::Scalar>> s = {{"segmentation", {0, 0, 0}},
                                                                    {"evolution", {180, 90, 30}},
                                                                    {"collision-detection", {40, 40, 220}},
                                                                    {"image-search", {40, 150, 40}},
                                                                    {"constraint-projection", {160, 60, 160}},
                                                                    {"separation", {0, 150, 220}}};
  return s;
}

double microsPerVertexStep(const ScalingPoint& p, const std::string& stage) {
  const auto it = p.seconds.find(stage);
  return it == p.seconds.end() || !(p.vertexSteps > 0) ? 0.0 : 1e6 * it->second / p.vertexSteps;
}

}  // namespace

TriangleMesh subdivideMidpoints(const TriangleMesh& mesh) {
  // Our own (a few lines): CGAL's subdivision methods move the old vertices (Loop, sqrt3), which would change the
  // anatomy the benchmark compares across resolutions.
  TriangleMesh out;
  const int nv = mesh.vertexCount(), nf = mesh.faceCount();
  std::map<std::pair<int, int>, int> midpoint;
  std::vector<Eigen::RowVector3d> added;
  auto mid = [&](int a, int b) {
    const std::pair<int, int> key(std::min(a, b), std::max(a, b));
    const auto it = midpoint.find(key);
    if (it != midpoint.end()) return it->second;
    const int index = nv + static_cast<int>(added.size());
    added.push_back(0.5 * (mesh.vertices.row(a) + mesh.vertices.row(b)));
    midpoint.emplace(key, index);
    return index;
  };
  out.faces.resize(4 * nf, 3);
  for (int f = 0; f < nf; ++f) {
    const int a = mesh.faces(f, 0), b = mesh.faces(f, 1), c = mesh.faces(f, 2);
    const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    out.faces.row(4 * f) << a, ab, ca;
    out.faces.row(4 * f + 1) << ab, b, bc;
    out.faces.row(4 * f + 2) << ca, bc, c;
    out.faces.row(4 * f + 3) << ab, bc, ca;
  }
  out.vertices.resize(nv + static_cast<int>(added.size()), 3);
  out.vertices.topRows(nv) = mesh.vertices;
  for (size_t i = 0; i < added.size(); ++i) out.vertices.row(nv + static_cast<int>(i)) = added[i];
  return out;
}

namespace {
/// One segmentation of the phantom from `scene`'s templates, timed per stage.
ScalingPoint measureRun(const Phantom& ph, const Scene& scene, const SegmentOptions& segment,
                        const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const SegmentationResult res = segmentScene(ph.image, scene, segment, progress);
  ScalingPoint p;
  p.segmentSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  p.seconds["segmentation"] = p.segmentSeconds;
  for (const char* stage : {"evolution", "collision-detection", "separation", "features"}) {
    const auto it = res.secondsPerStage.find(stage);
    p.seconds[stage] = it == res.secondsPerStage.end() ? 0.0 : it->second;
  }
  double search = 0, projection = 0, dice = 0;
  for (const ObjectResult& o : res.objects) {
    search += o.imageSearchSeconds;
    if (!o.levels.empty()) p.simplexVertices += o.levels.back().vertices;
    for (const LevelReport& l : o.levels) p.vertexSteps += static_cast<double>(l.vertices) * l.steps;
  }
  for (const auto& kv : res.secondsPerFamily) projection += kv.second;
  p.seconds["image-search"] = search;
  p.seconds["constraint-projection"] = projection;
  for (const PhantomObject& o : ph.objects) dice += labelMetrics(res.labels, o.label, ph.labels, o.label).dice;
  p.meanDice = ph.objects.empty() ? 0.0 : dice / static_cast<double>(ph.objects.size());
  p.peakRssMiB = processPeakRssMiB();
  return p;
}
}  // namespace

std::vector<ScalingPoint> runScalingBench(const ScalingBenchOptions& opts, const ProgressFn& progress) {
  if (opts.subdivisions < 0 || opts.subdivisions > 5)
    throw ParameterError("--subdivisions", std::to_string(opts.subdivisions), "must be 0..5");
  if (opts.repeat < 1 || opts.repeat > 20)
    throw ParameterError("--repeat", std::to_string(opts.repeat), "must be 1..20");
  const Phantom ph = makePhantom(opts.phantom, progress);
  Scene scene = phantomScene(ph);
  std::vector<ScalingPoint> points;
  for (int s = 0; s <= opts.subdivisions; ++s) {
    if (s > 0)
      for (SceneObject& o : scene.objects) o.templ = subdivideMidpoints(o.templ);
    ScalingPoint p;
    double slowest = 0;
    for (int run = 0; run < opts.repeat; ++run) {
      ScalingPoint q = measureRun(ph, scene, opts.segment, progress);
      q.subdivisions = s;
      slowest = std::max(slowest, q.segmentSeconds);
      if (run == 0 || q.segmentSeconds < p.segmentSeconds) p = q;
    }
    p.runs = opts.repeat;
    p.slowestSegmentSeconds = slowest;
    points.push_back(p);
  }
  return points;
}

void printScalingBench(const std::vector<ScalingPoint>& points) {
  std::printf("seconds of each stage per simplex vertex and step (us); memory: the peak's growth per added vertex\n");
  std::printf("%-6s %10s %12s %8s %8s", "subdiv", "vertices", "vertex-steps", "seg. s", "slowest");
  for (const auto& [stage, colour] : stages()) std::printf(" %10s", shortName(stage));
  std::printf(" %9s %10s %6s\n", "peak MiB", "KiB/vertex", "Dice");
  for (size_t i = 0; i < points.size(); ++i) {
    const ScalingPoint& p = points[i];
    std::printf("%-6d %10ld %12.0f %8.2f %8.2f", p.subdivisions, p.simplexVertices, p.vertexSteps, p.segmentSeconds,
                p.slowestSegmentSeconds);
    for (const auto& [stage, colour] : stages()) std::printf(" %10.3f", microsPerVertexStep(p, stage));
    if (i == 0 || p.simplexVertices <= points[i - 1].simplexVertices)
      std::printf(" %9.0f %10s %6.3f\n", p.peakRssMiB, "-", p.meanDice);
    else
      std::printf(" %9.0f %10.2f %6.3f\n", p.peakRssMiB,
                  1024.0 * (p.peakRssMiB - points[i - 1].peakRssMiB) /
                      static_cast<double>(p.simplexVertices - points[i - 1].simplexVertices),
                  p.meanDice);
  }
  if (points.size() >= 2) {
    const double first = microsPerVertexStep(points.front(), "evolution");
    const double last = microsPerVertexStep(points.back(), "evolution");
    std::printf("evolution per vertex-step at %ld vertices: %.2fx that at %ld (linear growth: 1x)",
                points.back().simplexVertices, first > 0 ? last / first : 0.0, points.front().simplexVertices);
    if (points.front().runs > 1) std::printf("; the fastest of %d runs at each size", points.front().runs);
    std::printf("\n");
  }
}

void writeScalingBench(const std::string& dir, const std::vector<ScalingPoint>& points, const std::string& title) {
  if (points.empty()) throw ParameterError("scaling plot", dir, "needs at least one run");
  // scaling.csv: one row per resolution.
  writeAtomically(dir + "/scaling.csv", [&](const std::string& tmp) {
    std::ofstream f(tmp);
    f << "subdivisions,simplex_vertices,vertex_steps";
    for (const auto& [stage, colour] : stages()) f << "," << stage << "_s," << stage << "_us_per_vertex_step";
    f << ",peak_rss_mib,mean_dice,runs,segmentation_s_slowest\n";
    f.precision(8);
    for (const ScalingPoint& p : points) {
      f << p.subdivisions << "," << p.simplexVertices << "," << p.vertexSteps;
      for (const auto& [stage, colour] : stages())
        f << "," << p.seconds.at(stage) << "," << microsPerVertexStep(p, stage);
      f << "," << p.peakRssMiB << "," << p.meanDice << "," << p.runs << "," << p.slowestSegmentSeconds << "\n";
    }
    if (!f.flush()) throw IoError(dir + "/scaling.csv", "cannot write");
  });
  // scaling.png: µs per vertex-step against vertices (log x), one line per stage.
  const int width = 900, height = 560, left = 80, right = 230, top = 50, bottom = 70;
  const int plotW = width - left - right, plotH = height - top - bottom;
  double xMin = 1e300, xMax = -1e300, yMax = 0;
  for (const ScalingPoint& p : points) {
    const double x = std::log10(std::max<double>(1, p.simplexVertices));
    xMin = std::min(xMin, x);
    xMax = std::max(xMax, x);
    for (const auto& [stage, colour] : stages()) yMax = std::max(yMax, microsPerVertexStep(p, stage));
  }
  if (xMax - xMin < 0.2) {
    xMin -= 0.1;
    xMax += 0.1;
  }
  yMax = yMax > 0 ? 1.1 * yMax : 1.0;
  auto px = [&](double vertices) {
    return left + static_cast<int>(std::lround((std::log10(std::max(1.0, vertices)) - xMin) / (xMax - xMin) * plotW));
  };
  auto py = [&](double us) { return top + static_cast<int>(std::lround((yMax - us) / yMax * plotH)); };
  cv::Mat pic(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar gridColour(225, 225, 225), axis(0, 0, 0);
  char buf[64];
  for (int k = static_cast<int>(std::floor(xMin)); k <= static_cast<int>(std::ceil(xMax)); ++k)
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, k);
      if (std::log10(v) < xMin - 1e-9 || std::log10(v) > xMax + 1e-9) continue;
      const int x = px(v);
      cv::line(pic, {x, top}, {x, top + plotH}, gridColour, 1);
      std::snprintf(buf, sizeof buf, "%g", v);
      plot::text(pic, buf, {x - 18, top + plotH + 22});
    }
  const double yStep = plot::tickStep(yMax, 6);
  for (double y = 0; y <= yMax + 1e-12; y += yStep) {
    cv::line(pic, {left, py(y)}, {left + plotW, py(y)}, gridColour, 1);
    std::snprintf(buf, sizeof buf, "%.3g", y);
    plot::text(pic, buf, {left - 50, py(y) + 5});
  }
  cv::rectangle(pic, {left, top}, {left + plotW, top + plotH}, axis, 1);
  plot::text(pic, "simplex vertices (all objects, finest level)", {left + plotW / 2 - 170, height - 22}, 0.55);
  plot::text(pic, "microseconds per vertex and step", {10, top - 8}, 0.5);
  plot::text(pic, title, {10, 20}, 0.6);
  int legendY = top + 10;
  for (const auto& [stage, colour] : stages()) {
    for (size_t i = 0; i < points.size(); ++i) {
      const cv::Point c(px(static_cast<double>(points[i].simplexVertices)), py(microsPerVertexStep(points[i], stage)));
      cv::circle(pic, c, 4, colour, cv::FILLED, cv::LINE_AA);
      if (i > 0)
        cv::line(
            pic,
            {px(static_cast<double>(points[i - 1].simplexVertices)), py(microsPerVertexStep(points[i - 1], stage))}, c,
            colour, 2, cv::LINE_AA);
    }
    cv::line(pic, {left + plotW + 15, legendY - 4}, {left + plotW + 35, legendY - 4}, colour, 2, cv::LINE_AA);
    plot::text(pic, stage, {left + plotW + 42, legendY}, 0.42, colour);
    legendY += 20;
  }
  plot::text(pic, "flat lines: linear growth", {left + plotW + 15, legendY + 10}, 0.42);
  writePngAtomically(dir + "/scaling.png", pic);
}

}  // namespace msk
