#include "msk/segmentation/png_file.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

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

}  // namespace msk
