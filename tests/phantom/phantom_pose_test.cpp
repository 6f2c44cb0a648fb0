#include "msk/phantom/phantom_pose.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/grid.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/phantom/multi_phantom.h"
#include "msk/phantom/phantom.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"

namespace {

using msk::Phantom;
using msk::PhantomOptions;
using msk::PhantomPose;
using msk::test::labelCentroid;

Eigen::Vector3d apply(const Eigen::Matrix4d& m, const Eigen::Vector3d& x) {
  return m.topLeftCorner<3, 3>() * x + m.topRightCorner<3, 1>();
}

PhantomPose pose(const Eigen::Vector3d& degrees, const Eigen::Vector3d& t, double s) {
  PhantomPose p;
  p.rotationDegrees = degrees;
  p.translationMm = t;
  p.scale = s;
  return p;
}

// A pose that rotates about all three axes, scales and moves the anatomy by several centimetres.
PhantomPose generalPose() { return pose({20, -10, 35}, {15, -25, 30}, 1.25); }

// Coarse, noise-free, mesh-free phantom options.
PhantomOptions coarse(uint32_t seed) {
  PhantomOptions o;
  o.seed = seed;
  o.spacing = {2.0, 2.0, 3.0};
  o.noise = 0;
  o.bias = 0;
  o.meshes = false;
  return o;
}

// Small meshes on a coarse sampling grid: enough to compare posed and un-posed truth.
PhantomOptions quickMeshes(const PhantomPose& p) {
  PhantomOptions o = coarse(6);
  o.meshes = true;
  o.meshVertices = 400;
  o.meshSpacingMm = 2.0;
  o.pose = p;
  return o;
}

size_t countLabel(const msk::LabelMap& m, int32_t label) {
  return static_cast<size_t>(std::count(m.data.begin(), m.data.end(), label));
}

}  // namespace

TEST(PhantomPose, MatrixIsTranslationRotationScaleAboutTheOrigin) {
  EXPECT_TRUE(msk::phantomPoseMatrix(PhantomPose{}) == Eigen::Matrix4d::Identity());
  EXPECT_TRUE(msk::phantomPoseInverse(PhantomPose{}) == Eigen::Matrix4d::Identity());
  EXPECT_TRUE(msk::phantomPoseCentre().isZero(0));
  const PhantomPose p = generalPose();
  const Eigen::Matrix4d m = msk::phantomPoseMatrix(p);
  const Eigen::Matrix3d r = msk::Grid::rotationXYZ(p.rotationDegrees);
  const Eigen::Vector3d x(12, -40, 73);
  EXPECT_LT((apply(m, x) - (p.translationMm + p.scale * r * x)).norm(), 1e-12);
  // Rotations about x, then y, then z: R = Rz·Ry·Rx.
  const double k = M_PI / 180;
  const Eigen::Matrix3d rzyx =
      (Eigen::AngleAxisd(35 * k, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-10 * k, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(20 * k, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  EXPECT_LT((r - rzyx).norm(), 1e-14);
  EXPECT_TRUE(m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)));
  const double det = m.topLeftCorner<3, 3>().determinant();
  EXPECT_NEAR(det, std::pow(1.25, 3), 1e-12);
  EXPECT_LT((msk::phantomPoseInverse(p) * m - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(PhantomPose, IdentityPoseIsBitwiseTheUnposedPhantom) {
  PhantomOptions o = coarse(2);
  o.noise = 0.03;
  o.bias = 0.15;
  o.obliqueDegrees = {5, 0, -10};
  const Phantom plain = msk::makePhantom(o);
  o.pose = pose({0, -0.0, 0}, {-0.0, 0, 0}, 1.0);
  const Phantom posed = msk::makePhantom(o);
  ASSERT_TRUE(posed.image.grid.sameGeometry(plain.image.grid, 0));
  EXPECT_TRUE(posed.image.grid.origin == plain.image.grid.origin);
  EXPECT_TRUE(posed.image.grid.direction == plain.image.grid.direction);
  EXPECT_TRUE(posed.image.data == plain.image.data);
  EXPECT_TRUE(posed.labels.data == plain.labels.data);
  EXPECT_TRUE(posed.tissues.data == plain.tissues.data);
}

// A translation by whole voxels of an axis-aligned grid moves the field of view with the anatomy: the voxel data are
// the un-posed ones (the bias field, fixed in the world, is off here).
TEST(PhantomPose, WholeVoxelTranslationMovesTheGridOnly) {
  PhantomOptions o = coarse(3);
  const Phantom plain = msk::makePhantom(o);
  o.pose = pose({0, 0, 0}, {10, -20, 9}, 1.0);
  const Phantom moved = msk::makePhantom(o);
  ASSERT_EQ(moved.labels.grid.dims, plain.labels.grid.dims);
  EXPECT_LT((moved.labels.grid.origin - plain.labels.grid.origin - o.pose.translationMm).norm(), 1e-9);
  size_t differ = 0;
  for (size_t n = 0; n < plain.labels.data.size(); ++n) differ += moved.labels.data[n] != plain.labels.data[n];
  EXPECT_LE(differ, plain.labels.data.size() / 100000);
  EXPECT_EQ(countLabel(moved.tissues, 4), countLabel(plain.tissues, 4));
}

// Labels of a posed phantom are the un-posed labels mapped by P: centroids moved by P, volumes scaled by s³; the grid
// keeps its spacing and oblique direction and still holds the whole limb.
TEST(PhantomPose, PosedLabelsAreUnposedLabelsMovedByThePose) {
  PhantomOptions o = coarse(4);
  o.obliqueDegrees = {0, 8, -12};
  const Phantom plain = msk::makePhantom(o);
  o.pose = generalPose();
  const Phantom posed = msk::makePhantom(o);
  const Eigen::Matrix4d p = msk::phantomPoseMatrix(o.pose);
  const msk::Grid& g = posed.labels.grid;
  EXPECT_TRUE(g.spacing == o.spacing);
  EXPECT_LT((g.direction - msk::Grid::rotationXYZ(o.obliqueDegrees)).norm(), 1e-12);
  ASSERT_TRUE(posed.image.grid.sameGeometry(g, 0));
  ASSERT_TRUE(posed.tissues.grid.sameGeometry(g, 0));
  const double s3 = std::pow(o.pose.scale, 3), voxelRatio = g.spacing.prod() / plain.labels.grid.spacing.prod();
  for (int label = 1; label <= 4; ++label) {
    SCOPED_TRACE(label);
    const Eigen::Vector3d expected = apply(p, labelCentroid(plain.labels, label));
    EXPECT_LT((labelCentroid(posed.labels, label) - expected).norm(), 0.5);
    const double before = static_cast<double>(countLabel(plain.labels, label));
    const double after = static_cast<double>(countLabel(posed.labels, label)) * voxelRatio;
    EXPECT_NEAR(after, s3 * before, 0.02 * s3 * before);
  }
  // No labelled voxel on the faces of the field of view: the grown grid covers the posed limb (the skin and fat
  // cylinder runs through the un-posed field of view's ends, and so through the posed one's).
  size_t edgeLabels = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (i == 0 || j == 0 || k == 0 || i == g.dims[0] - 1 || j == g.dims[1] - 1 || k == g.dims[2] - 1)
          edgeLabels += posed.labels.data[g.index(i, j, k)] != 0;
  EXPECT_EQ(edgeLabels, 0u);
  // Intensities follow the anatomy: the mean image value over marrow voxels is the un-posed one.
  auto meanOver = [](const Phantom& ph, msk::PhantomTissue tissue) {
    double sum = 0;
    size_t n = 0;
    for (size_t v = 0; v < ph.tissues.data.size(); ++v)
      if (ph.tissues.data[v] == static_cast<int32_t>(tissue)) {
        sum += ph.image.data[v];
        ++n;
      }
    return n ? sum / static_cast<double>(n) : 0.0;
  };
  for (msk::PhantomTissue t : {msk::PhantomTissue::Marrow, msk::PhantomTissue::Muscle, msk::PhantomTissue::Fat}) {
    const double before = meanOver(plain, t);
    ASSERT_GT(before, 0);
    EXPECT_NEAR(meanOver(posed, t), before, 0.05 * before) << static_cast<int>(t);
  }
}

// Truth meshes are the un-posed ones mapped by P (and match the posed labels); templates stay un-posed; scene.json's
// provenance records the pose and the written truth is the posed one.
TEST(PhantomPose, TruthMeshesArePosedAndTemplatesAreNot) {
  const Phantom plain = msk::makePhantom(quickMeshes(PhantomPose{}));
  const PhantomOptions o = quickMeshes(generalPose());
  const Phantom posed = msk::makePhantom(o);
  const Eigen::Matrix4d p = msk::phantomPoseMatrix(o.pose);
  ASSERT_EQ(posed.objects.size(), plain.objects.size());
  for (size_t i = 0; i < plain.objects.size(); ++i) {
    SCOPED_TRACE(plain.objects[i].name);
    msk::TriangleMesh expected = plain.objects[i].truth;
    msk::transformMesh(expected, p);
    ASSERT_EQ(posed.objects[i].truth.vertexCount(), expected.vertexCount());
    EXPECT_TRUE(posed.objects[i].truth.faces == expected.faces);
    EXPECT_LT((posed.objects[i].truth.vertices - expected.vertices).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_GT(msk::enclosedVolume(posed.objects[i].truth), 0);
    EXPECT_TRUE(posed.objects[i].templ.vertices == plain.objects[i].templ.vertices);
  }
  const msk::LabelMap femur = msk::rasterize(posed.objects[0].truth, posed.labels.grid);
  EXPECT_GT(msk::test::labelDice(femur, 1, posed.labels, 1), 0.9);

  msk::test::ScratchDir dir;
  msk::writePhantom(posed, o, dir.path());
  const msk::Json pose = msk::readJsonFile(dir.file("scene.json")).at("provenance").at("pose");
  EXPECT_DOUBLE_EQ(pose.at("scale").get<double>(), 1.25);
  EXPECT_DOUBLE_EQ(pose.at("rotationDegrees")[2].get<double>(), 35);
  EXPECT_DOUBLE_EQ(pose.at("translationMm")[1].get<double>(), -25);
  ASSERT_EQ(pose.at("matrix").size(), 4u);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_DOUBLE_EQ(pose.at("matrix")[r][c].get<double>(), p(r, c));
  const msk::TriangleMesh written = msk::readMesh(dir.file("truth_femur.vtk"));
  EXPECT_LT((written.vertices - posed.objects[0].truth.vertices).cwiseAbs().maxCoeff(), 1e-3);
  const msk::TriangleMesh templ = msk::readMesh(dir.file("template_femur.vtk"));
  EXPECT_LT((templ.vertices - plain.objects[0].templ.vertices).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(PhantomPose, OutOfRangePosesAreRefusedNamingTheOption) {
  const std::vector<PhantomPose> bad = {
      pose({NAN, 0, 0}, {0, 0, 0}, 1),   pose({0, 0, 0}, {0, INFINITY, 0}, 1), pose({0, 0, 0}, {0, 0, 0}, NAN),
      pose({0, 180.5, 0}, {0, 0, 0}, 1), pose({0, 0, -181}, {0, 0, 0}, 1),     pose({0, 0, 0}, {800, 0, 601}, 1),
      pose({0, 0, 0}, {0, 0, 0}, 0.49),  pose({0, 0, 0}, {0, 0, 0}, 2.01),     pose({0, 0, 0}, {0, 0, 0}, -1)};
  for (const PhantomPose& p : bad) {
    PhantomOptions o = coarse(1);
    o.pose = p;
    try {
      msk::checkPhantomOptions(o);
      ADD_FAILURE() << "accepted pose " << p.rotationDegrees.transpose() << " " << p.translationMm.transpose() << " "
                    << p.scale;
    } catch (const msk::ParameterError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("--pose = ", 0), 0u) << e.what();
    }
    EXPECT_THROW(msk::makePhantom(o), msk::ParameterError);
    EXPECT_THROW(msk::makeMultiPhantom(o), msk::ParameterError);
  }
  // The limits themselves are accepted.
  EXPECT_NO_THROW(msk::checkPhantomPose(pose({180, -180, 180}, {1000, 0, 0}, 0.5)));
  EXPECT_NO_THROW(msk::checkPhantomPose(pose({0, 0, 0}, {0, 0, -1000}, 2)));
}
