#pragma once
/// What the numbers of a label map mean, in the formats viewers read, and per-structure statistics.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "msk/imaging/json.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk {

/// One label of a label map: its value, the object's name and display colour.
struct LabelEntry {
  int label = 0;
  std::string name;
  std::array<uint8_t, 3> rgb{};
};

/// The scene's objects as labels, in scene order: the scene's colour of each, else qcObjectColour() of its place.
std::vector<LabelEntry> labelEntries(const Scene& scene);

/// Writes next to a label map, into `dir` (atomically): `labels.ctbl`, a 3D Slicer colour table (load it with the
/// label map, or pick it in the Volumes module); `labels.itksnap.txt`, an ITK-SNAP label description file
/// (Segmentation > Import Label Descriptions); `labels.tsv`, a BIDS dseg.tsv (index, name, color). Returns the paths.
std::vector<std::string> writeLabelTables(const std::string& dir, const std::vector<LabelEntry>& labels);

/// Per structure: volume from the label map and from the mesh (mL), the mesh's surface area (mm²), the image's
/// mean, median and standard deviation inside the label, and the label's bounding box (voxel centres) and centroid
/// (RAS mm). Objects are the result's, in its order.
Json structureStatistics(const ImageF& image, const SegmentationResult& result);

/// The statistics as CSV: one row per structure, the columns of structureStatistics() flattened.
std::string statisticsCsv(const Json& statistics);

}  // namespace msk
