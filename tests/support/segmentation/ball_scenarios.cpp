#include "msk/test/ball_scenarios.h"

#include <algorithm>
#include <cmath>

#include "msk/test/volumes.h"

namespace msk::test {

Grid boxGrid(const Eigen::Vector3d& spacing, const Eigen::Vector3d& halfWidth) {
  Grid g;
  for (int a = 0; a < 3; ++a) g.dims[a] = std::max(2, static_cast<int>(std::ceil(2 * halfWidth[a] / spacing[a])));
  g.spacing = spacing;
  g.origin = -spacing.cwiseProduct((g.dims.cast<double>().array() - 1.0).matrix() / 2.0);
  return g;
}

Scene ballScene(const TriangleMesh& templ) {
  Scene s;
  SceneObject o;
  o.name = "ball";
  o.label = 1;
  o.templ = templ;
  o.hasPolarity = true;
  o.polarity = Polarity::DarkInside;
  s.objects.push_back(o);
  return s;
}

SegmentOptions quickOptions(int levels, int steps) {
  SegmentOptions o;
  o.evolution.levels = levels;
  o.evolution.maxStepsPerLevel = steps;
  return o;
}

double meanRadius(const TriangleMesh& m, const Eigen::Vector3d& centre) {
  double sum = 0;
  for (int i = 0; i < m.vertexCount(); ++i) sum += (m.vertices.row(i).transpose() - centre).norm();
  return sum / m.vertexCount();
}

TriangleMesh ballInUnits(double unit, int levels) {
  const Grid g = boxGrid(Eigen::Vector3d::Constant(1.0 * unit), Eigen::Vector3d::Constant(15.0 * unit));
  const Eigen::Vector3d c = Eigen::Vector3d(0.3, -0.2, 0.1) * unit;
  const ImageF img = ballImage(g, c, 10.0 * unit, 200.f, 800.f);
  SegmentOptions o = quickOptions(levels, 25);
  o.image.edgePenalty = 0;
  o.image.rangeCoarseExtraMm *= unit;
  const SegmentationResult res = segmentScene(img, ballScene(makeIcosphere(8.0 * unit, 3, c)), o);
  TriangleMesh m = res.objects.at(0).mesh;
  m.vertices /= unit;
  return m;
}

}  // namespace msk::test
