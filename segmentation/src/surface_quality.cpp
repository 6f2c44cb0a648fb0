#include "msk/segmentation/surface_quality.h"

#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/box_intersection_d.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/detail/cgal_mesh.h"

namespace msk {

namespace PMP = CGAL::Polygon_mesh_processing;
using detail::CgalMesh;

namespace {

/// Throws if `mesh` is not a closed manifold, naming the caller.
void requireClosed(const TriangleMesh& mesh, const char* caller) {
  const std::string problem = closedMeshProblem(mesh);
  if (!problem.empty()) throw Error(std::string(caller) + ": the surface is not closed: " + problem);
}

/// The pairs of faces of `m` that cross each other.
std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> crossingPairs(const CgalMesh& m) {
  std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> pairs;
  PMP::self_intersections(m, std::back_inserter(pairs));
  return pairs;
}

/// The pairs of faces of `m` that cross each other and have a face in `changed` (a flag per face): those faces and
/// every face whose box meets one of theirs are given to CGAL's search, whose pairs are then every crossing pair of
/// `m` with a face in `changed` (and pairs of two faces outside it, which cross as well).
std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> crossingPairsNear(const CgalMesh& m,
                                                                                     const std::vector<char>& changed) {
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
  std::vector<Box> all, near;
  all.reserve(m.number_of_faces());
  for (CgalMesh::Face_index f : m.faces()) {
    CGAL::Bbox_3 box;
    for (CgalMesh::Vertex_index v : CGAL::vertices_around_face(m.halfedge(f), m)) box += m.point(v).bbox();
    all.emplace_back(box, static_cast<int>(f.idx()));
    if (changed[f.idx()]) near.push_back(all.back());
  }
  std::vector<char> in(changed.size(), 0);
  CGAL::box_intersection_d(near.begin(), near.end(), all.begin(), all.end(), [&](const Box& a, const Box& b) {
    in[static_cast<size_t>(a.info())] = 1;
    in[static_cast<size_t>(b.info())] = 1;
  });
  std::vector<CgalMesh::Face_index> range;
  for (size_t f = 0; f < in.size(); ++f)
    if (in[f]) range.emplace_back(static_cast<CgalMesh::size_type>(f));
  std::vector<std::pair<CgalMesh::Face_index, CgalMesh::Face_index>> pairs;
  PMP::self_intersections(range, m, std::back_inserter(pairs));
  return pairs;
}

}  // namespace

TriangleMesh remeshIsotropic(const TriangleMesh& mesh, int targetVertices) {
  if (targetVertices < 4) throw ParameterError("targetVertices", std::to_string(targetVertices), "must be at least 4");
  requireClosed(mesh, "remeshIsotropic");
  const CgalMesh input = detail::toCgalMesh(mesh, "remeshIsotropic");
  // Whether the input crosses itself matters only for a remesh that does, so it is asked then (once).
  std::optional<bool> inputEmbedded;
  // A closed genus-0 triangulation with V vertices has 2V − 4 faces; equilateral ones of edge L cover √3/4 L² each.
  // The remesher splits edges longer than 4/3 L and collapses those shorter than 4/5 L, and ends with about 15 % more
  // vertices than that count (measured on 27 phantom muscle templates): L is set 7 % longer for it.
  const double edge = 1.07 * std::sqrt(4.0 * surfaceArea(mesh) / (std::sqrt(3.0) * 2.0 * targetVertices));
  // A thin part can come out with a few crossing faces at one length and none at a slightly different one.
  for (double scale : {1.0, 0.97, 1.03, 0.94, 1.06}) {
    CgalMesh m = input;
    PMP::isotropic_remeshing(faces(m), scale * edge, m, CGAL::parameters::number_of_iterations(5));
    TriangleMesh out = detail::fromCgalMesh(std::move(m));
    if (!closedMeshProblem(out).empty()) continue;
    // Its vertices lie on the input's faces, so its chords cut the input's bends: offset back to the input's volume
    // (by a small fraction of an edge; a coarse ellipsoid of 162 vertices lost 3 % of its volume without it).
    offsetToVolume(out, enclosedVolume(mesh), 0.25 * edge);
    if (!crossingPairs(detail::toCgalMesh(out, "remeshIsotropic")).empty()) {
      if (!inputEmbedded) inputEmbedded = crossingPairs(input).empty();
      if (*inputEmbedded) continue;
    }
    return out;
  }
  return mesh;
}

bool isotropicTriangulation(const TriangleMesh& mesh, double maxVariation) {
  // Each edge of a closed surface is met twice, once from each of its faces: the same weight for every edge.
  double sum = 0, sumSq = 0;
  long count = 0;
  for (int f = 0; f < mesh.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) {
      const double l = (mesh.vertices.row(mesh.faces(f, k)) - mesh.vertices.row(mesh.faces(f, (k + 1) % 3))).norm();
      sum += l;
      sumSq += l * l;
      ++count;
    }
  if (count == 0) return false;
  const double mean = sum / static_cast<double>(count);
  const double variance = std::max(0.0, sumSq / static_cast<double>(count) - mean * mean);
  return mean > 0 && std::sqrt(variance) < maxVariation * mean;
}

size_t selfIntersections(const TriangleMesh& mesh) {
  requireClosed(mesh, "selfIntersections");
  return crossingPairs(detail::toCgalMesh(mesh, "selfIntersections")).size();
}

UnfoldReport unfoldSurface(TriangleMesh& mesh, int maxRounds) {
  requireClosed(mesh, "unfoldSurface");
  UnfoldReport rep;
  std::vector<std::vector<int>> ring(static_cast<size_t>(mesh.vertexCount()));  // each vertex's neighbours
  for (int f = 0; f < mesh.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) ring[static_cast<size_t>(mesh.faces(f, k))].push_back(mesh.faces(f, (k + 1) % 3));
  const Points start = mesh.vertices;
  std::vector<char> moved(ring.size(), 0);
  // After the first round only the faces with a smoothed corner can have started or stopped crossing: every face of a
  // crossing pair had its corners smoothed, so a pair of two faces without one crossed before and does not now.
  std::vector<char> changed;
  for (int round = 0;; ++round) {
    const CgalMesh cgal = detail::toCgalMesh(mesh, "unfoldSurface");
    const auto pairs = round == 0 ? crossingPairs(cgal) : crossingPairsNear(cgal, changed);
    if (round == 0) rep.before = pairs.size();
    rep.after = pairs.size();
    if (pairs.empty() || round == maxRounds) break;
    ++rep.rounds;
    std::vector<char> in(ring.size(), 0);
    for (const auto& [a, b] : pairs)
      for (CgalMesh::Face_index f : {a, b})
        for (int k = 0; k < 3; ++k) in[static_cast<size_t>(mesh.faces(static_cast<Eigen::Index>(f.idx()), k))] = 1;
    for (int grow = 0; grow < (round < 3 ? 1 : 2); ++grow) {
      std::vector<char> next = in;
      for (size_t v = 0; v < ring.size(); ++v)
        if (in[v])
          for (int u : ring[v]) next[static_cast<size_t>(u)] = 1;
      in.swap(next);
    }
    changed.assign(static_cast<size_t>(mesh.faceCount()), 0);
    for (int f = 0; f < mesh.faceCount(); ++f)
      for (int k = 0; k < 3; ++k) changed[static_cast<size_t>(f)] |= in[static_cast<size_t>(mesh.faces(f, k))];
    for (int it = 0; it < 3; ++it) {
      const Points x = mesh.vertices;
      for (size_t v = 0; v < ring.size(); ++v) {
        if (!in[v]) continue;
        Eigen::RowVector3d mean = Eigen::RowVector3d::Zero();
        for (int u : ring[v]) mean += x.row(u);
        mesh.vertices.row(static_cast<Eigen::Index>(v)) =
            0.5 * x.row(static_cast<Eigen::Index>(v)) + (0.5 / static_cast<double>(ring[v].size())) * mean;
        moved[v] = 1;
      }
    }
  }
  for (size_t v = 0; v < ring.size(); ++v) rep.verticesMoved += moved[v];
  rep.maxMoveMm = ring.empty() ? 0.0 : (mesh.vertices - start).rowwise().norm().maxCoeff();
  return rep;
}

std::string templateProblem(const TriangleMesh& t) {
  if (t.vertices.cwiseAbs().maxCoeff() > 1e6) return "coordinates beyond 1 km from the origin (not millimetres?)";
  const double area = surfaceArea(t);
  const double volume = enclosedVolume(t);
  if (!(area > 0) || !(std::abs(volume) > 1e-9 * std::pow(area, 1.5)))
    return "the surface encloses no volume (area " + std::to_string(area) + " mm², volume " + std::to_string(volume) +
           " mm³)";
  // A few crossing pairs are local folds, which the evolution smooths out (and remeshing removes); many mean surfaces
  // through each other, whose inside is not defined.
  const size_t crossing = selfIntersections(t);
  const size_t allowed = std::max<size_t>(10, static_cast<size_t>(t.faceCount()) / 200);
  if (crossing > allowed)
    return "the surface crosses itself (" + std::to_string(crossing) + " pairs of faces; at most " +
           std::to_string(allowed) + " local folds are accepted)";
  return "";
}

}  // namespace msk
