#pragma once
/// Shared test helpers: scratch folders, the real-data folder, running the mskseg program, and the real-scan helpers
/// (label centroids, contralateral templates, cropping).
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/template_builder.h"

namespace msk::test {

/// A fresh empty folder under the system temp dir, removed when the object dies.
class ScratchDir {
 public:
  ScratchDir();
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  /// The folder.
  const std::string& path() const { return path_; }
  /// path()/name.
  std::string file(const std::string& name) const { return path_ + "/" + name; }
  /// Names of the files in the folder (sorted).
  std::vector<std::string> list() const;

 private:
  std::string path_;
};

/// ../shared/data (or MSK_SHARED_DATA), empty string if absent.
std::string sharedData();

/// Result of running the CLI.
struct CliResult {
  int exitCode = -1;
  std::string out, err;
};

/// Runs the built mskseg with arguments (each shell-quoted), capturing stdout and stderr.
CliResult runCli(const std::vector<std::string>& args);

/// Number of lines in a text.
int lineCount(const std::string& text);

/// Checks a failed CLI run: the exit code, exactly one line on stderr, naming `file` (if non-empty) and `phrase`.
void expectOneLineError(const CliResult& r, int code, const std::string& file, const std::string& phrase);

/// Writes bytes to a file (test fixtures).
void writeBytes(const std::string& path, const std::string& bytes);
/// Reads a whole file.
std::string readBytes(const std::string& path);

/// Centroid (world RAS mm) of the voxels carrying `label`; throws msk::Error if there are none.
Eigen::Vector3d labelCentroid(const LabelMap& labels, int label);

/// Template of the other side: the smooth template of `fromLabel`, mirrored across the sagittal plane x = `midX`
/// (RAS mm).
TriangleMesh mirroredTemplate(const LabelMap& labels, int fromLabel, double midX, const TemplateOptions& opts = {});

/// One mesh holding both surfaces (b's vertices after a's, its faces renumbered): a surface covering some points
/// twice, or with a turned-over sheet when b's faces are reversed.
/// An image on `grid` with partial volume: each voxel is `inside` × f + `outside` × (1 − f), f the share of its 4³
/// sub-samples (world points) for which `isInside` holds.
ImageF partialVolumeImage(const Grid& grid, const std::function<bool(const Eigen::Vector3d&)>& isInside, float inside,
                          float outside);

TriangleMesh joinedMeshes(const TriangleMesh& a, const TriangleMesh& b);

/// The mesh scaled by `scale` about its vertex centroid, then moved by `offsetMm` (a template never exactly in place).
TriangleMesh displacedScaled(const TriangleMesh& mesh, const Eigen::Vector3d& offsetMm, double scale);

/// Voxel box [lo, hi] (inclusive, clipped to the grid) holding every vertex of `meshes` plus `marginMm`.
void voxelBox(const Grid& grid, const std::vector<TriangleMesh>& meshes, double marginMm, Eigen::Vector3i& lo,
              Eigen::Vector3i& hi);

/// The sub-volume of voxels [lo, hi] (inclusive), on a grid with the same spacing and direction (world positions kept).
ImageF cropVolume(const ImageF& image, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi);
/// Same for a label map.
LabelMap cropVolume(const LabelMap& labels, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi);

}  // namespace msk::test
