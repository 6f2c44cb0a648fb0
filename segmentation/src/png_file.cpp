#include "msk/segmentation/png_file.h"

// PNG through libpng's simplified API and JPEG through libjpeg: OpenCV's imgcodecs would do both, but it links about
// 120 more shared libraries (GDAL, codecs of every format), which every mskseg process then loads at start-up.
#include <jpeglib.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdio>  // before jpeglib.h, which needs FILE and size_t declared
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"

namespace msk {

namespace {

/// libpng's error handler: an error longjmps back to the writer's caller instead of aborting.
[[noreturn]] void pngFail(png_structp png, png_const_charp message) {
  auto* why = static_cast<std::string*>(png_get_error_ptr(png));
  if (why) *why = message ? message : "unknown error";
  png_longjmp(png, 1);
}

/// Writes `pixels` (8-bit grey or BGR, continuous) to the open file `f` as PNG; false with `why` on a libpng error.
/// Deflate level 3 and the "up" filter alone: on the QC pictures (flat areas, grey ramps) against libpng's defaults
/// (level 6, every filter tried per row) a thigh mosaic takes 0.17 s instead of 0.56 s for 1.86 MB instead of 1.74
/// MB, a single slice the same size. The simplified API (png_image_write_*) offers no such setting.
bool encodePng(std::FILE* f, const cv::Mat& pixels, std::string& why) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &why, pngFail, nullptr);
  if (!png) {
    why = "out of memory";
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    if (why.empty()) why = "out of memory";
    return false;
  }
  png_init_io(png, f);
  png_set_compression_level(png, 3);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  const bool colour = pixels.channels() == 3;
  png_set_IHDR(png, info, static_cast<png_uint_32>(pixels.cols), static_cast<png_uint_32>(pixels.rows), 8,
               colour ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_BASE,
               PNG_FILTER_TYPE_BASE);
  png_write_info(png, info);
  if (colour) png_set_bgr(png);
  for (int r = 0; r < pixels.rows; ++r) png_write_row(png, pixels.ptr<png_byte>(r));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

void writePngAtomically(const std::string& path, const cv::Mat& picture) {
  if (picture.empty() || picture.depth() != CV_8U || (picture.channels() != 1 && picture.channels() != 3))
    throw IoError(path, "cannot write PNG: the picture is not 8-bit grey or BGR");
  const cv::Mat pixels = picture.isContinuous() ? picture : picture.clone();
  writeAtomically(path, [&](const std::string& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw IoError(path, "cannot write PNG: cannot open " + tmp);
    std::string why;
    const bool ok = encodePng(f, pixels, why);
    const bool closed = std::fclose(f) == 0;
    if (!ok) throw IoError(path, "cannot write PNG: " + why);
    if (!closed) throw IoError(path, "cannot write PNG: the file could not be completed (disk full?)");
  });
}

cv::Mat readPicture(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path, "cannot read picture: no such file");
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path.c_str())) {
    const std::string why = img.message;
    png_image_free(&img);
    throw IoError(path, "cannot read picture (not a PNG file: " + why + ")");
  }
  img.format = PNG_FORMAT_BGR;
  if (img.width == 0 || img.height == 0 || img.width > 100000 || img.height > 100000) {
    png_image_free(&img);
    throw IoError(path, "cannot read picture: size " + std::to_string(img.width) + " x " + std::to_string(img.height));
  }
  cv::Mat picture(static_cast<int>(img.height), static_cast<int>(img.width), CV_8UC3);
  if (!png_image_finish_read(&img, nullptr, picture.data, static_cast<png_int_32>(picture.step[0]), nullptr)) {
    const std::string why = img.message;
    png_image_free(&img);
    throw IoError(path, "cannot read picture: " + why);
  }
  return picture;
}

namespace {

/// libjpeg's error manager: an error longjmps back to the encoder's caller instead of exiting the process.
struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf back;
};

[[noreturn]] void jpegFail(j_common_ptr info) { std::longjmp(reinterpret_cast<JpegError*>(info->err)->back, 1); }

/// `bgr` (8-bit, 3 channels, continuous) as JPEG bytes at `quality`; empty on an encoder error.
std::string encodeJpeg(const cv::Mat& bgr, int quality) {
  jpeg_compress_struct c{};
  JpegError err{};
  c.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = jpegFail;
  unsigned char* buffer = nullptr;
  unsigned long size = 0;  // NOLINT(runtime/int): libjpeg's type
  std::vector<unsigned char> row(static_cast<size_t>(bgr.cols) * 3);
  if (setjmp(err.back)) {
    jpeg_destroy_compress(&c);
    std::free(buffer);
    return {};
  }
  jpeg_create_compress(&c);
  jpeg_mem_dest(&c, &buffer, &size);
  c.image_width = static_cast<JDIMENSION>(bgr.cols);
  c.image_height = static_cast<JDIMENSION>(bgr.rows);
  c.input_components = 3;
  c.in_color_space = JCS_RGB;
  jpeg_set_defaults(&c);
  jpeg_set_quality(&c, quality, TRUE);
  jpeg_start_compress(&c, TRUE);
  while (c.next_scanline < c.image_height) {
    const unsigned char* src = bgr.ptr<unsigned char>(static_cast<int>(c.next_scanline));
    for (int x = 0; x < bgr.cols; ++x)
      for (int k = 0; k < 3; ++k) row[static_cast<size_t>(3 * x + k)] = src[3 * x + 2 - k];
    JSAMPROW rows[1] = {row.data()};
    jpeg_write_scanlines(&c, rows, 1);
  }
  jpeg_finish_compress(&c);
  jpeg_destroy_compress(&c);
  std::string out(reinterpret_cast<const char*>(buffer), size);
  std::free(buffer);
  return out;
}

}  // namespace

std::string thumbnailJpeg(const std::string& path, int width) {
  const cv::Mat picture = readPicture(path);
  const int height =
      std::max(1, static_cast<int>(std::lround(picture.rows * static_cast<double>(width) / picture.cols)));
  cv::Mat small;
  cv::resize(picture, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  const std::string bytes = encodeJpeg(small, 85);
  if (bytes.empty()) throw IoError(path, "cannot encode thumbnail");
  return bytes;
}

}  // namespace msk
