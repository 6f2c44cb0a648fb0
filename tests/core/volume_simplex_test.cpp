#include "msk/core/volume_simplex.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>

#include "msk/core/error.h"
#include "msk/test/shapes.h"
#include "msk/test/tet_surface.h"

namespace {

using msk::test::uniformVector;
using msk::test::volumeResiduals;

/// Inverse masses: tets free (1), ghosts fixed (0).
Eigen::VectorXd ghostsFixed(const msk::VolumeSimplexMesh& vm) {
  Eigen::VectorXd w = Eigen::VectorXd::Ones(vm.vertexCount());
  w.tail(vm.ghostCount()).setZero();
  return w;
}

}  // namespace

// Table 4.25 corrections carry no linear and no angular momentum, and a full step satisfies C = 0.
TEST(VolumeSimplexKernel, ConservesMomentumAndSatisfiesConstraint) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> um(0.2, 5.0), ue(-0.3, 1.0), ug(0.1, 1.0);
  double worstLin = 0, worstAng = 0, worstC = 0;
  for (int t = 0; t < 500; ++t) {
    Eigen::Vector3d pi[4];
    for (auto& q : pi) q = uniformVector(rng, 20.0);
    const Eigen::Vector3d p = uniformVector(rng, 20.0) + Eigen::Vector3d(5, -3, 2);
    double eps[4], sum = 0;
    for (double& e : eps) sum += (e = ue(rng));
    for (double& e : eps) e /= sum;
    const double w = 1.0 / um(rng), wi[4] = {1.0 / um(rng), 1.0 / um(rng), 1.0 / um(rng), 1.0 / um(rng)};
    const double gamma = t % 2 ? 1.0 : ug(rng);
    Eigen::Vector3d dp, dpi[4];
    ASSERT_TRUE(msk::volumeSimplexCorrection(p, pi, w, wi, eps, gamma, dp, dpi));
    Eigen::Vector3d lin = dp / w, ang = p.cross(dp) / w;
    double scaleLin = dp.norm() / w, scaleAng = p.norm() * dp.norm() / w;
    for (int i = 0; i < 4; ++i) {
      lin += dpi[i] / wi[i];
      ang += pi[i].cross(dpi[i]) / wi[i];
      scaleLin += dpi[i].norm() / wi[i];
      scaleAng += pi[i].norm() * dpi[i].norm() / wi[i];
    }
    worstLin = std::max(worstLin, lin.norm() / scaleLin);
    worstAng = std::max(worstAng, ang.norm() / scaleAng);
    // Residual after the step: (1 − γ) C.
    Eigen::Vector3d c0 = -p, c1 = -(p + dp);
    for (int i = 0; i < 4; ++i) {
      c0 += eps[i] * pi[i];
      c1 += eps[i] * (pi[i] + dpi[i]);
    }
    worstC = std::max(worstC, (c1 - (1.0 - gamma) * c0).norm() / c0.norm());
  }
  EXPECT_LT(worstLin, 1e-9);
  EXPECT_LT(worstAng, 1e-9);
  EXPECT_LT(worstC, 1e-9);
}

TEST(VolumeSimplexKernel, RejectsDegenerateInput) {
  const Eigen::Vector3d p(0, 0, 0), pi[4] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, -1, -1}};
  const double eps[4] = {0.25, 0.25, 0.25, 0.25}, bad[4] = {0.5, 0.5, 0.5, 0.5};
  const double wi[4] = {1, 1, 1, 1}, fixed[4] = {0, 0, 0, 0};
  Eigen::Vector3d dp(7, 7, 7), dpi[4];
  EXPECT_FALSE(msk::volumeSimplexCorrection(p, pi, 0.0, fixed, eps, 1.0, dp, dpi));
  EXPECT_FALSE(msk::volumeSimplexCorrection(p, pi, 1.0, wi, bad, 1.0, dp, dpi));
  const Eigen::Vector3d nan(std::nan(""), 0, 0);
  EXPECT_FALSE(msk::volumeSimplexCorrection(nan, pi, 1.0, wi, eps, 1.0, dp, dpi));
  EXPECT_EQ(dp, Eigen::Vector3d(7, 7, 7));  // outputs untouched
}

TEST(SimplexBarycentric, TetrahedronCoplanarAndOffPlane) {
  const Eigen::Vector3d tet[4] = {{0, 0, 0}, {2, 0, 0}, {0, 3, 0}, {0, 0, 4}};
  const Eigen::Vector3d p(0.3, 0.7, 1.1);
  double eps[4];
  EXPECT_EQ(msk::simplexBarycentric(p, tet, eps), 0);
  Eigen::Vector3d back = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i) back += eps[i] * tet[i];
  EXPECT_LT((back - p).norm(), 1e-12);
  EXPECT_NEAR(eps[0] + eps[1] + eps[2] + eps[3], 1.0, 1e-12);

  const Eigen::Vector3d flat[4] = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {2, 2, 0}};
  EXPECT_EQ(msk::simplexBarycentric(Eigen::Vector3d(0.5, 1.5, 0), flat, eps), 1);
  back.setZero();
  for (int i = 0; i < 4; ++i) back += eps[i] * flat[i];
  EXPECT_LT((back - Eigen::Vector3d(0.5, 1.5, 0)).norm(), 1e-9);
  EXPECT_NEAR(eps[0] + eps[1] + eps[2] + eps[3], 1.0, 1e-12);
  EXPECT_EQ(msk::simplexBarycentric(Eigen::Vector3d(0.5, 1.5, 1.0), flat, eps), 2);
  EXPECT_NEAR(eps[0] + eps[1] + eps[2] + eps[3], 1.0, 1e-12);
}

TEST(TetMesh, VolumesBoundaryAndProblems) {
  const msk::TetMesh m = msk::makeCubeTets(3, 2.0);
  EXPECT_EQ(msk::tetMeshProblem(m), "");
  EXPECT_NEAR(msk::totalVolume(m), 216.0, 1e-9);
  EXPECT_GT(msk::tetVolumes(m).minCoeff(), 0.0);
  Eigen::VectorXi nodeOf;
  const msk::TriangleMesh b = msk::tetBoundary(m, &nodeOf);
  EXPECT_EQ(msk::closedMeshProblem(b), "");
  EXPECT_EQ(b.faceCount(), 6 * 9 * 2);
  EXPECT_EQ(b.vertexCount(), 64 - 8);  // a 4×4×4 node grid less its 2×2×2 interior nodes
  EXPECT_NEAR(msk::enclosedVolume(b), 216.0, 1e-9);

  msk::TetMesh bad = m;
  std::swap(bad.tets(5, 2), bad.tets(5, 3));
  EXPECT_NE(msk::tetMeshProblem(bad).find("not positively oriented"), std::string::npos);
  EXPECT_THROW(msk::volumeSimplexFromTets(bad), msk::Error);
  msk::TetMesh open = m;
  open.tets.conservativeResize(m.tetCount() - 1, 4);  // still a closed boundary (a notch), valid
  EXPECT_EQ(msk::tetMeshProblem(open), "");
}

TEST(VolumeSimplex, DualOfCubeIsValidAndReproducesRest) {
  const int n = 4;
  const double h = 2.5;
  const msk::TetMesh m = msk::makeCubeTets(n, h);
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(m);
  EXPECT_EQ(vm.simplex.k, 3);
  EXPECT_EQ(msk::simplexMeshProblem(vm.simplex), "");
  EXPECT_EQ(vm.tetCount(), 6 * n * n * n);
  EXPECT_EQ(vm.ghostCount(), 12 * n * n);
  EXPECT_EQ(vm.simplex.neighbors.cols(), 4);
  EXPECT_EQ(msk::simplexMeshProblem(vm.boundary), "");
  EXPECT_EQ(vm.boundary.k, 2);
  // The ghost layer is the boundary 2-simplex surface.
  EXPECT_LT((vm.boundary.positions - vm.simplex.positions.bottomRows(vm.ghostCount())).norm(), 1e-12);
  const int nt = vm.tetCount();
  for (int g = 0; g < vm.ghostCount(); ++g)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(vm.simplex.neighbors(nt + g, k), nt + vm.boundary.neighbors(g, k));
  // Only ghosts can have coplanar neighbours here (near the cube's corners, by symmetry); every tet is constrained.
  int degenerate = 0;
  for (int v = 0; v < vm.vertexCount(); ++v) degenerate += vm.degenerate[v] == 0 ? 0 : 1;
  EXPECT_EQ(vm.degenerate.head(vm.tetCount()).cwiseAbs().sum(), 0);
  EXPECT_LE(degenerate, 24);
  // ε̃ reproduce the rest positions.
  const msk::Points r = volumeResiduals(vm, vm.simplex.positions);
  EXPECT_LT(r.rowwise().norm().maxCoeff(), 1e-9 * h);
  for (int v = 0; v < vm.vertexCount(); ++v) EXPECT_NEAR(vm.epsilon.row(v).sum(), 1.0, 1e-12);
  // Rest nodes and volume recovered from the simplex positions.
  const msk::TetMesh back = msk::tetsFromVolumeSimplex(vm, vm.simplex.positions);
  const double side = n * h;
  EXPECT_LT((back.nodes - m.nodes).rowwise().norm().maxCoeff(), 1e-6 * side);
  EXPECT_NEAR(msk::volumeSimplexVolume(vm, vm.simplex.positions), side * side * side, 1e-6 * side * side * side);
}

// With the ghosts fixed at rest, the 3-simplex constraints restore a scrambled interior.
TEST(VolumeSimplexConstraints, RestoreInteriorWithGhostsFixed) {
  const int n = 4;
  const double h = 2.5, side = n * h, diag = std::sqrt(3.0) * side, vol0 = side * side * side;
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(msk::makeCubeTets(n, h));
  const msk::Points rest = vm.simplex.positions;
  std::mt19937 rng(3);
  msk::Points p = rest;
  for (int v = 0; v < vm.tetCount(); ++v) p.row(v) += uniformVector(rng, 0.1 * diag / std::sqrt(3.0)).transpose();
  const double before = (p - rest).rowwise().norm().maxCoeff() / diag;
  EXPECT_GT(before, 0.05);
  msk::VolumeSimplexConstraints c(vm, 1.0);
  const Eigen::VectorXd w = ghostsFixed(vm);
  for (int it = 0; it < 400; ++it) c.project(p, w);
  EXPECT_EQ(c.skipped(), 0);
  EXPECT_LT((p.bottomRows(vm.ghostCount()) - rest.bottomRows(vm.ghostCount())).norm(), 1e-12);  // ghosts fixed
  const double after = (p - rest).rowwise().norm().maxCoeff() / diag;
  const double vol = msk::volumeSimplexVolume(vm, p);
  EXPECT_LT(after, 0.01);
  EXPECT_NEAR(vol, vol0, 0.02 * vol0);
}

// The surface drives the volume: ghosts moved by an affine map pull the interior to the same map (ε̃ are affine
// invariant), so the volume follows det(A).
TEST(VolumeSimplexConstraints, SurfaceDrivesVolume) {
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(msk::makeCubeTets(3, 3.0));
  Eigen::Matrix3d a;
  a << 1.2, 0.1, 0.0, -0.05, 0.9, 0.1, 0.0, 0.2, 1.1;
  const Eigen::RowVector3d t(4, -2, 7);
  const msk::Points target = (vm.simplex.positions * a.transpose()).rowwise() + t;
  msk::Points p = vm.simplex.positions;
  p.bottomRows(vm.ghostCount()) = target.bottomRows(vm.ghostCount());  // the surface model moved the ghosts
  msk::VolumeSimplexConstraints c(vm, 1.0);
  const Eigen::VectorXd w = ghostsFixed(vm);
  for (int it = 0; it < 1500; ++it) c.project(p, w);
  EXPECT_LT((p - target).rowwise().norm().maxCoeff(), 1e-6);
  EXPECT_NEAR(msk::volumeSimplexVolume(vm, p), a.determinant() * 729.0, 1e-6 * 729.0);
}

// A pass over free particles conserves total linear momentum, and firstParticle() addresses a stacked system.
TEST(VolumeSimplexConstraints, StackedAndMomentumConserving) {
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(msk::makeCubeTets(2, 1.0));
  const int first = 7, n = vm.vertexCount();
  std::mt19937 rng(5);
  msk::Points p(first + n + 3, 3);
  for (int i = 0; i < p.rows(); ++i) p.row(i) = uniformVector(rng, 1.0).transpose();
  p.middleRows(first, n) += vm.simplex.positions;
  Eigen::VectorXd w(p.rows());
  std::uniform_real_distribution<double> um(0.5, 2.0);
  for (int i = 0; i < w.size(); ++i) w[i] = 1.0 / um(rng);
  const msk::Points before = p;
  msk::VolumeSimplexConstraints c(vm, 0.7, msk::VolumeBoundary::Constrained);
  c.setFirstParticle(first);
  c.project(p, w);
  EXPECT_EQ((p.topRows(first) - before.topRows(first)).norm(), 0.0);
  EXPECT_EQ((p.bottomRows(3) - before.bottomRows(3)).norm(), 0.0);
  const Eigen::RowVector3d momentum = (w.cwiseInverse().asDiagonal() * (p - before)).colwise().sum();
  EXPECT_LT(momentum.norm(), 1e-9 * (p - before).norm());
  EXPECT_GT((p - before).norm(), 0.1);
  EXPECT_THROW(msk::VolumeSimplexConstraints(vm, 1.5), msk::ParameterError);
}

// The tets' equilibrium with the ghosts held, nearest to the start: the rest tets for the rest ghosts; for ghosts
// moved affinely and tets started at the same affine map, that map (already an equilibrium); for tets started away
// from it, the tet constraints are met far better than at the start.
TEST(VolumeSimplexRelax, RestAndAffineGhostsKeepRestAndAffineTets) {
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(msk::makeCubeTets(4, 2.0));
  const int nt = vm.tetCount();
  const msk::Points rest = vm.simplex.positions;
  EXPECT_LT((msk::relaxVolumeSimplexTets(vm, rest) - rest).cwiseAbs().maxCoeff(), 1e-9);
  Eigen::Matrix3d a;
  a << 1.1, 0.2, 0.0, -0.1, 0.9, 0.05, 0.0, 0.1, 1.05;
  const msk::Points moved = (rest * a.transpose()).rowwise() + Eigen::RowVector3d(3, -1, 2);
  EXPECT_LT((msk::relaxVolumeSimplexTets(vm, moved) - moved).cwiseAbs().maxCoeff(), 1e-8);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.5);
  msk::Points start = moved;
  for (int t = 0; t < nt; ++t)
    for (int c = 0; c < 3; ++c) start(t, c) += noise(rng);
  const msk::Points solved = msk::relaxVolumeSimplexTets(vm, start);
  const double before = volumeResiduals(vm, start).topRows(nt).rowwise().norm().mean();
  const double after = volumeResiduals(vm, solved).topRows(nt).rowwise().norm().mean();
  EXPECT_LT(after, 0.05 * before);
  EXPECT_EQ((solved.bottomRows(vm.ghostCount()) - moved.bottomRows(vm.ghostCount())).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_THROW(msk::relaxVolumeSimplexTets(vm, rest, 0.0), msk::ParameterError);
}

// Node recovery with the boundary nodes held (as the segmenter holds them on the evolved surface): held at their
// affine images, the interior nodes come back at theirs from the affinely moved simplex vertices; the held nodes are
// exactly where they were put; bad input is refused.
TEST(VolumeSimplexRecovery, FixedBoundaryNodesAndAffineMotion) {
  const msk::TetMesh cube = msk::makeCubeTets(4, 2.0);
  const msk::VolumeSimplexMesh vm = msk::volumeSimplexFromTets(cube);
  Eigen::Matrix3d a;
  a << 1.1, 0.2, 0.0, -0.1, 0.9, 0.05, 0.0, 0.1, 1.05;
  const Eigen::RowVector3d shift(3, -1, 2);
  const msk::Points moved = (vm.simplex.positions * a.transpose()).rowwise() + shift;
  const msk::Points nodesMoved = (cube.nodes * a.transpose()).rowwise() + shift;
  Eigen::VectorXi surfaceNode;
  msk::tetBoundary(cube, &surfaceNode);
  msk::Points held(surfaceNode.size(), 3);
  for (Eigen::Index i = 0; i < surfaceNode.size(); ++i) held.row(i) = nodesMoved.row(surfaceNode[i]);
  const msk::TetMesh m = msk::tetsFromVolumeSimplex(vm, moved, surfaceNode, held);
  EXPECT_LT((m.nodes - nodesMoved).cwiseAbs().maxCoeff(), 1e-6);
  for (Eigen::Index i = 0; i < surfaceNode.size(); ++i) EXPECT_TRUE(m.nodes.row(surfaceNode[i]) == held.row(i));
  EXPECT_TRUE(m.tets == cube.tets);
  EXPECT_THROW(msk::tetsFromVolumeSimplex(vm, moved, surfaceNode, held.topRows(3)), msk::ParameterError);
  Eigen::VectorXi bad = surfaceNode;
  bad[0] = cube.nodeCount();
  EXPECT_THROW(msk::tetsFromVolumeSimplex(vm, moved, bad, held), msk::ParameterError);
}
