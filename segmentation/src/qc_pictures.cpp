// OpenCV adapter behind msk/segmentation/qc_pictures.h: OpenCV types stay in this file.
#include "msk/segmentation/qc_pictures.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <utility>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/imaging/filters.h"
#include "msk/segmentation/png_file.h"

namespace fs = std::filesystem;

namespace msk {

namespace {

/// Saturated, mutually distinct colours (RGB); none is grey, so they never occur in the windowed image.
constexpr std::array<std::array<uint8_t, 3>, 8> kPalette = {{{255, 40, 40},
                                                             {40, 255, 40},
                                                             {60, 120, 255},
                                                             {255, 230, 0},
                                                             {255, 0, 255},
                                                             {0, 230, 255},
                                                             {255, 140, 0},
                                                             {160, 60, 255}}};

/// Pictures have their longer side between these sizes (px).
constexpr double kMinSidePx = 256, kMaxSidePx = 512;

/// One display plane: world directions of increasing column and row, letters at the left, right and top edges.
struct View {
  const char* name;
  Eigen::Vector3d right, down;
  const char *leftLetter, *rightLetter, *topLetter;
};

/// Radiological display in RAS: +x is the patient's right, shown on the screen's left.
const std::array<View, 3> kViews = {{
    {"axial", {-1, 0, 0}, {0, -1, 0}, "R", "L", "A"},
    {"coronal", {-1, 0, 0}, {0, 0, -1}, "R", "L", "S"},
    {"sagittal", {0, -1, 0}, {0, 0, -1}, "A", "P", "S"},
}};

cv::Scalar bgr(const std::array<uint8_t, 3>& rgb, double factor = 1.0) {
  return cv::Scalar(rgb[2] * factor, rgb[1] * factor, rgb[0] * factor);
}

/// Centroid (world mm) of the voxels of `label`, if any.
std::optional<Eigen::Vector3d> labelCentroid(const LabelMap& labels, int label) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  size_t n = 0;
  const Grid& g = labels.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (labels.at(i, j, k) == label) {
          sum += Eigen::Vector3d(i, j, k);
          ++n;
        }
  if (n == 0) return std::nullopt;
  return g.toWorld(sum / static_cast<double>(n));
}

/// The sampling plane of one picture: pixel (c, r) centre = corner + (c + ½)·pix·right + (r + ½)·pix·down.
struct Plane {
  Eigen::Vector3d corner;
  double pix = 1;
  int width = 1, height = 1;
  Eigen::Vector3d at(int c, int r, const View& v) const {
    return corner + (c + 0.5) * pix * v.right + (r + 0.5) * pix * v.down;
  }
};

/// The plane through `centre` covering the image's voxel-centre bounding box along the view's two axes.
Plane makePlane(const Grid& grid, const View& v, const Eigen::Vector3d& centre) {
  const auto bounds = grid.worldBounds();
  const Eigen::Vector3d lo = bounds[0], hi = bounds[1];
  // Start on the side the axis runs from (the maximum for a negative direction).
  auto edge = [&](const Eigen::Vector3d& d) {
    Eigen::Vector3d e;
    for (int a = 0; a < 3; ++a) e[a] = d[a] < 0 ? hi[a] : lo[a];
    return e;
  };
  const double wMm = std::fabs(v.right.dot(hi - lo)), hMm = std::fabs(v.down.dot(hi - lo));
  const double longest = std::max({wMm, hMm, 1e-6});
  Plane p;
  p.pix = grid.spacing.minCoeff();
  if (longest / p.pix > kMaxSidePx) p.pix = longest / kMaxSidePx;
  if (longest / p.pix < kMinSidePx) p.pix = longest / kMinSidePx;
  p.width = std::max(1, static_cast<int>(std::ceil(wMm / p.pix)));
  p.height = std::max(1, static_cast<int>(std::ceil(hMm / p.pix)));
  // The corner: on the box edge the column and row axes run from, and at the centre along the plane's normal.
  const Eigen::Vector3d startRight = edge(v.right), startDown = edge(v.down);
  for (int a = 0; a < 3; ++a)
    p.corner[a] = std::fabs(v.right[a]) > 0.5 ? startRight[a] : std::fabs(v.down[a]) > 0.5 ? startDown[a] : centre[a];
  return p;
}

/// Calls f(c, r, ijk) for every pixel of the plane with its centre's continuous voxel coordinates on `grid`, stepped
/// along each row from the row's first pixel (the map is affine).
template <class F>
void forEachPixelVoxel(const Grid& grid, const Plane& p, const View& v, const F& f) {
  const Eigen::Vector3d step = grid.toVoxel(p.at(1, 0, v)) - grid.toVoxel(p.at(0, 0, v));
  for (int r = 0; r < p.height; ++r) {
    const Eigen::Vector3d first = grid.toVoxel(p.at(0, r, v));
    for (int c = 0; c < p.width; ++c) f(c, r, Eigen::Vector3d(first + c * step));
  }
}

/// Labels sampled (nearest) on the plane; 0 outside the grid.
cv::Mat labelSlice(const LabelMap& labels, const Plane& p, const View& v) {
  cv::Mat out(p.height, p.width, CV_32S, cv::Scalar(0));
  forEachPixelVoxel(labels.grid, p, v, [&](int c, int r, const Eigen::Vector3d& ijk) {
    out.at<int32_t>(r, c) = sampleNearestAtVoxel(labels, ijk).value_or(0);
  });
  return out;
}

/// Outline of `label` in a sampled label slice.
std::vector<std::vector<cv::Point>> contoursOf(const cv::Mat& slice, int label) {
  cv::Mat mask = slice == label;  // 255 where equal
  std::vector<std::vector<cv::Point>> contours;
  if (cv::countNonZero(mask) > 0) cv::findContours(mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
  return contours;
}

/// White text with a dark outline, readable on any background.
void text(cv::Mat& img, const std::string& s, cv::Point org) {
  cv::putText(img, s, org, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(img, s, org, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
}

std::string safeFileName(const std::string& name) {
  std::string s = name.empty() ? "object" : name;
  for (char& ch : s)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '_' && ch != '.') ch = '_';
  return s;
}

/// Intensity window on the 1st–99th percentile of the finite voxels.
std::pair<double, double> intensityWindow(const ImageF& image) {
  const std::vector<double> range = percentiles(image, {1.0, 99.0});  // both from one pair of passes
  const double lo = range[0];
  double hi = range[1];
  if (!(hi > lo)) hi = lo + 1.0;
  return {lo, hi};
}

/// The image sampled on the plane, windowed to grey (black outside the image).
cv::Mat greySlice(const ImageF& image, const Plane& p, const View& v, std::pair<double, double> window) {
  cv::Mat pic(p.height, p.width, CV_8UC3, cv::Scalar(0, 0, 0));
  const double lo = window.first, scale = 255.0 / (window.second - window.first);
  forEachPixelVoxel(image.grid, p, v, [&](int c, int r, const Eigen::Vector3d& ijk) {
    const std::optional<double> s = sampleTrilinearAtVoxel(image, ijk);
    if (!s || !std::isfinite(*s)) return;
    const auto grey = static_cast<uint8_t>(std::clamp((*s - lo) * scale, 0.0, 255.0) + 0.5);
    pic.at<cv::Vec3b>(r, c) = cv::Vec3b(grey, grey, grey);
  });
  return pic;
}

/// Contours drawn dashed (3 px drawn, 3 px left out along each outline).
void drawDashed(cv::Mat& pic, const std::vector<std::vector<cv::Point>>& contours, const cv::Scalar& colour) {
  for (const auto& c : contours)
    for (size_t i = 0; i < c.size(); ++i)
      if ((i / 3) % 2 == 0) cv::line(pic, c[i], c[(i + 1) % c.size()], colour, 1, cv::LINE_8);
}

/// World box of the voxels carrying any of `objects`' labels in `labels` (grown into `box`); false if there are none.
bool growLabelBox(const LabelMap& labels, const std::vector<QcObject>& objects, Eigen::Vector3d& lo,
                  Eigen::Vector3d& hi) {
  std::vector<bool> wanted;
  for (const QcObject& o : objects) {
    if (static_cast<size_t>(o.label) >= wanted.size()) wanted.resize(static_cast<size_t>(o.label) + 1, false);
    wanted[static_cast<size_t>(o.label)] = true;
  }
  bool any = false;
  const Grid& g = labels.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const int l = labels.at(i, j, k);
        if (l <= 0 || static_cast<size_t>(l) >= wanted.size() || !wanted[static_cast<size_t>(l)]) continue;
        // The voxel's eight corners, so that a box of one voxel still has its size.
        for (int corner = 0; corner < 8; ++corner) {
          const Eigen::Vector3d w = g.toWorld(Eigen::Vector3d(
              i + ((corner & 1) ? 0.5 : -0.5), j + ((corner & 2) ? 0.5 : -0.5), k + ((corner & 4) ? 0.5 : -0.5)));
          lo = lo.cwiseMin(w);
          hi = hi.cwiseMax(w);
        }
        any = true;
      }
  return any;
}

}  // namespace

std::array<uint8_t, 3> qcObjectColour(size_t index) { return kPalette[index % kPalette.size()]; }

namespace {
/// The contour colour of objects[k].
std::array<uint8_t, 3> colourOf(const std::vector<QcObject>& objects, size_t k) {
  return objects[k].colour.value_or(qcObjectColour(k));
}
}  // namespace

std::vector<std::string> writeQcPictures(const std::string& dir, const ImageF& image, const LabelMap& labels,
                                         const std::vector<QcObject>& objects, const LabelMap* reference) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw IoError(dir, "output folder does not exist");
  for (const auto& o : objects)
    if (o.label < 1) throw ParameterError("label of " + o.name, std::to_string(o.label), "must be >= 1");
  if (objects.empty()) return {};

  const auto [lo, hi] = intensityWindow(image);
  const auto bounds = image.grid.worldBounds();
  const Eigen::Vector3d imageCentre = 0.5 * (bounds[0] + bounds[1]);

  std::vector<std::string> written;
  for (size_t oi = 0; oi < objects.size(); ++oi) {
    const QcObject& obj = objects[oi];
    std::optional<Eigen::Vector3d> centre = labelCentroid(labels, obj.label);
    if (!centre && reference) centre = labelCentroid(*reference, obj.label);
    for (const View& v : kViews) {
      const Plane p = makePlane(image.grid, v, centre.value_or(imageCentre));
      cv::Mat pic = greySlice(image, p, v, {lo, hi});
      // Others dimmed and thin, then the reference (white, thin), then the object on top.
      const cv::Mat slice = labelSlice(labels, p, v);
      for (size_t k = 0; k < objects.size(); ++k)
        if (k != oi)
          cv::drawContours(pic, contoursOf(slice, objects[k].label), -1, bgr(colourOf(objects, k), 0.55), 1,
                           cv::LINE_8);
      if (reference)
        cv::drawContours(pic, contoursOf(labelSlice(*reference, p, v), obj.label), -1, cv::Scalar(255, 255, 255), 1,
                         cv::LINE_8);
      cv::drawContours(pic, contoursOf(slice, obj.label), -1, bgr(colourOf(objects, oi)), 2, cv::LINE_8);

      text(pic, obj.name + " " + v.name, cv::Point(6, 16));
      text(pic, v.leftLetter, cv::Point(4, p.height / 2 + 5));
      text(pic, v.rightLetter, cv::Point(std::max(0, p.width - 14), p.height / 2 + 5));
      text(pic, v.topLetter, cv::Point(p.width / 2 - 4, 32));

      const std::string path = fileInFolder(dir, safeFileName(obj.name) + "_" + v.name + ".png");
      writePngAtomically(path, pic);
      written.push_back(path);
    }
  }
  return written;
}

void writeQcMosaic(const std::string& path, const ImageF& image, const LabelMap& labels,
                   const std::vector<QcObject>& objects, const LabelMap* reference, const QcMosaicOptions& options) {
  if (options.slicesPerView < 1 || options.slicesPerView > 12)
    throw ParameterError("slices per view", std::to_string(options.slicesPerView), "must be 1..12");
  if (options.tileWidthPx < 256 || options.tileWidthPx > 2048)
    throw ParameterError("tile width", std::to_string(options.tileWidthPx), "must be 256..2048 px");
  const auto imageBounds = image.grid.worldBounds();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  bool any = growLabelBox(labels, objects, lo, hi);
  if (reference) any = growLabelBox(*reference, objects, lo, hi) || any;
  if (!any) {
    lo = imageBounds[0];
    hi = imageBounds[1];
  }
  const Eigen::Vector3d grow = 0.1 * (hi - lo);
  lo = (lo - grow).cwiseMax(imageBounds[0]);
  hi = (hi + grow).cwiseMin(imageBounds[1]);
  const auto window = intensityWindow(image);

  const int n = options.slicesPerView, tileW = options.tileWidthPx, gap = 4, caption = 22, header = 34;
  struct Tile {
    cv::Mat pic;
    std::string caption;
  };
  std::vector<std::vector<Tile>> rows;
  for (const View& v : kViews) {
    const Eigen::Vector3d normal = v.right.cross(v.down);
    int axis = 0;
    normal.cwiseAbs().maxCoeff(&axis);
    const double wMm = std::fabs(v.right.dot(hi - lo)), hMm = std::fabs(v.down.dot(hi - lo));
    Plane p;
    p.pix = std::max(wMm, 1e-6) / tileW;
    p.width = tileW;
    p.height = std::clamp(static_cast<int>(std::ceil(hMm / p.pix)), 16, 3 * tileW);
    std::vector<Tile> row;
    for (int s = 0; s < n; ++s) {
      const double at = lo[axis] + (hi[axis] - lo[axis]) * (s + 1.0) / (n + 1.0);
      for (int a = 0; a < 3; ++a) p.corner[a] = a == axis ? at : (v.right[a] + v.down[a]) < 0 ? hi[a] : lo[a];
      cv::Mat pic = greySlice(image, p, v, window);
      if (reference)
        for (const QcObject& o : objects)
          drawDashed(pic, contoursOf(labelSlice(*reference, p, v), o.label), cv::Scalar(255, 255, 255));
      const cv::Mat slice = labelSlice(labels, p, v);
      for (size_t k = 0; k < objects.size(); ++k)
        cv::drawContours(pic, contoursOf(slice, objects[k].label), -1, bgr(colourOf(objects, k)), 2, cv::LINE_8);
      text(pic, v.leftLetter, cv::Point(4, p.height / 2 + 5));
      text(pic, v.rightLetter, cv::Point(std::max(0, p.width - 14), p.height / 2 + 5));
      text(pic, v.topLetter, cv::Point(p.width / 2 - 4, 18));
      char where[96];
      std::snprintf(where, sizeof where, "%s  %c = %.1f mm", v.name, "xyz"[axis], at);
      row.push_back({pic, where});
    }
    rows.push_back(row);
  }

  int height = header;
  for (const auto& row : rows) height += caption + row[0].pic.rows + gap;
  const int width = n * tileW + (n - 1) * gap;
  cv::Mat mosaic(height, width, CV_8UC3, cv::Scalar(24, 24, 24));
  // Header: the title, then the legend (each object's colour and name; the reference's dashes).
  int x = 8;
  if (!options.title.empty()) {
    text(mosaic, options.title, cv::Point(x, 22));
    x += cv::getTextSize(options.title, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, nullptr).width + 24;
  }
  for (size_t k = 0; k < objects.size() && x < width - 40; ++k) {
    cv::line(mosaic, cv::Point(x, 17), cv::Point(x + 18, 17), bgr(colourOf(objects, k)), 3, cv::LINE_8);
    text(mosaic, objects[k].name, cv::Point(x + 24, 22));
    x += 24 + cv::getTextSize(objects[k].name, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, nullptr).width + 18;
  }
  if (reference && x < width - 120) {
    for (int d = 0; d < 18; d += 6)
      cv::line(mosaic, cv::Point(x + d, 17), cv::Point(x + d + 3, 17), cv::Scalar(255, 255, 255), 1, cv::LINE_8);
    text(mosaic, "reference", cv::Point(x + 24, 22));
  }
  int y = header;
  for (const auto& row : rows) {
    for (int s = 0; s < n; ++s) {
      const int left = s * (tileW + gap);
      text(mosaic, row[static_cast<size_t>(s)].caption, cv::Point(left + 6, y + 16));
      row[static_cast<size_t>(s)].pic.copyTo(
          mosaic(cv::Rect(left, y + caption, tileW, row[static_cast<size_t>(s)].pic.rows)));
    }
    y += caption + row[0].pic.rows + gap;
  }
  writePngAtomically(path, mosaic);
}

RgbPicture readRgbPicture(const std::string& path) {
  const cv::Mat bgrImage = readPicture(path);
  RgbPicture out;
  out.width = bgrImage.cols;
  out.height = bgrImage.rows;
  out.rgb.resize(static_cast<size_t>(out.width) * static_cast<size_t>(out.height) * 3);
  size_t n = 0;
  for (int r = 0; r < out.height; ++r)
    for (int c = 0; c < out.width; ++c) {
      const cv::Vec3b px = bgrImage.at<cv::Vec3b>(r, c);
      out.rgb[n++] = px[2];
      out.rgb[n++] = px[1];
      out.rgb[n++] = px[0];
    }
  return out;
}

}  // namespace msk
