#include "msk/segmentation/tetrahedralize.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Polyhedron_3.h>
#include <CGAL/Random.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/lloyd_optimize_mesh_3.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/odt_optimize_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/tet_split.h"
#include "msk/core/tet_untangle.h"

namespace msk {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Polyhedron = CGAL::Polyhedron_3<Kernel>;
using Domain = CGAL::Polyhedral_mesh_domain_3<Polyhedron, Kernel>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

void checkPositive(const char* name, double v, bool zeroAllowed) {
  if (!(zeroAllowed ? v >= 0 : v > 0) || !std::isfinite(v))
    throw ParameterError(name, std::to_string(v), zeroAllowed ? "must be ≥ 0 (0 = derived)" : "must be > 0");
}

/// The surface as a CGAL polyhedron (the soup is a closed oriented manifold, checked by the caller).
Polyhedron toPolyhedron(const TriangleMesh& mesh) {
  std::vector<Kernel::Point_3> points;
  points.reserve(static_cast<size_t>(mesh.vertexCount()));
  for (int v = 0; v < mesh.vertexCount(); ++v)
    points.emplace_back(mesh.vertices(v, 0), mesh.vertices(v, 1), mesh.vertices(v, 2));
  std::vector<std::array<std::size_t, 3>> faces;
  faces.reserve(static_cast<size_t>(mesh.faceCount()));
  for (int f = 0; f < mesh.faceCount(); ++f)
    faces.push_back({static_cast<std::size_t>(mesh.faces(f, 0)), static_cast<std::size_t>(mesh.faces(f, 1)),
                     static_cast<std::size_t>(mesh.faces(f, 2))});
  Polyhedron poly;
  CGAL::Polygon_mesh_processing::polygon_soup_to_polygon_mesh(points, faces, poly);
  return poly;
}

}  // namespace

TetMesh tetrahedralize(const TriangleMesh& surface, const TetOptions& opt) {
  const std::string problem = closedMeshProblem(surface);
  if (!problem.empty()) throw Error("tetrahedralize: the surface is not closed: " + problem);
  if (!(enclosedVolume(surface) > 0))
    throw Error("tetrahedralize: the surface encloses no volume (inward-oriented or flat)");
  checkPositive("cell size (mm)", opt.cellSizeMm, true);
  checkPositive("facet size (mm)", opt.facetSizeMm, true);
  checkPositive("facet distance (mm)", opt.facetDistanceMm, true);
  if (!(opt.facetAngleDeg > 0 && opt.facetAngleDeg <= 30))
    throw ParameterError("facet angle (degrees)", std::to_string(opt.facetAngleDeg), "must be in (0, 30]");
  if (!(opt.sliverBoundDeg >= 0 && opt.sliverBoundDeg < 70.6))
    throw ParameterError("sliver bound (degrees)", std::to_string(opt.sliverBoundDeg), "must be in [0, 70.5]");
  if (opt.optimiseIterations < 1)
    throw ParameterError("optimiser passes", std::to_string(opt.optimiseIterations), "must be ≥ 1");
  if (!(opt.cellRadiusEdgeRatio >= 2))
    throw ParameterError("cell radius-edge ratio", std::to_string(opt.cellRadiusEdgeRatio), "must be ≥ 2");

  // Derived sizes, relative to the bounding-box diagonal.
  const double diag = (surface.vertices.colwise().maxCoeff() - surface.vertices.colwise().minCoeff()).norm();
  const double cell = opt.cellSizeMm > 0 ? opt.cellSizeMm : diag / 15.0;
  const double facet = opt.facetSizeMm > 0 ? opt.facetSizeMm : cell;
  const double distance = opt.facetDistanceMm > 0 ? opt.facetDistanceMm : cell / 20.0;

  const Polyhedron poly = toPolyhedron(surface);
  // Repeatable runs: the domain's initial points come from `rng`, and CGAL's default generator (used elsewhere in
  // Mesh_3, e.g. by the random shuffles of spatial sorting) is reset to the same seed before every run.
  CGAL::Random rng(opt.seed);
  CGAL::get_default_random() = CGAL::Random(opt.seed);
  const Domain domain(poly, &rng);
  namespace p = CGAL::parameters;
  const Criteria criteria(p::facet_angle = opt.facetAngleDeg, p::facet_size = facet, p::facet_distance = distance,
                          p::cell_radius_edge_ratio = opt.cellRadiusEdgeRatio, p::cell_size = cell);
  Complex c3t3 =
      CGAL::make_mesh_3<Complex>(domain, criteria, p::no_perturb(), p::no_exude(), p::no_lloyd(), p::no_odt());
  // Optimisers in CGAL's order (global smoothing, then perturbation, then exudation), none with a time limit.
  if (opt.odt) CGAL::odt_optimize_mesh_3(c3t3, domain, p::max_iteration_number = opt.optimiseIterations);
  if (opt.lloyd) CGAL::lloyd_optimize_mesh_3(c3t3, domain, p::max_iteration_number = opt.optimiseIterations);
  if (opt.perturb) CGAL::perturb_mesh_3(c3t3, domain, p::sliver_bound = opt.sliverBoundDeg);
  if (opt.exude) CGAL::exude_mesh_3(c3t3, p::sliver_bound = opt.sliverBoundDeg);

  // Cells inside the domain → tets; vertices numbered in order of first use.
  const Triangulation& tr = c3t3.triangulation();
  std::map<Triangulation::Vertex_handle, int> index;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<int, 4>> tets;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    std::array<int, 4> t{};
    for (int i = 0; i < 4; ++i) {
      const auto v = c->vertex(i);
      auto it = index.find(v);
      if (it == index.end()) {
        const auto& q = tr.point(v).point();
        it = index.emplace(v, static_cast<int>(nodes.size())).first;
        nodes.emplace_back(CGAL::to_double(q.x()), CGAL::to_double(q.y()), CGAL::to_double(q.z()));
      }
      t[i] = it->second;
    }
    if (signedTetVolume(nodes[t[0]], nodes[t[1]], nodes[t[2]], nodes[t[3]]) < 0) std::swap(t[2], t[3]);
    tets.push_back(t);
  }
  if (tets.empty()) throw Error("tetrahedralize: the mesher produced no tetrahedra (surface too small for the sizes?)");

  // Canonical order: CGAL's cell order follows its memory layout, which differs between runs in one process. Nodes
  // sorted by coordinates, each tet written as its lexicographically smallest even permutation (same orientation),
  // tets sorted.
  std::vector<int> order(nodes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::sort(order.begin(), order.end(), [&nodes](int a, int b) {
    return std::lexicographical_compare(nodes[a].data(), nodes[a].data() + 3, nodes[b].data(), nodes[b].data() + 3);
  });
  std::vector<int> rank(nodes.size());
  for (size_t i = 0; i < order.size(); ++i) rank[static_cast<size_t>(order[i])] = static_cast<int>(i);
  static const int kEven[12][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 0, 3, 2}, {1, 2, 0, 3}, {1, 3, 2, 0},
                                   {2, 0, 1, 3}, {2, 1, 3, 0}, {2, 3, 0, 1}, {3, 0, 2, 1}, {3, 1, 0, 2}, {3, 2, 1, 0}};
  for (auto& t : tets) {
    const std::array<int, 4> r = {rank[t[0]], rank[t[1]], rank[t[2]], rank[t[3]]};
    std::array<int, 4> best = r;
    for (const auto& perm : kEven)
      best = std::min(best, std::array<int, 4>{r[perm[0]], r[perm[1]], r[perm[2]], r[perm[3]]});
    t = best;
  }
  std::sort(tets.begin(), tets.end());

  TetMesh out;
  out.nodes.resize(static_cast<Eigen::Index>(nodes.size()), 3);
  for (size_t i = 0; i < nodes.size(); ++i) out.nodes.row(static_cast<Eigen::Index>(i)) = nodes[order[i]].transpose();
  out.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (size_t i = 0; i < tets.size(); ++i)
    out.tets.row(static_cast<Eigen::Index>(i)) << tets[i][0], tets[i][1], tets[i][2], tets[i][3];
  const std::string tp = tetMeshProblem(out);
  if (!tp.empty()) throw Error("tetrahedralize: invalid output: " + tp);
  if (opt.interiorNodes) {
    const int before = out.nodeCount();
    out = splitBoundaryTets(out, nullptr, opt.interiorSplit);
    // The Steiner nodes start at edge midpoints or face centroids, often just inside the surface: moved away from small
    // tets (volume energy against the mean tet), then to raise their tets' worst shape quality (the other nodes stay,
    // so the boundary and the mesher's nodes are kept). Without the shape pass ~100 tets per muscle had a dihedral
    // angle under 5 degrees, with it 0-8.
    std::vector<char> steiner(static_cast<size_t>(out.nodeCount()), 0);
    std::fill(steiner.begin() + before, steiner.end(), 1);
    TetUntangleOptions smooth;
    smooth.minRelativeVolume = std::numeric_limits<double>::infinity();
    smooth.maxSweeps = 10;
    const Eigen::VectorXd typical = Eigen::VectorXd::Constant(out.tetCount(), totalVolume(out) / out.tetCount());
    untangleTets(out, steiner, typical, smooth);
    improveTetShapes(out, steiner);
    const std::string sp = tetMeshProblem(out);
    if (!sp.empty()) throw Error("tetrahedralize: invalid output after the interior-node split: " + sp);
  }
  return out;
}

TetOptions volumeModelTetOptions(const TriangleMesh& templ) {
  const double edge = meanEdgeLength(templ);
  TetOptions to;
  to.facetSizeMm = edge;
  to.cellSizeMm = 1.5 * edge;
  to.facetDistanceMm = 0.1 * edge;
  to.odt = to.perturb = to.exude = true;
  to.interiorNodes = true;
  return to;
}

}  // namespace msk
