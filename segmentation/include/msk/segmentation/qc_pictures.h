#pragma once
/// Quality-control pictures: three orthogonal slices through each object with its contour drawn (OpenCV PNG).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "msk/imaging/volume.h"

namespace msk {

/// One object to draw.
struct QcObject {
  std::string name;  ///< used in file names: <dir>/<name>_axial.png, _coronal.png, _sagittal.png
  int label = 0;     ///< its value in the label map
  std::optional<std::array<uint8_t, 3>> colour;  ///< its contour colour (unset: qcObjectColour() of its place)
};

/// Writes, for every object, axial, coronal and sagittal slices (world-aligned, square pixels, radiological
/// display: patient left on screen right, anterior up in axial, superior up otherwise) through the object's
/// centroid, intensity windowed on the 1st–99th percentile, the object's contour in a distinct colour and the other
/// objects' contours dimmed; optional `reference` contours drawn dashed/thin (e.g. ground truth). Atomic writes.
/// Returns the files written. Throws IoError if `dir` is missing.
/// Details: pictures are sampled on a world-aligned plane (trilinear image, nearest labels) with square pixels of
/// the smallest voxel spacing, resampled so the longer side has 256–512 px; axial: patient right (+x) on screen
/// left, anterior up; coronal: patient right on the left, superior up; sagittal: anterior on the left, superior up.
/// Object i is drawn in its colour, else qcObjectColour(i) (2 px), the others dimmed (1 px), the reference in white (1
/// px); a label
/// "<name> <view>" and orientation letters are written in the corners. An object absent from `labels` is sliced
/// through its reference centroid if it has one, else through the centre of the image. Characters of a name other
/// than letters, digits, '-', '_' and '.' become '_' in file names.
std::vector<std::string> writeQcPictures(const std::string& dir, const ImageF& image, const LabelMap& labels,
                                         const std::vector<QcObject>& objects, const LabelMap* reference = nullptr);

/// How a QC mosaic is laid out.
struct QcMosaicOptions {
  int slicesPerView = 4;  ///< slices in each row (axial, coronal, sagittal), spread over the objects' extent
  int tileWidthPx = 512;  ///< width of each slice picture, px (>= 256)
  std::string title;      ///< written in the header (e.g. the case's name)
};

/// Writes one picture of a whole case (atomically, PNG): a header with the title and a legend of the objects' names
/// in their colours, then a row per view (axial, coronal, sagittal) of `slicesPerView` slices evenly spread over the
/// box holding every object (grown by 10 %, within the image), each `tileWidthPx` wide with square pixels, radiological
/// display as writeQcPictures(), a caption above it (view and slice position in mm, outside the slice, so it never
/// covers the orientation letters), every object's contour in qcObjectColour(i) (2 px) and, with `reference`, the
/// reference's contours dashed white. Throws IoError naming `path`.
void writeQcMosaic(const std::string& path, const ImageF& image, const LabelMap& labels,
                   const std::vector<QcObject>& objects, const LabelMap* reference = nullptr,
                   const QcMosaicOptions& options = {});

/// Contour colour of the i-th object (RGB, from a fixed palette of saturated colours that cycles).
std::array<uint8_t, 3> qcObjectColour(size_t index);

/// An 8-bit RGB picture, rows from the top, pixels left to right.
struct RgbPicture {
  int width = 0, height = 0;  ///< size in pixels
  std::vector<uint8_t> rgb;   ///< width × height × 3 bytes (R, G, B)
  /// The pixel at column x, row y.
  std::array<uint8_t, 3> at(int x, int y) const {
    const size_t n = 3 * (static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x));
    return {rgb[n], rgb[n + 1], rgb[n + 2]};
  }
};

/// Reads a picture (PNG or another format OpenCV reads) as RGB, e.g. to check written QC pictures. Throws IoError.
RgbPicture readRgbPicture(const std::string& path);

}  // namespace msk
