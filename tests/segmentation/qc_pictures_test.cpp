#include "msk/segmentation/qc_pictures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/segmentation/png_file.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"

namespace {

using msk::test::ScratchDir;

// A 1×1.5×2.5 mm volume (optionally oblique) with a labelled ball (label 1) off-centre toward the patient's right
// (+x in RAS), posterior (−y) and superior (+z), and a small box (label 2) on the other side.
struct Synthetic {
  msk::ImageF image;
  msk::LabelMap labels;
  Eigen::Vector3d ballCentre;
};

Synthetic synthetic(bool oblique) {
  msk::Grid g;
  g.spacing = {1.0, 1.5, 2.5};
  g.dims = {80, 54, 32};
  g.direction = oblique ? msk::Grid::rotationXYZ({10, -15, 25}) : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d centre(5, -3, 40);
  g.origin = centre - g.direction * g.spacing.cwiseProduct((g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2);
  Synthetic s{msk::ImageF(g, 0.f), msk::LabelMap(g, 0), centre + Eigen::Vector3d(18, -12, 15)};
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d w = g.toWorld(Eigen::Vector3d(i, j, k));
        float v = 200.f + static_cast<float>(i % 7);
        if ((w - s.ballCentre).norm() <= 9) {
          s.labels.at(i, j, k) = 1;
          v = 800.f;
        } else if ((w - (centre + Eigen::Vector3d(-20, 10, -10))).cwiseAbs().maxCoeff() <= 6) {
          s.labels.at(i, j, k) = 2;
          v = 500.f;
        }
        s.image.at(i, j, k) = v;
      }
  return s;
}

struct ColourStats {
  size_t count = 0;
  double meanX = 0, meanY = 0;  // as fractions of width and height
};
ColourStats colourStats(const msk::RgbPicture& p, const std::array<uint8_t, 3>& rgb) {
  ColourStats s;
  for (int y = 0; y < p.height; ++y)
    for (int x = 0; x < p.width; ++x)
      if (p.at(x, y) == rgb) {
        ++s.count;
        s.meanX += (x + 0.5) / p.width;
        s.meanY += (y + 0.5) / p.height;
      }
  if (s.count) {
    s.meanX /= static_cast<double>(s.count);
    s.meanY /= static_cast<double>(s.count);
  }
  return s;
}

std::array<uint8_t, 3> dimmed(const std::array<uint8_t, 3>& c) {
  std::array<uint8_t, 3> d;
  for (int i = 0; i < 3; ++i) d[i] = static_cast<uint8_t>(std::lround(c[i] * 0.55));
  return d;
}

size_t whiteCount(const msk::RgbPicture& p) { return colourStats(p, {255, 255, 255}).count; }

}  // namespace

TEST(QcPictures, WritesReadableRadiologicalPictures) {
  const std::vector<msk::QcObject> objects = {{"ball", 1, std::nullopt}, {"box", 2, std::nullopt}};
  for (bool oblique : {false, true}) {
    SCOPED_TRACE(oblique ? "oblique grid" : "axis-aligned grid");
    const Synthetic s = synthetic(oblique);
    ScratchDir dir;
    const std::vector<std::string> files = msk::writeQcPictures(dir.path(), s.image, s.labels, objects);
    const std::vector<std::string> names = {"ball_axial.png", "ball_coronal.png", "ball_sagittal.png",
                                            "box_axial.png",  "box_coronal.png",  "box_sagittal.png"};
    ASSERT_EQ(files.size(), 6u);
    for (size_t i = 0; i < files.size(); ++i) EXPECT_EQ(files[i], dir.file(names[i]));
    EXPECT_EQ(dir.list(), (std::vector<std::string>{"ball_axial.png", "ball_coronal.png", "ball_sagittal.png",
                                                    "box_axial.png", "box_coronal.png", "box_sagittal.png"}));

    const auto ball = msk::qcObjectColour(0), box = msk::qcObjectColour(1);
    // World bounds of the voxel centres: where the ball is expected in each picture (fractions of width, height).
    const auto b = s.image.grid.worldBounds();
    auto frac = [&](int axis, bool reversed) {
      const double f = (s.ballCentre[axis] - b[0][axis]) / (b[1][axis] - b[0][axis]);
      return reversed ? 1 - f : f;
    };
    struct Expect {
      const char* file;
      double x, y;  // expected centre of the ball's contour
    };
    const Expect expect[] = {
        {"ball_axial.png", frac(0, true), frac(1, true)},     // patient right (+x) on the left, anterior up
        {"ball_coronal.png", frac(0, true), frac(2, true)},   // patient right on the left, superior up
        {"ball_sagittal.png", frac(1, true), frac(2, true)},  // anterior on the left, superior up
    };
    for (const Expect& e : expect) {
      SCOPED_TRACE(e.file);
      const msk::RgbPicture p = msk::readRgbPicture(dir.file(e.file));
      EXPECT_GE(std::max(p.width, p.height), 256);
      EXPECT_LE(std::max(p.width, p.height), 512);
      const ColourStats st = colourStats(p, ball);
      ASSERT_GT(st.count, 50u) << "the ball's contour colour";
      // The ball lies toward the patient's right, posterior and superior.
      if (std::string(e.file) == "ball_axial.png") {
        EXPECT_LT(st.meanX, 0.5) << "patient right on the screen's left";
        EXPECT_GT(st.meanY, 0.5) << "posterior down";
      } else if (std::string(e.file) == "ball_coronal.png") {
        EXPECT_LT(st.meanX, 0.5);
        EXPECT_LT(st.meanY, 0.5) << "superior up";
      } else {
        EXPECT_GT(st.meanX, 0.5) << "posterior on the right";
        EXPECT_LT(st.meanY, 0.5) << "superior up";
      }
      if (!oblique) {
        EXPECT_NEAR(st.meanX, e.x, 0.03);
        EXPECT_NEAR(st.meanY, e.y, 0.03);
      }
    }
    // Square pixels: the axial picture's aspect is the world extent's (x by y), not the voxel counts'.
    if (!oblique) {
      const msk::RgbPicture ax = msk::readRgbPicture(dir.file("ball_axial.png"));
      EXPECT_NEAR(static_cast<double>(ax.width) / ax.height, (b[1][0] - b[0][0]) / (b[1][1] - b[0][1]), 0.02);
      const msk::RgbPicture sag = msk::readRgbPicture(dir.file("ball_sagittal.png"));
      EXPECT_NEAR(static_cast<double>(sag.width) / sag.height, (b[1][1] - b[0][1]) / (b[1][2] - b[0][2]), 0.02);
    }
    // The box's own axial picture passes through the box (its colour at full strength) and misses the ball.
    const msk::RgbPicture boxAxial = msk::readRgbPicture(dir.file("box_axial.png"));
    EXPECT_GT(colourStats(boxAxial, box).count, 50u);
    EXPECT_EQ(colourStats(boxAxial, ball).count, 0u);
    const msk::RgbPicture ballSag = msk::readRgbPicture(dir.file("ball_sagittal.png"));
    EXPECT_EQ(colourStats(ballSag, box).count, 0u) << "other objects are never drawn at full strength";
  }
}

TEST(QcPictures, OtherObjectsDimmedAndReferenceInWhite) {
  const Synthetic s = synthetic(false);
  // A third object crossing the ball's axial plane, and a reference that is the ball shifted by 3 mm.
  msk::LabelMap labels = s.labels, reference(s.labels.grid, 0);
  msk::test::paintBall(labels, s.ballCentre + Eigen::Vector3d(-25, 0, 0), 6, 5);
  msk::test::paintBall(reference, s.ballCentre + Eigen::Vector3d(3, 0, 0), 9, 1);
  const std::vector<msk::QcObject> objects = {{"ball", 1, std::nullopt}, {"other", 5, std::nullopt}};
  ScratchDir plain, withRef;
  msk::writeQcPictures(plain.path(), s.image, labels, objects);
  msk::writeQcPictures(withRef.path(), s.image, labels, objects, &reference);
  const msk::RgbPicture a = msk::readRgbPicture(plain.file("ball_axial.png"));
  const msk::RgbPicture r = msk::readRgbPicture(withRef.file("ball_axial.png"));
  EXPECT_GT(colourStats(a, dimmed(msk::qcObjectColour(1))).count, 20u) << "the other object, dimmed";
  EXPECT_EQ(colourStats(a, msk::qcObjectColour(1)).count, 0u);
  EXPECT_GT(whiteCount(r), whiteCount(a) + 30) << "reference contour in white";
}

TEST(QcPictures, ErrorsAndAbsentObjects) {
  const Synthetic s = synthetic(false);
  ScratchDir dir;
  const std::string missing = dir.file("no/such/folder");
  try {
    msk::writeQcPictures(missing, s.image, s.labels, {{"ball", 1, std::nullopt}});
    ADD_FAILURE() << "no error for a missing folder";
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), missing);
  }
  EXPECT_THROW(msk::writeQcPictures(dir.path(), s.image, s.labels, {{"bad", 0, std::nullopt}}), msk::ParameterError);
  EXPECT_TRUE(dir.list().empty());

  // An object absent from the labels still gets its three pictures (through the image centre), without contour;
  // names are made safe for file names.
  const std::vector<std::string> files =
      msk::writeQcPictures(dir.path(), s.image, s.labels, {{"tibia/left", 9, std::nullopt}});
  ASSERT_EQ(files.size(), 3u);
  EXPECT_EQ(files[0], dir.file("tibia_left_axial.png"));
  const msk::RgbPicture p = msk::readRgbPicture(files[0]);
  EXPECT_EQ(colourStats(p, msk::qcObjectColour(0)).count, 0u);
  EXPECT_GT(p.width, 0);
  EXPECT_THROW(msk::readRgbPicture(dir.file("absent.png")), msk::IoError);
  // No temporary files are left behind.
  for (const auto& f : dir.list()) EXPECT_EQ(f.find(".tmp"), std::string::npos) << f;
}

// PNG files hold their pixels exactly, colour and grey (read back as BGR with equal channels), including a picture
// whose rows are not contiguous; a folder that does not exist is a clear error and leaves nothing behind.
TEST(PngFile, RoundTripsColourAndGreyExactly) {
  ScratchDir dir;
  cv::Mat colour(37, 53, CV_8UC3), grey(21, 17, CV_8UC1);
  cv::randu(colour, cv::Scalar::all(0), cv::Scalar::all(256));
  cv::randu(grey, cv::Scalar::all(0), cv::Scalar::all(256));
  msk::writePngAtomically(dir.file("colour.png"), colour);
  msk::writePngAtomically(dir.file("grey.png"), grey);
  const cv::Mat roi = colour(cv::Rect(5, 3, 20, 30));
  ASSERT_FALSE(roi.isContinuous());
  msk::writePngAtomically(dir.file("roi.png"), roi);
  const cv::Mat c = msk::readPicture(dir.file("colour.png")), g = msk::readPicture(dir.file("grey.png")),
                r = msk::readPicture(dir.file("roi.png"));
  ASSERT_EQ(c.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(c, colour, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r, roi, cv::NORM_INF), 0);
  cv::Mat greyAsBgr;
  cv::cvtColor(grey, greyAsBgr, cv::COLOR_GRAY2BGR);
  EXPECT_EQ(cv::norm(g, greyAsBgr, cv::NORM_INF), 0);
  const std::string missing = dir.file("no-such-folder/x.png");
  try {
    msk::writePngAtomically(missing, colour);
    FAIL() << "wrote into a missing folder";
  } catch (const msk::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-folder"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("no-such-folder")));
}
