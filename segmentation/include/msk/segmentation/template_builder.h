#pragma once
/// Template surfaces from label maps: one label → a smooth closed triangle mesh in world RAS mm, and mirroring of
/// a template across a plane (a contralateral template from the other side's label).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Parameters of templateFromLabels() (user input only; 0 means "relative to the voxel size").
struct TemplateOptions {
  int vertices = 3000;  ///< target vertex count after decimation (the isosurface is kept if it has fewer); ≥ 4
  /// Gaussian sigma (mm) applied to the binary mask before the 0.5 isosurface; 0 → 0.5 × the largest voxel
  /// spacing (1.5 mm on 3 mm slices: removes the slice staircase, keeps features of a few voxels).
  double smoothingSigmaMm = 0;
  bool largestComponent = true;  ///< keep only the largest 26-connected component of the label
  /// Offset the final surface along its normals so that its enclosed volume equals the mask's voxel volume
  /// (Gaussian smoothing moves the 0.5 level inward on convex parts by about σ²·H, H the mean curvature).
  bool preserveVolume = true;
  /// A label cut by a face of its grid (the scan's field of view ends inside the structure) is continued this far
  /// (mm) beyond that face before the surface is made: its last slice's section repeated straight outward, so that
  /// another subject whose scan shows more of the structure has a template that reaches into it (the structures of
  /// one scan, continued alike, keep their places relative to one another). 0: a flat cap on the face. Faces where
  /// the label's section is under 10 % of its largest section along that axis (a structure grazing the edge) are not
  /// continued.
  double extendCutMm = 0;
};

/// Throws ParameterError, naming the command-line option (--vertices, --smooth), for options out of range.
void checkTemplateOptions(const TemplateOptions& opts);

/// What templateFromLabels() did (for reports).
struct TemplateReport {
  double sigmaMm = 0;            ///< Gaussian sigma used
  size_t voxels = 0;             ///< voxels of the label kept (after the largest-component step)
  size_t componentsDropped = 0;  ///< other components discarded
  double maskVolumeMm3 = 0;      ///< voxels × voxel volume of what was kept
  double offsetMm = 0;           ///< normal offset applied by preserveVolume (0 if off)
  /// The faces of the grid the label was cut by and continued beyond (extendCutMm), each named by the anatomical
  /// direction it faces ("inferior", "superior", "left", "right", "anterior", "posterior").
  std::vector<std::string> extendedFaces;
  double extendedMm = 0;         ///< how far each was continued (the slices added × their spacing)
  double extendedVolumeMm3 = 0;  ///< the volume added beyond the grid (the template encloses mask + this)
};

/// Smooth closed template of `label`: binary mask (cropped to the label with a margin, largest component) →
/// float (1 inside) → gaussianSmooth(σ) → isosurface at 0.5 (largest component) → windowed-sinc smoothing
/// (non-shrinking) → quadric decimation to `opts.vertices` → volume-preserving normal offset. World RAS mm,
/// outward oriented, passes closedMeshProblem(). An object cut by the grid border gets a flat cap on the voxel
/// boundary, or is continued beyond it (TemplateOptions::extendCutMm). Throws Error "label N not found" if no voxel
/// has the label, ParameterError for invalid options.
TriangleMesh templateFromLabels(const LabelMap& labels, int label, const TemplateOptions& opts = {},
                                TemplateReport* report = nullptr);

/// Reflection of a mesh across the plane through `planePoint` with normal `planeNormal` (any length > 0):
/// x' = x − 2((x − p)·n)n. Faces are flipped so the normals stay outward; point data is kept.
/// Throws ParameterError for a zero or non-finite normal.
TriangleMesh mirrorMesh(const TriangleMesh& mesh, const Eigen::Vector3d& planePoint,
                        const Eigen::Vector3d& planeNormal);

}  // namespace msk
