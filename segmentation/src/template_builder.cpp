#include "msk/segmentation/template_builder.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/filters.h"
#include "msk/imaging/surface_extraction.h"

namespace msk {

namespace {

/// Windowed-sinc smoothing after the isosurface: removes the marching-cubes facets without shrinking.
constexpr int kSmoothIterations = 20;
constexpr double kSmoothPassBand = 0.1;
/// Largest isotropic grid the smoothed mask is resampled onto before the isosurface (voxels; 128 MB of floats).
constexpr double kMaxFineVoxels = 32e6;
/// A cut label is continued beyond a face only where its section there is at least this share of its largest
/// section along the face's axis.
constexpr double kMinCutSectionShare = 0.1;

/// The anatomical name of the world direction `d` (RAS): its largest component.
const char* anatomicalDirection(const Eigen::Vector3d& d) {
  static const char* const names[3][2] = {{"left", "right"}, {"posterior", "anterior"}, {"inferior", "superior"}};
  int a = 0;
  d.cwiseAbs().maxCoeff(&a);
  return names[a][d[a] > 0 ? 1 : 0];
}

/// The area (in voxels) of the section of `field` at index `t` along `axis`.
double sectionArea(const ImageF& field, int axis, int t) {
  const int b = (axis + 1) % 3, c = (axis + 2) % 3;
  double area = 0;
  Eigen::Vector3i ijk;
  ijk[axis] = t;
  for (int y = 0; y < field.grid.dims[c]; ++y)
    for (int x = 0; x < field.grid.dims[b]; ++x) {
      ijk[b] = x, ijk[c] = y;
      area += field.at(ijk[0], ijk[1], ijk[2]);
    }
  return area;
}

/// `field` (1 inside) continued by `slices` copies of its section on the face on `side` (−1: index 0, +1: the last
/// index) of `axis`. The section is repeated straight along the axis, not drifted with the structure's own axis: the
/// structures of one scan, continued alike, keep their places relative to one another and do not run into each other.
ImageF extendBeyondFace(const ImageF& field, int axis, int side, int slices) {
  const Grid& g = field.grid;
  Grid grown = g;
  grown.dims[axis] += slices;
  Eigen::Vector3d firstVoxel = Eigen::Vector3d::Zero();
  if (side < 0) firstVoxel[axis] = -slices;
  grown.origin = g.toWorld(firstVoxel);
  ImageF out(grown, 0.f);
  const int shift = side < 0 ? slices : 0;
  for (int k = 0; k < grown.dims[2]; ++k)
    for (int j = 0; j < grown.dims[1]; ++j)
      for (int i = 0; i < grown.dims[0]; ++i) {
        Eigen::Vector3i from(i, j, k);
        from[axis] = std::clamp(from[axis] - shift, 0, g.dims[axis] - 1);  // beyond the face: the face's section
        out.at(i, j, k) = field.at(from[0], from[1], from[2]);
      }
  return out;
}

/// Keeps only the largest 26-connected component of `mask` (1 = inside); returns the number of components dropped.
size_t keepLargestComponent(std::vector<uint8_t>& mask, const Grid& g) {
  std::vector<int> comp(mask.size(), -1);
  std::vector<size_t> sizes, stack;
  for (size_t seed = 0; seed < mask.size(); ++seed) {
    if (!mask[seed] || comp[seed] >= 0) continue;
    const int id = static_cast<int>(sizes.size());
    size_t count = 0;
    comp[seed] = id;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const size_t n = stack.back();
      stack.pop_back();
      ++count;
      const int i = static_cast<int>(n % g.dims[0]), j = static_cast<int>((n / g.dims[0]) % g.dims[1]),
                k = static_cast<int>(n / (static_cast<size_t>(g.dims[0]) * g.dims[1]));
      for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            if (!g.contains(i + di, j + dj, k + dk)) continue;
            const size_t m = g.index(i + di, j + dj, k + dk);
            if (mask[m] && comp[m] < 0) {
              comp[m] = id;
              stack.push_back(m);
            }
          }
    }
    sizes.push_back(count);
  }
  if (sizes.size() <= 1) return 0;
  const int best = static_cast<int>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  for (size_t n = 0; n < mask.size(); ++n)
    if (mask[n] && comp[n] != best) mask[n] = 0;
  return sizes.size() - 1;
}

}  // namespace

void checkTemplateOptions(const TemplateOptions& opts) {
  if (opts.vertices < 4 || opts.vertices > 10000000)
    throw ParameterError("--vertices", std::to_string(opts.vertices), "must be in 4..10000000");
  if (!(opts.smoothingSigmaMm >= 0) || !std::isfinite(opts.smoothingSigmaMm))
    throw ParameterError("--smooth", std::to_string(opts.smoothingSigmaMm),
                         "must be >= 0 mm (0: half the largest voxel spacing)");
  if (!(opts.extendCutMm >= 0 && opts.extendCutMm <= 500))
    throw ParameterError("--extend-cut", std::to_string(opts.extendCutMm), "must be in [0, 500] mm");
}

TriangleMesh templateFromLabels(const LabelMap& labels, int label, const TemplateOptions& opts,
                                TemplateReport* report) {
  checkTemplateOptions(opts);
  const Grid& g = labels.grid;
  const std::string gridProblem = g.problem();
  if (!gridProblem.empty()) throw Error("templateFromLabels: invalid grid: " + gridProblem);
  if (labels.data.size() != g.voxelCount()) throw Error("templateFromLabels: data size does not match the grid");

  // Bounding box of the label in voxels.
  Eigen::Vector3i lo = g.dims, hi = Eigen::Vector3i::Constant(-1);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (labels.at(i, j, k) == label) {
          lo = lo.cwiseMin(Eigen::Vector3i(i, j, k));
          hi = hi.cwiseMax(Eigen::Vector3i(i, j, k));
        }
  if (hi[0] < 0) throw Error("label " + std::to_string(label) + " not found");

  const double sigma = opts.smoothingSigmaMm > 0 ? opts.smoothingSigmaMm : 0.5 * g.spacing.maxCoeff();

  // Crop with the kernel's reach plus one voxel; clamped to the grid, where the replicated border of the smoothing
  // and the isosurface's outside padding put a flat cap on the voxel boundary.
  Grid crop = g;
  Eigen::Vector3i start;
  for (int a = 0; a < 3; ++a) {
    const int margin = static_cast<int>(std::ceil(4.0 * sigma / g.spacing[a])) + 1;
    start[a] = std::max(lo[a] - margin, 0);
    crop.dims[a] = std::min(hi[a] + margin, g.dims[a] - 1) - start[a] + 1;
  }
  crop.origin = g.toWorld(start.cast<double>());

  std::vector<uint8_t> mask(crop.voxelCount(), 0);
  for (int k = 0; k < crop.dims[2]; ++k)
    for (int j = 0; j < crop.dims[1]; ++j)
      for (int i = 0; i < crop.dims[0]; ++i)
        mask[crop.index(i, j, k)] = labels.at(start[0] + i, start[1] + j, start[2] + k) == label;
  const size_t dropped = opts.largestComponent ? keepLargestComponent(mask, crop) : 0;

  ImageF field(crop, 0.f);
  size_t voxels = 0;
  for (size_t n = 0; n < mask.size(); ++n) {
    field.data[n] = mask[n] ? 1.f : 0.f;
    voxels += mask[n];
  }
  const double maskVolume = static_cast<double>(voxels) * g.spacing.prod();
  double targetVolume = maskVolume;  // the label's, and what continuing it beyond the grid adds

  // Faces of the grid that cut the label (its crop reaches them and its section there is not a graze): continued.
  std::vector<std::string> extendedFaces;
  double extendedMm = 0;
  if (opts.extendCutMm > 0) {
    for (int a = 0; a < 3; ++a)
      for (int side : {-1, 1}) {
        const bool atFace = side < 0 ? start[a] == 0 : start[a] + crop.dims[a] == g.dims[a];
        if (!atFace) continue;
        const int faceIndex = side < 0 ? 0 : field.grid.dims[a] - 1;
        double largest = 0;
        for (int t = 0; t < field.grid.dims[a]; ++t) largest = std::max(largest, sectionArea(field, a, t));
        const double atEdge = sectionArea(field, a, faceIndex);
        if (!(atEdge > 0 && atEdge >= kMinCutSectionShare * largest)) continue;
        const int slices = std::max(1, static_cast<int>(std::ceil(opts.extendCutMm / g.spacing[a] - 1e-9)));
        const double before = std::accumulate(field.data.begin(), field.data.end(), 0.0);
        field = extendBeyondFace(field, a, side, slices);
        targetVolume += (std::accumulate(field.data.begin(), field.data.end(), 0.0) - before) * g.spacing.prod();
        extendedFaces.emplace_back(anatomicalDirection(side * g.direction.col(a)));
        extendedMm = std::max(extendedMm, slices * g.spacing[a]);
      }
  }

  // Smoothed mask, then one voxel of zeros around it: a structure cut by the grid border (replicated by the
  // smoothing) gets its 0.5 level, a flat cap, half a voxel beyond the last voxel centre, on the voxel boundary.
  const ImageF smoothed = gaussianSmooth(field, sigma);
  const Grid& fieldGrid = field.grid;
  Grid padded = fieldGrid;
  padded.dims += Eigen::Vector3i::Constant(2);
  padded.origin = fieldGrid.toWorld(Eigen::Vector3d::Constant(-1));
  ImageF smoothPadded(padded, 0.f);
  for (int k = 0; k < fieldGrid.dims[2]; ++k)
    for (int j = 0; j < fieldGrid.dims[1]; ++j)
      for (int i = 0; i < fieldGrid.dims[0]; ++i) smoothPadded.at(i + 1, j + 1, k + 1) = smoothed.at(i, j, k);

  // Isosurface on an isotropic grid (trilinear resampling of the smooth field): well-shaped triangles on thick
  // slices, and enough of them for the decimation to reach the target count.
  const Eigen::Vector3d extent = padded.spacing.cwiseProduct((padded.dims - Eigen::Vector3i::Ones()).cast<double>());
  IsosurfaceOptions iso;
  iso.largestComponentOnly = opts.largestComponent;
  // Fine step: the smallest spacing, coarser if the grid would exceed kMaxFineVoxels; refined (down to a quarter
  // of the smallest spacing) if the surface has fewer vertices than asked.
  const double hMin = 0.25 * g.spacing.minCoeff();
  double h = std::max(g.spacing.minCoeff(), std::cbrt(extent.prod() / kMaxFineVoxels));
  TriangleMesh mesh;
  for (int attempt = 0; attempt < 3; ++attempt) {
    Grid fine = padded;
    fine.spacing = Eigen::Vector3d::Constant(h);
    for (int a = 0; a < 3; ++a) fine.dims[a] = static_cast<int>(std::floor(extent[a] / h + 1e-9)) + 1;
    mesh = isosurface(resample(smoothPadded, fine, 0.f), 0.5, iso);
    MSK_ASSERT(mesh.faceCount() > 0, "the smoothed mask of label " + std::to_string(label) + " has no 0.5 level");
    // Marching-cubes vertex counts grow as 1/h²: aim for twice the target so the decimation chooses the vertices.
    const double next = std::max(
        {hMin, h * std::sqrt(mesh.vertexCount() / (2.0 * opts.vertices)), std::cbrt(extent.prod() / kMaxFineVoxels)});
    if (mesh.vertexCount() >= opts.vertices || next >= h) break;
    h = next;
  }
  mesh = smoothMesh(mesh, kSmoothIterations, kSmoothPassBand);
  mesh = decimateMesh(mesh, opts.vertices);

  // Volume-preserving offset along the normals: δ = (V_mask − V) / area, twice (the area changes with δ), limited
  // to ±σ so that a thin structure the smoothing nearly erased is not inflated into nonsense.
  const double offset = opts.preserveVolume ? offsetToVolume(mesh, targetVolume, sigma) : 0.0;
  const std::string problem = closedMeshProblem(mesh);
  MSK_ASSERT(problem.empty(), "template of label " + std::to_string(label) + " is not closed: " + problem);
  if (report) {
    report->sigmaMm = sigma;
    report->voxels = voxels;
    report->componentsDropped = dropped;
    report->maskVolumeMm3 = maskVolume;
    report->offsetMm = offset;
    report->extendedFaces = extendedFaces;
    report->extendedMm = extendedMm;
    report->extendedVolumeMm3 = targetVolume - maskVolume;
  }
  return mesh;
}

TriangleMesh mirrorMesh(const TriangleMesh& mesh, const Eigen::Vector3d& planePoint,
                        const Eigen::Vector3d& planeNormal) {
  const double len = planeNormal.norm();
  if (!(len > 0) || !std::isfinite(len) || !planePoint.allFinite())
    throw ParameterError(
        "planeNormal",
        std::to_string(planeNormal.x()) + "," + std::to_string(planeNormal.y()) + "," + std::to_string(planeNormal.z()),
        "must be a finite non-zero vector (and the plane point finite)");
  const Eigen::Vector3d n = planeNormal / len;
  Eigen::Matrix4d h = Eigen::Matrix4d::Identity();
  h.topLeftCorner<3, 3>() -= 2.0 * n * n.transpose();
  h.topRightCorner<3, 1>() = 2.0 * n.dot(planePoint) * n;
  TriangleMesh out = mesh;
  transformMesh(out, h);  // det = −1: windings flipped, normals stay outward
  return out;
}

}  // namespace msk
