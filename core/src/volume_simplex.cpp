#include "msk/core/volume_simplex.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/error.h"

namespace msk {

namespace {

using Vec3 = Eigen::Vector3d;

std::string str(long long v) { return std::to_string(v); }

/// Local face j of a tet is the face opposite node j, listed so that its normal points out of a positive tet.
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

/// Face-adjacency of a tet mesh: across(t, j) = the tet sharing local face j of t, −1 on the boundary. Returns the
/// problem (a face in more than two tets) or an empty string.
std::string faceAdjacency(const Tets& tets, Eigen::Matrix<int, Eigen::Dynamic, 4>& across) {
  struct Slot {
    std::array<int, 3> key;
    int tet, local;
  };
  const int nt = static_cast<int>(tets.rows());
  std::vector<Slot> slots;
  slots.reserve(static_cast<size_t>(nt) * 4);
  for (int t = 0; t < nt; ++t) {
    for (int j = 0; j < 4; ++j) {
      std::array<int, 3> key = {tets(t, kFace[j][0]), tets(t, kFace[j][1]), tets(t, kFace[j][2])};
      std::sort(key.begin(), key.end());
      slots.push_back({key, t, j});
    }
  }
  std::sort(slots.begin(), slots.end(), [](const Slot& a, const Slot& b) {
    return a.key != b.key ? a.key < b.key : (a.tet != b.tet ? a.tet < b.tet : a.local < b.local);
  });
  across.resize(nt, 4);
  across.setConstant(-1);
  for (size_t i = 0; i < slots.size();) {
    size_t e = i + 1;
    while (e < slots.size() && slots[e].key == slots[i].key) ++e;
    if (e - i > 2)
      return "face (" + str(slots[i].key[0]) + ", " + str(slots[i].key[1]) + ", " + str(slots[i].key[2]) +
             ") is shared by " + str(static_cast<long long>(e - i)) + " tets";
    if (e - i == 2) {
      across(slots[i].tet, slots[i].local) = slots[i + 1].tet;
      across(slots[i + 1].tet, slots[i + 1].local) = slots[i].tet;
    }
    i = e;
  }
  return "";
}

/// Boundary faces (outward) and their owners from an adjacency table, in tet order then local-face order.
Triangles boundaryFromAdjacency(const Tets& tets, const Eigen::Matrix<int, Eigen::Dynamic, 4>& across,
                                Eigen::VectorXi* owner) {
  const int nt = static_cast<int>(tets.rows());
  int nb = 0;
  for (int t = 0; t < nt; ++t)
    for (int j = 0; j < 4; ++j) nb += across(t, j) < 0 ? 1 : 0;
  Triangles faces(nb, 3);
  if (owner) owner->resize(nb);
  int g = 0;
  for (int t = 0; t < nt; ++t) {
    for (int j = 0; j < 4; ++j) {
      if (across(t, j) >= 0) continue;
      faces.row(g) << tets(t, kFace[j][0]), tets(t, kFace[j][1]), tets(t, kFace[j][2]);
      if (owner) (*owner)[g] = t;
      ++g;
    }
  }
  return faces;
}

/// The triangle mesh of `faces` over `nodes` with the unused nodes dropped; nodeOf (optional) maps back.
TriangleMesh compactSurface(const Points& nodes, const Triangles& faces, Eigen::VectorXi* nodeOf) {
  std::vector<int> compact(static_cast<size_t>(nodes.rows()), -1);
  std::vector<int> used;
  TriangleMesh s;
  s.faces.resize(faces.rows(), 3);
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int& c = compact[static_cast<size_t>(faces(f, k))];
      if (c < 0) {
        c = static_cast<int>(used.size());
        used.push_back(faces(f, k));
      }
      s.faces(f, k) = c;
    }
  }
  s.vertices.resize(static_cast<Eigen::Index>(used.size()), 3);
  if (nodeOf) nodeOf->resize(static_cast<Eigen::Index>(used.size()));
  for (size_t i = 0; i < used.size(); ++i) {
    s.vertices.row(static_cast<Eigen::Index>(i)) = nodes.row(used[i]);
    if (nodeOf) (*nodeOf)[static_cast<Eigen::Index>(i)] = used[i];
  }
  return s;
}

/// The 4 neighbour positions of simplex vertex v.
void gather(const Points& p, const NeighborTable& nb, int v, Vec3 pi[4]) {
  for (int i = 0; i < 4; ++i) pi[i] = p.row(nb(v, i)).transpose();
}

}  // namespace

// ------------------------------------------------------------------------------------------------ tet meshes

double signedTetVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

Eigen::VectorXd tetVolumes(const TetMesh& m) {
  Eigen::VectorXd v(m.tetCount());
  for (int t = 0; t < m.tetCount(); ++t)
    v[t] = signedTetVolume(m.nodes.row(m.tets(t, 0)), m.nodes.row(m.tets(t, 1)), m.nodes.row(m.tets(t, 2)),
                           m.nodes.row(m.tets(t, 3)));
  return v;
}

double totalVolume(const TetMesh& m) { return tetVolumes(m).sum(); }

Eigen::VectorXd tetMinDihedralAngles(const TetMesh& m) {
  // The dihedral angle at edge (i, j) is π minus the angle between the outward normals of the two faces sharing it,
  // the faces opposite the other two nodes k and l.
  static const int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  Eigen::VectorXd out(m.tetCount());
  for (int t = 0; t < m.tetCount(); ++t) {
    Vec3 n[4];
    for (int j = 0; j < 4; ++j) {
      const Vec3 a = m.nodes.row(m.tets(t, kFace[j][0])), b = m.nodes.row(m.tets(t, kFace[j][1])),
                 c = m.nodes.row(m.tets(t, kFace[j][2]));
      n[j] = (b - a).cross(c - a);
    }
    double smallest = M_PI;
    for (const auto& e : kEdges) {
      int other[2], k = 0;
      for (int j = 0; j < 4; ++j)
        if (j != e[0] && j != e[1]) other[k++] = j;
      const double na = n[other[0]].norm(), nb = n[other[1]].norm();
      const double cosine = na > 0 && nb > 0 ? std::clamp(n[other[0]].dot(n[other[1]]) / (na * nb), -1.0, 1.0) : 1.0;
      smallest = std::min(smallest, M_PI - std::acos(cosine));
    }
    out[t] = smallest * 180.0 / M_PI;
  }
  return out;
}

std::string tetMeshProblem(const TetMesh& m) {
  const int nn = m.nodeCount(), nt = m.tetCount();
  if (nn == 0 || nt == 0) return "empty tet mesh (" + str(nn) + " nodes, " + str(nt) + " tets)";
  if (!m.nodes.allFinite()) return "non-finite node coordinates";
  for (int t = 0; t < nt; ++t) {
    for (int a = 0; a < 4; ++a) {
      const int u = m.tets(t, a);
      if (u < 0 || u >= nn) return "tet " + str(t) + " has a node index out of range (" + str(u) + ")";
      for (int b = 0; b < a; ++b)
        if (m.tets(t, b) == u) return "tet " + str(t) + " repeats node " + str(u);
    }
  }
  const Eigen::VectorXd vol = tetVolumes(m);
  for (int t = 0; t < nt; ++t)
    if (!(vol[t] > 0)) return "tet " + str(t) + " is not positively oriented (volume " + std::to_string(vol[t]) + ")";
  Eigen::Matrix<int, Eigen::Dynamic, 4> across;
  return faceAdjacency(m.tets, across);
}

Triangles tetBoundaryFaces(const TetMesh& m, Eigen::VectorXi* owner) {
  Eigen::Matrix<int, Eigen::Dynamic, 4> across;
  const std::string p = faceAdjacency(m.tets, across);
  if (!p.empty()) throw Error("tetBoundaryFaces: " + p);
  return boundaryFromAdjacency(m.tets, across, owner);
}

TriangleMesh tetBoundary(const TetMesh& m, Eigen::VectorXi* nodeOf) {
  return compactSurface(m.nodes, tetBoundaryFaces(m), nodeOf);
}

// ------------------------------------------------------------------------------------------------ dual model

int simplexBarycentric(const Vec3& p, const Vec3 pi[4], double eps[4]) {
  const Vec3 c = (pi[0] + pi[1] + pi[2] + pi[3]) / 4.0;
  double s = 0;
  for (int i = 0; i < 4; ++i) s = std::max(s, (pi[i] - c).norm());
  if (!(s > 0) || !std::isfinite(s) || !p.allFinite()) {
    for (int i = 0; i < 4; ++i) eps[i] = 0.25;
    return 2;
  }
  // Scale-free frame: neighbours within the unit ball around their centroid.
  Vec3 q[4];
  for (int i = 0; i < 4; ++i) q[i] = (pi[i] - c) / s;
  const Vec3 x = (p - c) / s;
  Eigen::Matrix3d e;
  e << q[1] - q[0], q[2] - q[0], q[3] - q[0];
  // A regular tet inscribed in the unit sphere has volume 8/(9√3) ≈ 0.51; relative flatness below 1e-6 is coplanar.
  const double det = e.determinant();
  if (std::fabs(det) / 6.0 > 1e-6 * 0.51) {
    const Vec3 b = e.partialPivLu().solve(x - q[0]);
    eps[0] = 1.0 - b.sum();
    eps[1] = b[0];
    eps[2] = b[1];
    eps[3] = b[2];
    return 0;
  }
  // Coplanar (or collinear) neighbours: minimum-norm affine least squares [q0..q3; 1 1 1 1] ε = [x; 1].
  Eigen::Matrix4d a;
  a.topRows<3>() << q[0], q[1], q[2], q[3];
  a.row(3).setOnes();
  Eigen::Vector4d rhs;
  rhs << x, 1.0;
  Eigen::CompleteOrthogonalDecomposition<Eigen::Matrix4d> cod;
  cod.setThreshold(1e-6);
  cod.compute(a);
  Eigen::Vector4d sol = cod.solve(rhs);
  const bool exact = (a * sol - rhs).norm() < 1e-6 && sol.allFinite();
  const double sum = sol.sum();
  if (std::isfinite(sum) && std::fabs(sum) > 1e-12)
    sol /= sum;
  else
    sol.setConstant(0.25);
  for (int i = 0; i < 4; ++i) eps[i] = sol[i];
  return exact ? 1 : 2;
}

VolumeSimplexMesh volumeSimplexFromTets(const TetMesh& mesh) {
  const std::string problem = tetMeshProblem(mesh);
  if (!problem.empty()) throw Error("volumeSimplexFromTets: invalid tet mesh: " + problem);
  Eigen::Matrix<int, Eigen::Dynamic, 4> across;
  faceAdjacency(mesh.tets, across);
  Eigen::VectorXi owner;
  VolumeSimplexMesh vm;
  vm.tets = mesh.tets;
  vm.nodeCount = mesh.nodeCount();
  vm.boundaryFaces = boundaryFromAdjacency(mesh.tets, across, &owner);
  const int nt = mesh.tetCount(), nb = vm.ghostCount(), n = nt + nb;

  // The ghost layer: the 2-simplex dual of the boundary triangulation (vertex g = boundary face g).
  const TriangleMesh surface = compactSurface(mesh.nodes, vm.boundaryFaces, nullptr);
  {
    const std::string sp = closedMeshProblem(surface);
    if (!sp.empty()) throw Error("volumeSimplexFromTets: the boundary of the tet mesh is not a closed manifold: " + sp);
  }
  vm.boundary = simplexFromTriangles(surface);

  SimplexMesh& s = vm.simplex;
  s.k = 3;
  s.positions.resize(n, 3);
  s.neighbors.resize(n, 4);
  for (int t = 0; t < nt; ++t)
    s.positions.row(t) = (mesh.nodes.row(mesh.tets(t, 0)) + mesh.nodes.row(mesh.tets(t, 1)) +
                          mesh.nodes.row(mesh.tets(t, 2)) + mesh.nodes.row(mesh.tets(t, 3))) /
                         4.0;
  s.positions.bottomRows(nb) = vm.boundary.positions;
  int g = 0;
  for (int t = 0; t < nt; ++t)
    for (int j = 0; j < 4; ++j) s.neighbors(t, j) = across(t, j) >= 0 ? across(t, j) : nt + g++;
  for (int b = 0; b < nb; ++b) {
    for (int k = 0; k < 3; ++k) s.neighbors(nt + b, k) = nt + vm.boundary.neighbors(b, k);
    s.neighbors(nt + b, 3) = owner[b];
  }
  const std::string sp = simplexMeshProblem(s);
  MSK_ASSERT(sp.empty(), "dual 3-simplex mesh invalid: " + sp);

  vm.epsilon.resize(n, 4);
  vm.degenerate.resize(n);
  for (int v = 0; v < n; ++v) {
    Vec3 pi[4];
    gather(s.positions, s.neighbors, v, pi);
    double eps[4];
    vm.degenerate[v] = simplexBarycentric(s.positions.row(v).transpose(), pi, eps);
    for (int i = 0; i < 4; ++i) vm.epsilon(v, i) = eps[i];
  }
  return vm;
}

TetMesh tetsFromVolumeSimplex(const VolumeSimplexMesh& vm, const Points& p) {
  return tetsFromVolumeSimplex(vm, p, Eigen::VectorXi(), Points(0, 3));
}

TetMesh tetsFromVolumeSimplex(const VolumeSimplexMesh& vm, const Points& p, const Eigen::VectorXi& fixedNodes,
                              const Points& fixedPositions) {
  const int nt = vm.tetCount(), nb = vm.ghostCount(), nn = vm.nodeCount;
  if (fixedPositions.rows() != fixedNodes.size())
    throw ParameterError("fixed node positions", str(fixedPositions.rows()),
                         "need one row per fixed node (" + str(fixedNodes.size()) + ")");
  std::vector<char> fixed(static_cast<size_t>(nn), 0);
  for (Eigen::Index i = 0; i < fixedNodes.size(); ++i) {
    if (fixedNodes[i] < 0 || fixedNodes[i] >= nn)
      throw ParameterError("fixed node", str(fixedNodes[i]), "must index a node (< " + str(nn) + ")");
    fixed[static_cast<size_t>(fixedNodes[i])] = 1;
  }
  MSK_ASSERT(p.rows() == nt + nb,
             "tetsFromVolumeSimplex: " + str(p.rows()) + " positions for " + str(nt + nb) + " vertices");
  // A: one row per simplex vertex, the mean of its primal nodes (4 for a tet, 3 for a boundary face).
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(nt) * 4 + static_cast<size_t>(nb) * 3);
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 4; ++k) trip.emplace_back(t, vm.tets(t, k), 0.25);
  for (int b = 0; b < nb; ++b)
    for (int k = 0; k < 3; ++k) trip.emplace_back(nt + b, vm.boundaryFaces(b, k), 1.0 / 3.0);
  Eigen::SparseMatrix<double> a(nt + nb, nn);
  a.setFromTriplets(trip.begin(), trip.end());

  // N₀: the mean of the simplex vertices incident to each node (regularises nodes the system leaves free).
  Points n0 = Points::Zero(nn, 3);
  Eigen::VectorXd count = Eigen::VectorXd::Zero(nn);
  for (int k = 0; k < a.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(a, k); it; ++it) {
      n0.row(it.col()) += p.row(it.row());
      count[it.col()] += 1.0;
    }
  for (int i = 0; i < nn; ++i) {
    if (count[i] > 0) n0.row(i) /= count[i];
  }

  Eigen::SparseMatrix<double> ata = a.transpose() * a;
  const double mu = 1e-6 * ata.diagonal().sum() / std::max(nn, 1);
  Eigen::MatrixXd rhs = a.transpose() * Eigen::MatrixXd(p);
  if (!fixedNodes.size()) {
    for (int i = 0; i < nn; ++i) ata.coeffRef(i, i) += count[i] > 0 ? mu : 1.0;
    for (int i = 0; i < nn; ++i) rhs.row(i) += (count[i] > 0 ? mu : 1.0) * n0.row(i);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(ata);
    MSK_ASSERT(solver.info() == Eigen::Success, "tetsFromVolumeSimplex: factorisation failed");
    TetMesh out;
    out.nodes = solver.solve(rhs);
    out.tets = vm.tets;
    return out;
  }
  // Fixed nodes: min |A_F N_F − (P − A_X N_X)|² + μ|N_F − N₀_F|² over the free nodes F.
  Points known = Points::Zero(nn, 3);
  for (Eigen::Index i = 0; i < fixedNodes.size(); ++i) known.row(fixedNodes[i]) = fixedPositions.row(i);
  std::vector<int> freeIndex(static_cast<size_t>(nn), -1);
  int nf = 0;
  for (int i = 0; i < nn; ++i)
    if (!fixed[static_cast<size_t>(i)]) freeIndex[static_cast<size_t>(i)] = nf++;
  TetMesh out;
  out.nodes = known;
  out.tets = vm.tets;
  if (nf == 0) return out;
  const Eigen::MatrixXd residual = Eigen::MatrixXd(p) - a * Eigen::MatrixXd(known);
  std::vector<Eigen::Triplet<double>> ftrip;
  for (int k = 0; k < a.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(a, k); it; ++it)
      if (freeIndex[static_cast<size_t>(it.col())] >= 0)
        ftrip.emplace_back(static_cast<int>(it.row()), freeIndex[static_cast<size_t>(it.col())], it.value());
  Eigen::SparseMatrix<double> af(nt + nb, nf);
  af.setFromTriplets(ftrip.begin(), ftrip.end());
  Eigen::SparseMatrix<double> ff = af.transpose() * af;
  Eigen::MatrixXd frhs = af.transpose() * residual;
  for (int i = 0; i < nn; ++i) {
    const int f = freeIndex[static_cast<size_t>(i)];
    if (f < 0) continue;
    const double w = count[i] > 0 ? mu : 1.0;
    ff.coeffRef(f, f) += w;
    frhs.row(f) += w * n0.row(i);
  }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(ff);
  MSK_ASSERT(solver.info() == Eigen::Success, "tetsFromVolumeSimplex: factorisation failed");
  const Eigen::MatrixXd xf = solver.solve(frhs);
  for (int i = 0; i < nn; ++i)
    if (freeIndex[static_cast<size_t>(i)] >= 0) out.nodes.row(i) = xf.row(freeIndex[static_cast<size_t>(i)]);
  return out;
}

Points relaxVolumeSimplexTets(const VolumeSimplexMesh& vm, const Points& p, double mu) {
  const int nt = vm.tetCount(), n = vm.vertexCount();
  MSK_ASSERT(p.rows() == n, "relaxVolumeSimplexTets: " + str(p.rows()) + " positions for " + str(n) + " vertices");
  if (!(mu > 0) || !std::isfinite(mu)) throw ParameterError("relax weight", std::to_string(mu), "must be > 0");
  // Row t: P_t − Σ_{tet neighbours} ε̃i Pi = Σ_{ghost neighbours} ε̃i Pi (M x = b). A degenerate = 2 tet gives no row.
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(nt) * 5);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(nt, 3);
  for (int t = 0; t < nt; ++t) {
    if (vm.degenerate[t] == 2) continue;
    trip.emplace_back(t, t, 1.0);
    for (int i = 0; i < 4; ++i) {
      const int u = vm.simplex.neighbors(t, i);
      if (u < nt)
        trip.emplace_back(t, u, -vm.epsilon(t, i));
      else
        b.row(t) += vm.epsilon(t, i) * p.row(u);
    }
  }
  Eigen::SparseMatrix<double> m(nt, nt);
  m.setFromTriplets(trip.begin(), trip.end());
  // (MᵀM + μI) x = Mᵀb + μ x₀: the constraints met as far as they determine the tets, the rest left at the start.
  Eigen::SparseMatrix<double> a = m.transpose() * m;
  for (int t = 0; t < nt; ++t) a.coeffRef(t, t) += mu;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
  if (solver.info() != Eigen::Success) throw Error("relaxVolumeSimplexTets: factorisation failed");
  const Eigen::MatrixXd rhs = m.transpose() * b + mu * Eigen::MatrixXd(p.topRows(nt));
  Points out = p;
  out.topRows(nt) = solver.solve(rhs);
  if (!out.allFinite()) throw Error("relaxVolumeSimplexTets: non-finite solution");
  return out;
}

double volumeSimplexVolume(const VolumeSimplexMesh& vm, const Points& p) {
  return totalVolume(tetsFromVolumeSimplex(vm, p));
}

// ------------------------------------------------------------------------------------------------ constraint

bool volumeSimplexRow(const Vec3& p, const Vec3 pi[4], const double eps[4], double gamma, ConstraintRow& row) {
  const double sumEps = eps[0] + eps[1] + eps[2] + eps[3];
  if (!(std::fabs(sumEps - 1.0) < 1e-9)) return false;  // momentum is conserved only for affine weights
  row.count = 5;
  row.c = -p;
  row.index[0] = 0;
  row.grad[0] = row.react[0] = -1.0;
  for (int i = 0; i < 4; ++i) {
    row.index[i + 1] = i + 1;
    row.grad[i + 1] = row.react[i + 1] = eps[i];
    row.c += eps[i] * pi[i];
  }
  row.gamma = gamma;
  row.direction = false;
  row.compliant = true;
  return row.c.allFinite();
}

bool volumeSimplexCorrection(const Vec3& p, const Vec3 pi[4], double w, const double wi[4], const double eps[4],
                             double gamma, Vec3& dp, Vec3 dpi[4]) {
  ConstraintRow row;
  if (!volumeSimplexRow(p, pi, eps, gamma, row)) return false;
  return pbdCorrections(row, w, wi, dp, dpi);
}

VolumeSimplexConstraints::VolumeSimplexConstraints(const VolumeSimplexMesh& model, double gamma,
                                                   VolumeBoundary boundary)
    : nb_(model.simplex.neighbors), eps_(model.epsilon), gamma_(gamma) {
  checkUnitInterval("volume stiffness", gamma);
  MSK_ASSERT(
      model.simplex.k == 3 && nb_.cols() == 4 && eps_.rows() == nb_.rows() && model.degenerate.size() == nb_.rows(),
      "3-simplex volume model expected");
  for (int v = 0; v < static_cast<int>(nb_.rows()); ++v) {
    const bool ghost = v >= model.tetCount();
    if (model.degenerate[v] != 2 && (!ghost || boundary == VolumeBoundary::Constrained)) rows_.push_back(v);
  }
}

int VolumeSimplexConstraints::rowParticles(int r, int index[kMaxRowParticles]) const {
  const int v = rows_[static_cast<size_t>(r)];
  index[0] = first_ + v;
  for (int i = 0; i < 4; ++i) index[i + 1] = first_ + nb_(v, i);
  return 5;
}

void VolumeSimplexConstraints::beginRows(const Points& p, const Eigen::VectorXd& w) {
  MSK_ASSERT(p.rows() >= first_ + nb_.rows() && w.size() == p.rows(), "volume-simplex constraints: size mismatch");
}

bool VolumeSimplexConstraints::row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const {
  (void)w;
  const int v = rows_[static_cast<size_t>(r)];
  Vec3 pi[4];
  double eps[4];
  for (int i = 0; i < 4; ++i) {
    pi[i] = p.row(first_ + nb_(v, i)).transpose();
    eps[i] = eps_(v, i);
  }
  if (!volumeSimplexRow(p.row(first_ + v).transpose(), pi, eps, gamma_, out)) return false;
  rowParticles(r, out.index);
  return true;
}

TetMesh makeCubeTets(int n, double edgeMm) {
  if (n < 1 || !(edgeMm > 0))
    throw ParameterError("cube tets", std::to_string(n) + " x " + std::to_string(edgeMm),
                         "need n >= 1 cubes of a positive edge");
  TetMesh m;
  const int s = n + 1;
  m.nodes.resize(s * s * s, 3);
  auto id = [s](int i, int j, int k) { return i + s * (j + s * k); };
  for (int k = 0; k < s; ++k)
    for (int j = 0; j < s; ++j)
      for (int i = 0; i < s; ++i) m.nodes.row(id(i, j, k)) << edgeMm * i, edgeMm * j, edgeMm * k;
  // Each tet follows a path 0 → e_a → e_a + e_b → (1,1,1) through its cube.
  const int orders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  m.tets.resize(6 * n * n * n, 4);
  int t = 0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (const auto& order : orders) {
          int c[3] = {i, j, k}, row[4];
          row[0] = id(c[0], c[1], c[2]);
          for (int a = 0; a < 3; ++a) {
            ++c[order[a]];
            row[a + 1] = id(c[0], c[1], c[2]);
          }
          if (signedTetVolume(m.nodes.row(row[0]), m.nodes.row(row[1]), m.nodes.row(row[2]), m.nodes.row(row[3])) < 0)
            std::swap(row[2], row[3]);
          m.tets.row(t++) << row[0], row[1], row[2], row[3];
        }
  return m;
}

}  // namespace msk
