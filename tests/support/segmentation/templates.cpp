#include "msk/test/templates.h"

namespace msk::test {

TriangleMesh mirroredTemplate(const LabelMap& labels, int fromLabel, double midX, const TemplateOptions& opts) {
  return mirrorMesh(templateFromLabels(labels, fromLabel, opts), Eigen::Vector3d(midX, 0, 0), Eigen::Vector3d::UnitX());
}

}  // namespace msk::test
