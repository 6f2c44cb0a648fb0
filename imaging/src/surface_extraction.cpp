// VTK adapter behind msk/imaging/surface_extraction.h (decimateMesh() is in surface_decimation.cpp): VTK types stay in
// this file and vtk_mesh.h.
#include "msk/imaging/surface_extraction.h"

#include <vtkCellArray.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkWindowedSincPolyDataFilter.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <unordered_map>
#include <vector>

#include "msk/core/error.h"
#include "vtk_mesh.h"

namespace msk {

namespace {

template <typename T>
using Ptr = vtkSmartPointer<T>;

/// Triangles of a vtkPolyData (polygons fan-triangulated), points copied as they are.
TriangleMesh fromVtk(vtkPolyData* poly) {
  TriangleMesh m;
  const vtkIdType np = poly->GetNumberOfPoints();
  m.vertices.resize(np, 3);
  for (vtkIdType i = 0; i < np; ++i) {
    double p[3];
    poly->GetPoint(i, p);
    m.vertices.row(i) << p[0], p[1], p[2];
  }
  std::vector<Eigen::Vector3i> tris;
  vtkCellArray* polys = poly->GetPolys();
  if (polys) {
    tris.reserve(static_cast<size_t>(polys->GetNumberOfCells()));
    vtkIdType npts = 0;
    const vtkIdType* pts = nullptr;
    for (polys->InitTraversal(); polys->GetNextCell(npts, pts);)
      for (vtkIdType k = 1; k + 1 < npts; ++k)
        tris.emplace_back(static_cast<int>(pts[0]), static_cast<int>(pts[k]), static_cast<int>(pts[k + 1]));
  }
  m.faces.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) m.faces.row(static_cast<Eigen::Index>(f)) = tris[f].transpose();
  return m;
}

/// Merges vertices with bit-identical coordinates, drops faces that became degenerate and unused vertices.
void mergeAndCompact(TriangleMesh& m) {
  struct Key {
    double x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct Hash {
    size_t operator()(const Key& k) const {
      uint64_t h = 1469598103934665603ull;
      for (double d : {k.x, k.y, k.z}) {
        uint64_t b;
        std::memcpy(&b, &d, sizeof b);
        h = (h ^ b) * 1099511628211ull;
      }
      return static_cast<size_t>(h);
    }
  };
  const int nv = m.vertexCount();
  std::vector<int> remap(static_cast<size_t>(nv));
  std::unordered_map<Key, int, Hash> seen;
  seen.reserve(static_cast<size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    Key k{m.vertices(i, 0), m.vertices(i, 1), m.vertices(i, 2)};
    remap[static_cast<size_t>(i)] = seen.emplace(k, i).first->second;
  }
  std::vector<Eigen::Vector3i> tris;
  tris.reserve(static_cast<size_t>(m.faceCount()));
  std::vector<int> used(static_cast<size_t>(nv), -1);
  int next = 0;
  for (int f = 0; f < m.faceCount(); ++f) {
    Eigen::Vector3i t(remap[static_cast<size_t>(m.faces(f, 0))], remap[static_cast<size_t>(m.faces(f, 1))],
                      remap[static_cast<size_t>(m.faces(f, 2))]);
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    for (int k = 0; k < 3; ++k) {
      int& u = used[static_cast<size_t>(t[k])];
      if (u < 0) u = next++;
    }
    tris.push_back(t);
  }
  TriangleMesh out;
  out.vertices.resize(next, 3);
  for (int i = 0; i < nv; ++i)
    if (used[static_cast<size_t>(i)] >= 0) out.vertices.row(used[static_cast<size_t>(i)]) = m.vertices.row(i);
  out.faces.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f)
    for (int k = 0; k < 3; ++k) out.faces(static_cast<Eigen::Index>(f), k) = used[static_cast<size_t>(tris[f][k])];
  m = std::move(out);
}

/// Keeps the vertex-connected component with the most faces.
void keepLargestComponent(TriangleMesh& m) {
  const int nv = m.vertexCount();
  std::vector<int> parent(static_cast<size_t>(nv));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int a) {
    while (parent[static_cast<size_t>(a)] != a) {
      int& p = parent[static_cast<size_t>(a)];
      p = parent[static_cast<size_t>(p)];  // path halving
      a = p;
    }
    return a;
  };
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 1; k < 3; ++k) {
      int a = find(m.faces(f, 0)), b = find(m.faces(f, k));
      if (a != b) parent[static_cast<size_t>(a)] = b;
    }
  std::unordered_map<int, int> count;
  for (int f = 0; f < m.faceCount(); ++f) ++count[find(m.faces(f, 0))];
  if (count.size() <= 1) return;
  int best = -1, bestCount = -1;
  for (const auto& kv : count)
    if (kv.second > bestCount || (kv.second == bestCount && kv.first < best)) best = kv.first, bestCount = kv.second;
  Triangles kept(bestCount, 3);
  int n = 0;
  for (int f = 0; f < m.faceCount(); ++f)
    if (find(m.faces(f, 0)) == best) kept.row(n++) = m.faces.row(f);
  m.faces = std::move(kept);
  mergeAndCompact(m);  // drops the vertices no longer used
}

void orientOutward(TriangleMesh& m) {
  if (m.faceCount() > 0 && enclosedVolume(m) < 0) flipFaces(m);
}

}  // namespace

TriangleMesh isosurface(const ImageF& field, double level, const IsosurfaceOptions& opts) {
  const std::string gridProblem = field.grid.problem();
  if (!gridProblem.empty()) throw Error("isosurface: invalid grid: " + gridProblem);
  if (field.data.size() != field.grid.voxelCount()) throw Error("isosurface: data size does not match the grid");
  if (!std::isfinite(level)) throw ParameterError("level", std::to_string(level), "must be finite");

  // g > 0 inside. Values exactly at (or within eps below) the level are nudged outside so that no vertex lands
  // exactly on a grid point (coincident vertices would make degenerate triangles).
  const double sign = opts.inside == IsoInside::Above ? 1.0 : -1.0;
  double gmin = 0, gabs = 0;
  bool any = false;
  for (float v : field.data) {
    if (!std::isfinite(v)) continue;
    const double g = sign * (static_cast<double>(v) - level);
    gmin = std::min(gmin, g);
    gabs = std::max(gabs, std::fabs(g));
    any = any || g > 0;
  }
  if (!any) return {};
  const double eps = std::max(1e-4 * gabs, 1e-12);
  const float outside = static_cast<float>(std::min(gmin, -eps));

  const Eigen::Vector3i d = field.grid.dims;
  auto image = Ptr<vtkImageData>::New();
  image->SetDimensions(d[0] + 2, d[1] + 2, d[2] + 2);
  image->SetOrigin(-1, -1, -1);
  image->SetSpacing(1, 1, 1);
  auto scalars = Ptr<vtkFloatArray>::New();
  scalars->SetNumberOfTuples(static_cast<vtkIdType>(d[0] + 2) * (d[1] + 2) * (d[2] + 2));
  float* out = scalars->WritePointer(0, scalars->GetNumberOfTuples());
  size_t n = 0;
  for (int k = -1; k <= d[2]; ++k)
    for (int j = -1; j <= d[1]; ++j)
      for (int i = -1; i <= d[0]; ++i, ++n) {
        float g = outside;
        if (field.grid.contains(i, j, k)) {
          const float v = field.at(i, j, k);
          if (std::isfinite(v)) {
            g = static_cast<float>(sign * (static_cast<double>(v) - level));
            if (g <= 0) g = std::min(g, static_cast<float>(-eps));
          }
        }
        out[n] = g;
      }
  scalars->SetName("g");
  image->GetPointData()->SetScalars(scalars);

  auto fe = Ptr<vtkFlyingEdges3D>::New();
  fe->SetInputData(image);
  fe->SetNumberOfContours(1);
  fe->SetValue(0, 0.0);
  fe->ComputeNormalsOff();
  fe->ComputeGradientsOff();
  fe->ComputeScalarsOff();
  fe->InterpolateAttributesOff();
  fe->Update();

  TriangleMesh m = fromVtk(fe->GetOutput());
  mergeAndCompact(m);
  for (int i = 0; i < m.vertexCount(); ++i)
    m.vertices.row(i) = field.grid.toWorld(m.vertices.row(i).transpose()).transpose();
  if (opts.largestComponentOnly) keepLargestComponent(m);
  orientOutward(m);
  const std::string problem = closedMeshProblem(m);
  MSK_ASSERT(problem.empty(), "isosurface is not a closed manifold: " + problem);
  return m;
}

TriangleMesh smoothMesh(const TriangleMesh& mesh, int iterations, double passBand) {
  if (iterations < 0) throw ParameterError("iterations", std::to_string(iterations), "must be >= 0");
  if (!(passBand > 0 && passBand < 2)) throw ParameterError("passBand", std::to_string(passBand), "must be in (0, 2)");
  if (iterations == 0 || mesh.vertexCount() == 0) return mesh;
  auto filter = Ptr<vtkWindowedSincPolyDataFilter>::New();
  filter->SetInputData(detail::toPolyData(mesh));
  filter->SetNumberOfIterations(iterations);
  filter->SetPassBand(passBand);
  filter->BoundarySmoothingOff();
  filter->FeatureEdgeSmoothingOff();
  filter->NonManifoldSmoothingOn();
  filter->NormalizeCoordinatesOn();
  filter->Update();
  vtkPolyData* out = filter->GetOutput();
  MSK_ASSERT(out->GetNumberOfPoints() == mesh.vertexCount(), "smoothing changed the number of points");
  TriangleMesh m = mesh;
  for (int i = 0; i < m.vertexCount(); ++i) {
    double p[3];
    out->GetPoint(i, p);
    m.vertices.row(i) << p[0], p[1], p[2];
  }
  return m;
}

}  // namespace msk
