#include "msk/segmentation/png_file.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"

namespace msk {

void writePngAtomically(const std::string& path, const cv::Mat& picture) {
  writeAtomically(path, [&](const std::string& tmp) {
    bool ok = false;
    try {
      ok = cv::imwrite(tmp, picture);
    } catch (const cv::Exception& e) {
      throw IoError(path, std::string("cannot write PNG: ") + e.what());
    }
    if (!ok) throw IoError(path, "cannot write PNG");
  });
}

cv::Mat readPicture(const std::string& path) {
  // Checked first: OpenCV would print a warning of its own for a missing file.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path, "cannot read picture: no such file");
  cv::Mat picture;
  try {
    picture = cv::imread(path, cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    throw IoError(path, std::string("cannot read picture: ") + e.what());
  }
  if (picture.empty()) throw IoError(path, "cannot read picture (missing or not an image)");
  return picture;
}

std::string thumbnailJpeg(const std::string& path, int width) {
  const cv::Mat picture = readPicture(path);
  const int height =
      std::max(1, static_cast<int>(std::lround(picture.rows * static_cast<double>(width) / picture.cols)));
  cv::Mat small;
  cv::resize(picture, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  std::vector<uchar> bytes;
  if (!cv::imencode(".jpg", small, bytes, {cv::IMWRITE_JPEG_QUALITY, 85}))
    throw IoError(path, "cannot encode thumbnail");
  return std::string(bytes.begin(), bytes.end());
}

}  // namespace msk
