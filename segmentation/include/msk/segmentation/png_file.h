#pragma once
/// Pictures as files: PNG written atomically and read back (libpng), JPEG thumbnails (libjpeg). Pictures are OpenCV
/// matrices (the caller includes <opencv2/core.hpp>).
#include <string>

namespace cv {
class Mat;
}

namespace msk {

/// Writes `picture` (8-bit grey or BGR) to `path` as a PNG through a temporary file and a rename; an encoder
/// failure throws IoError naming `path`.
void writePngAtomically(const std::string& path, const cv::Mat& picture);

/// Reads a PNG picture as 8-bit BGR. Throws IoError naming `path` if it is missing
/// or cannot be decoded.
cv::Mat readPicture(const std::string& path);

/// The picture at `path` scaled to `width` px (aspect kept), encoded as JPEG bytes (quality 85) for embedding in a
/// page. Throws IoError naming `path` if it cannot be read.
std::string thumbnailJpeg(const std::string& path, int width);

}  // namespace msk
