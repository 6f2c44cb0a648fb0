#include "msk/imaging/transform_io.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/test/files.h"

namespace {

using msk::test::ScratchDir;
using msk::test::writeBytes;

std::string num(double v) {
  std::ostringstream s;
  s << std::setprecision(17) << v;
  return s.str();
}

double maxDiff(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) { return (a - b).cwiseAbs().maxCoeff(); }

// Rotation by 90° about +z (RAS: x → y) followed by a translation, as 4×4 rows.
Eigen::Matrix4d rotZ90Then(const Eigen::Vector3d& t) {
  Eigen::Matrix4d m;
  m << 0, -1, 0, t[0], 1, 0, 0, t[1], 0, 0, 1, t[2], 0, 0, 0, 1;
  return m;
}

// A general affine map: rotation, anisotropic scale and shear, translation.
Eigen::Matrix4d generalAffine() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  Eigen::Matrix3d shear;
  shear << 1.1, 0.05, 0, 0, 0.93, -0.02, 0.01, 0, 1.04;
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix() * shear;
  m.topRightCorner<3, 1>() = Eigen::Vector3d(12.5, -30.25, 7.125);
  return m;
}

std::string itkFile(const std::string& type, const std::string& parameters, const std::string& fixed) {
  return "#Insight Transform File V1.0\n#Transform 0\nTransform: " + type + "\nParameters: " + parameters +
         "\nFixedParameters: " + fixed + "\n";
}

// Expects readLinearTransform(path) to throw IoError naming the file and containing `phrase`.
void expectRefused(const std::string& path, const std::string& phrase) {
  try {
    msk::readLinearTransform(path);
    ADD_FAILURE() << path << " was accepted";
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(e.problem().find(phrase), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(TransformIo, SlicerFileRoundTrips) {
  ScratchDir dir;
  for (const Eigen::Matrix4d& m :
       {Eigen::Matrix4d(Eigen::Matrix4d::Identity()), rotZ90Then({1, 2, 3}), generalAffine()}) {
    const std::string path = dir.file("placement.tfm");
    msk::writeSlicerTransform(path, m);
    EXPECT_LT(maxDiff(msk::readLinearTransform(path), m), 1e-12);
  }
  EXPECT_EQ(dir.list(), std::vector<std::string>{"placement.tfm"});  // no temporary left behind
  EXPECT_TRUE(msk::readLinearTransform(dir.file("placement.tfm")).row(3) == Eigen::RowVector4d(0, 0, 0, 1));
}

// What Slicer writes for a transform that moves the atlas by +10, +20, +30 mm (R, A, S): the inverse ("from parent"),
// in LPS: −10, −20, −30 RAS = +10, +20, −30 LPS.
TEST(TransformIo, SlicerTranslationIsReadAsAtlasToSubjectRas) {
  ScratchDir dir;
  writeBytes(dir.file("t.tfm"), itkFile("AffineTransform_double_3_3", "1 0 0 0 1 0 0 0 1 10 20 -30", "0 0 0"));
  Eigen::Matrix4d expected = Eigen::Matrix4d::Identity();
  expected.topRightCorner<3, 1>() = Eigen::Vector3d(10, 20, 30);
  EXPECT_LT(maxDiff(msk::readLinearTransform(dir.file("t.tfm")), expected), 1e-15);
  // And the writer writes exactly those parameters.
  msk::writeSlicerTransform(dir.file("w.tfm"), expected);
  EXPECT_NE(msk::test::readBytes(dir.file("w.tfm")).find("Parameters: 1 0 0 0 1 0 0 0 1 10 20 -30\n"),
            std::string::npos)
      << msk::test::readBytes(dir.file("w.tfm"));
}

// Hand-computed: the file's LPS map F(x) = A·(x − c) + c, A = rotation by −90° about z, c = (10, 0, 0) LPS, sends
// subject (0, 0, 0) RAS = (0, 0, 0) LPS to A·(−10, 0, 0) + c = (0, 10, 0) + (10, 0, 0) = (10, 10, 0) LPS =
// (−10, −10, 0) RAS of the atlas. So M (atlas → subject, RAS) = [Rz(90°) | (−10, 10, 0)]: M·(−10, −10, 0) = 0.
TEST(TransformIo, HandComputedLpsExampleWithCentre) {
  ScratchDir dir;
  const Eigen::Matrix4d expected = rotZ90Then({-10, 10, 0});
  for (const char* type :
       {"AffineTransform_double_3_3", "MatrixOffsetTransformBase_double_3_3", "AffineTransform_float_3_3"}) {
    SCOPED_TRACE(type);
    writeBytes(dir.file("r.txt"), itkFile(type, "0 1 0 -1 0 0 0 0 1 0 0 0", "10 0 0"));
    const Eigen::Matrix4d m = msk::readLinearTransform(dir.file("r.txt"));
    EXPECT_LT(maxDiff(m, expected), 1e-12);
    EXPECT_LT((m * Eigen::Vector4d(-10, -10, 0, 1)).head<3>().norm(), 1e-12);
  }
  // The same map as an Euler3DTransform (−π/2 about z; angles in radians), a VersorRigid3DTransform (versor of −90°
  // about z) and a Similarity3DTransform of scale 1; missing fixed parameters mean centre 0, folded into t here.
  const std::string s = num(-std::sqrt(0.5));
  const std::vector<std::string> same = {
      itkFile("Euler3DTransform_double_3_3", "0 0 " + num(-M_PI / 2) + " 0 0 0", "10 0 0"),
      itkFile("Euler3DTransform_double_3_3", "0 0 " + num(-M_PI / 2) + " 0 0 0", "10 0 0 1"),
      itkFile("VersorRigid3DTransform_double_3_3", "0 0 " + s + " 10 10 0", ""),
      itkFile("Similarity3DTransform_double_3_3", "0 0 " + s + " 0 0 0 1", "10 0 0")};
  for (const std::string& text : same) {
    SCOPED_TRACE(text);
    writeBytes(dir.file("e.tfm"), text);
    EXPECT_LT(maxDiff(msk::readLinearTransform(dir.file("e.tfm")), expected), 1e-12);
  }
}

TEST(TransformIo, EulerAnglesFollowItkOrder) {
  ScratchDir dir;
  const double ax = 0.3, ay = -0.2, az = 0.7;
  const Eigen::Matrix3d rx = Eigen::AngleAxisd(ax, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d ry = Eigen::AngleAxisd(ay, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(az, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const std::string angles = num(ax) + " " + num(ay) + " " + num(az);
  for (bool zyx : {false, true}) {
    writeBytes(dir.file("e.tfm"), itkFile("Euler3DTransform_double_3_3", angles + " 1 2 3", zyx ? "0 0 0 1" : "0 0 0"));
    Eigen::Matrix4d lps = Eigen::Matrix4d::Identity();
    lps.topLeftCorner<3, 3>() = zyx ? Eigen::Matrix3d(rz * ry * rx) : Eigen::Matrix3d(rz * rx * ry);
    lps.topRightCorner<3, 1>() = Eigen::Vector3d(1, 2, 3);
    const Eigen::Matrix4d c = Eigen::Vector4d(-1, -1, 1, 1).asDiagonal();
    EXPECT_LT(maxDiff(msk::readLinearTransform(dir.file("e.tfm")), c * lps.inverse() * c), 1e-12) << zyx;
  }
}

TEST(TransformIo, JsonAndPlainTextAreRasAtlasToSubject) {
  ScratchDir dir;
  const Eigen::Matrix4d m = rotZ90Then({5, -6, 7.5});
  writeBytes(dir.file("a.json"), R"({"matrix": [[0, -1, 0, 5], [1, 0, 0, -6], [0, 0, 1, 7.5], [0, 0, 0, 1]]})");
  writeBytes(dir.file("b.json"), "[[0, -1, 0, 5], [1, 0, 0, -6], [0, 0, 1, 7.5]]\n");
  writeBytes(dir.file("c.json"),
             R"({"space": "LPS", "matrix": [[0, -1, 0, -5], [1, 0, 0, 6], [0, 0, 1, 7.5], [0, 0, 0, 1]]})");
  writeBytes(dir.file("d.txt"), "# atlas to subject\n0 -1 0 5\n1 0 0 -6\n0 0 1 7.5\n0 0 0 1\n");
  writeBytes(dir.file("e.mat.txt"), "0,-1,0,5\n 1, 0, 0, -6 \r\n0\t0\t1\t7.5\n\n");
  for (const char* f : {"a.json", "b.json", "c.json", "d.txt", "e.mat.txt"})
    EXPECT_TRUE(msk::readLinearTransform(dir.file(f)) == m) << f;
}

TEST(TransformIo, RefusesBadFilesWithOneLine) {
  ScratchDir dir;
  auto file = [&](const std::string& name, const std::string& text) {
    writeBytes(dir.file(name), text);
    return dir.file(name);
  };
  expectRefused(dir.file("missing.tfm"), "cannot open");
  expectRefused(file("three.txt", "1 2 3\n"), "row 1 has 3 numbers");
  expectRefused(file("three.json", "[1, 2, 3]"), "array of rows");
  expectRefused(file("nan.txt", "1 0 0 0\n0 nan 0 0\n0 0 1 0\n0 0 0 1\n"), "not a finite number");
  expectRefused(file("word.txt", "1 0 0 0\n0 one 0 0\n0 0 1 0\n"), "'one' is not a number");
  expectRefused(file("singular.txt", "1 0 0 0\n0 1 0 0\n0 0 0 0\n0 0 0 1\n"), "singular");
  expectRefused(file("thin.txt", "100 0 0 0\n0 100 0 0\n0 0 5e-5 0\n0 0 0 1\n"), "ill-conditioned");
  expectRefused(file("projective.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0.1 0 1\n"), "last row must be 0 0 0 1");
  expectRefused(file("five.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n0 0 0 1\n"), "found 5 rows");
  expectRefused(file("two.txt", "1 0 0 0\n0 1 0 0\n"), "found 2 rows");
  expectRefused(file("bspline.tfm", itkFile("BSplineTransform_double_3_3", "0 0 0", "0 0 0")),
                "unsupported ITK transform type 'BSplineTransform_double_3_3'");
  expectRefused(file("short.tfm", itkFile("AffineTransform_double_3_3", "1 0 0 0 1 0 0 0 1", "0 0 0")),
                "needs 12 Parameters, found 9");
  expectRefused(file("flat.tfm", itkFile("AffineTransform_double_3_3", "1 0 0 0 1 0 0 0 0 0 0 0", "0 0 0")),
                "singular");
  expectRefused(file("inf.tfm", itkFile("AffineTransform_double_3_3", "1 0 0 0 1 0 0 0 1 inf 0 0", "0 0 0")),
                "not a finite number");
  expectRefused(file("two.tfm", itkFile("AffineTransform_double_3_3", "1 0 0 0 1 0 0 0 1 0 0 0", "0 0 0") +
                                    "#Transform 1\nTransform: AffineTransform_double_3_3\nParameters: 1 0 0 0 1 0 0 "
                                    "0 1 0 0 0\n"),
                "more than one transform");
  expectRefused(file("noheader.tfm", "Transform: AffineTransform_double_3_3\n"), "not an ITK text transform");
  expectRefused(file("key.json", R"({"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]], "units": "mm"})"), "unknown key");
  expectRefused(file("empty.txt", "\n# nothing\n"), "empty file");
  expectRefused(file("x.h5", "HDF"), "binary ITK transforms");
}

TEST(TransformIo, WriterRefusesUnusableMatrices) {
  ScratchDir dir;
  Eigen::Matrix4d singular = Eigen::Matrix4d::Identity();
  singular(1, 1) = 0;
  Eigen::Matrix4d nan = Eigen::Matrix4d::Identity();
  nan(0, 3) = NAN;
  for (const Eigen::Matrix4d& m : {singular, nan})
    EXPECT_THROW(msk::writeSlicerTransform(dir.file("bad.tfm"), m), msk::ParameterError);
  EXPECT_TRUE(dir.list().empty());
  EXPECT_EQ(msk::linearTransformProblem(Eigen::Matrix4d::Identity()), "");
}
