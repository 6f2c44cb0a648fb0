#pragma once
/// CGAL adapter, not part of the API: our triangle meshes as CGAL surface meshes and back. Shared by msk_imaging
/// (decimation) and msk_segmentation (proximity, remeshing, self-intersections); whoever includes it links CGAL.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/triangle_mesh.h"

namespace msk::detail {

using CgalKernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using CgalMesh = CGAL::Surface_mesh<CgalKernel::Point_3>;

/// `m` as a CGAL surface mesh, vertices and faces in the same order (face orientation kept). Throws Error naming
/// `what` and the face if a face would make the surface non-manifold.
inline CgalMesh toCgalMesh(const TriangleMesh& m, const std::string& what) {
  CgalMesh out;
  std::vector<CgalMesh::Vertex_index> id;
  id.reserve(static_cast<size_t>(m.vertexCount()));
  for (int v = 0; v < m.vertexCount(); ++v)
    id.push_back(out.add_vertex(CgalKernel::Point_3(m.vertices(v, 0), m.vertices(v, 1), m.vertices(v, 2))));
  for (int f = 0; f < m.faceCount(); ++f)
    if (out.add_face(id[static_cast<size_t>(m.faces(f, 0))], id[static_cast<size_t>(m.faces(f, 1))],
                     id[static_cast<size_t>(m.faces(f, 2))]) == CgalMesh::null_face())
      throw Error(what + ": face " + std::to_string(f) + " makes the surface non-manifold");
  return out;
}

/// A CGAL surface mesh of triangles back as our triangle mesh (garbage collected first; no per-vertex arrays).
inline TriangleMesh fromCgalMesh(CgalMesh m) {
  m.collect_garbage();
  TriangleMesh out;
  out.vertices.resize(static_cast<Eigen::Index>(m.number_of_vertices()), 3);
  for (CgalMesh::Vertex_index v : m.vertices()) {
    const auto& p = m.point(v);
    out.vertices.row(static_cast<Eigen::Index>(v.idx())) << p.x(), p.y(), p.z();
  }
  out.faces.resize(static_cast<Eigen::Index>(m.number_of_faces()), 3);
  for (CgalMesh::Face_index f : m.faces()) {
    int k = 0;
    for (CgalMesh::Vertex_index v : CGAL::vertices_around_face(m.halfedge(f), m))
      out.faces(static_cast<Eigen::Index>(f.idx()), k++) = static_cast<int>(v.idx());
  }
  return out;
}

}  // namespace msk::detail
