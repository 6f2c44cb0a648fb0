#pragma once
/// Atlas scenarios, shared by the segmentation tests (which assert on them) and bench/atlas_bench.cpp (which reports
/// their figures): an atlas built from one subject (a phantom seed, or a real scan mirrored so that its left side
/// stands for the right), placed by registration in another subject (another seed in another pose, or the scan moved
/// in world space), segmented and scored against the subject's reference labels.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "msk/imaging/volume.h"
#include "msk/phantom/phantom.h"
#include "msk/phantom/phantom_pose.h"
#include "msk/segmentation/atlas.h"
#include "msk/segmentation/metrics.h"
#include "msk/segmentation/segmenter.h"

namespace msk::test {

/// An atlas to build and a subject to segment with it.
struct AtlasCase {
  std::string name;
  ImageF atlasImage;
  LabelMap atlasLabels;
  std::vector<AtlasObjectSpec> objects;
  ImageF subject;
  LabelMap subjectLabels;
  std::vector<int> referenceLabel;  ///< per object: its label in subjectLabels
  SegmentOptions options;           ///< the run's options (those of the templates-in-place scene of the same scan)
  bool refineBones = false;         ///< the bones take the refinement pass (as in the templates-in-place scene)
  /// Further subjects of the atlas (image, labels), after the reference (atlasImage, atlasLabels).
  std::vector<std::pair<ImageF, LabelMap>> moreSubjects;
  AtlasStarts starts = AtlasStarts::Each;  ///< with moreSubjects: which subjects the segmentation starts from
};

/// Moves a grid in world space by the rigid motion or mirror `m` (orthonormal 3×3 part): the voxels stay, the affine
/// becomes m·A.
void moveGrid(Grid& grid, const Eigen::Matrix4d& m);

/// The rigid motion of `degrees` about the axis (1, 2, 3)/√14 through `centre`, then `mm` along (2, −1, 1)/√6.
Eigen::Matrix4d knownMove(double degrees, double mm, const Eigen::Vector3d& centre);

/// Phantom: the atlas from seed `atlasSeed` (un-posed), the subject seed `subjectSeed` in `pose`; femur,
/// quadriceps, hamstrings, adductors.
AtlasCase phantomAtlasCase(uint32_t atlasSeed, uint32_t subjectSeed, const PhantomPose& pose);

/// Phantom: the atlas from the seeds `atlasSeeds` (un-posed; the first the reference), the subject seed `subjectSeed`
/// in `pose`.
AtlasCase phantomAtlasCase(const std::vector<uint32_t>& atlasSeeds, uint32_t subjectSeed, const PhantomPose& pose);

/// Phantom: the atlas and the subject as the options generate them (meshes are not made): other fields of view
/// (PhantomOptions::fovZ), voxel sizes or noise on either side.
AtlasCase phantomAtlasCase(const PhantomOptions& atlas, const PhantomOptions& subject);

/// Real CT (data/totalseg-ct): the atlas from the CT mirrored across the sacrum's mid-sagittal plane, its left femur,
/// hip bone, gluteus maximus and medius standing for the right ones; the subject the CT moved by knownMove(degrees, mm)
/// about the centre of its field of view (header only),
/// scored against the right side's labels. Empty name if the data are absent.
AtlasCase ctAtlasCase(const std::string& sharedData, double degrees, double mm);

/// Real MR (data/totalseg-mr): the atlas from the MR mirrored across the vertebrae's mid-sagittal plane, each
/// autochthon muscle standing for the other side's, the vertebrae for themselves; the subject the MR moved as the CT,
/// scored against the other side's labels. Empty name if the data are absent.
AtlasCase mrAtlasCase(const std::string& sharedData, double degrees, double mm);

/// One object's scores: the placed template alone and the result, against its reference label.
struct AtlasObjectScore {
  std::string name;
  SegmentationMetrics placed, result;
};

/// A run of the atlas route.
struct AtlasRun {
  std::vector<AtlasObjectScore> objects;
  Placement placement;
  SegmentationResult result;
  std::vector<AtlasStartRun> starts;  ///< each start's run (AtlasStarts::Each with several starts)
  std::vector<size_t> chosen;         ///< per object: the start (index into `starts`) its final run started from
  std::vector<double> progress;       ///< every fraction segmentWithAtlas() reported, in order
  double meanAssd = 0;
  double buildSeconds = 0, placementSeconds = 0, segmentSeconds = 0;
};

/// Builds the case's atlas in `scratch` (a folder that exists), places it in the subject and segments (c.options,
/// segmentWithAtlas() from c.starts), and scores.
AtlasRun runAtlasCase(const AtlasCase& c, const std::string& scratch, const PlacementOptions& placing = {},
                      const AtlasOptions& atlasOptions = {});

}  // namespace msk::test
