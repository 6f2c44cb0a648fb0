#include "msk/test/shapes.h"

#include <random>

namespace msk::test {

SimplexMesh simplexSphere(double radiusMm, int subdivisions, const Eigen::Vector3d& centre) {
  return simplexFromTriangles(makeIcosphere(radiusMm, subdivisions, centre));
}

Points perturbed(const Points& p, double amplitude, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  Points q = p;
  for (Eigen::Index i = 0; i < q.rows(); ++i)
    for (int c = 0; c < 3; ++c) q(i, c) += u(rng);
  return q;
}

Eigen::Vector3d uniformVector(std::mt19937& rng, double halfWidth) {
  std::uniform_real_distribution<double> u(-halfWidth, halfWidth);
  Eigen::Vector3d v;
  for (int c = 0; c < 3; ++c) v[c] = u(rng);
  return v;
}

Points pointsNearSphere(int count, double radiusMm, double spread, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(1 - spread, 1 + spread);
  Points p(count, 3);
  for (int i = 0; i < count; ++i) {
    const double x = g(rng), y = g(rng), z = g(rng);
    p.row(i) = (radiusMm * u(rng) * Eigen::Vector3d(x, y, z).normalized()).transpose();
  }
  return p;
}

TriangleMesh joinedMeshes(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m = a;
  m.vertices.conservativeResize(a.vertexCount() + b.vertexCount(), 3);
  m.vertices.bottomRows(b.vertexCount()) = b.vertices;
  m.faces.conservativeResize(a.faceCount() + b.faceCount(), 3);
  m.faces.bottomRows(b.faceCount()) = b.faces.array() + a.vertexCount();
  return m;
}

TriangleMesh displacedScaled(const TriangleMesh& mesh, const Eigen::Vector3d& offsetMm, double scale) {
  TriangleMesh out = mesh;
  const Eigen::RowVector3d c = mesh.vertices.colwise().mean();
  out.vertices = ((mesh.vertices.rowwise() - c) * scale).rowwise() + (c + offsetMm.transpose());
  return out;
}

}  // namespace msk::test
