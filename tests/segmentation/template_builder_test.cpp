#include "msk/segmentation/template_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/nifti_io.h"
#include "msk/test/files.h"
#include "msk/test/volumes.h"

namespace {

// A ball of radius r (labelled `label`) on a 1×1×3 mm grid, centred off the voxel lattice.
msk::LabelMap ballLabels(const Eigen::Vector3d& c, double r, int label,
                         const Eigen::Matrix3d& dir = Eigen::Matrix3d::Identity()) {
  msk::Grid g;
  g.spacing = {1.0, 1.0, 3.0};
  g.direction = dir;
  g.dims = {48, 48, 18};
  g.origin = c - dir * g.spacing.cwiseProduct((g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2) +
             Eigen::Vector3d(0.31, -0.17, 0.43);
  return msk::test::ballLabels(g, c, r, label);
}

struct RadiusStats {
  double meanAbs = 0, maxAbs = 0;
};
RadiusStats radiusStats(const msk::TriangleMesh& m, const Eigen::Vector3d& c, double r) {
  RadiusStats s;
  for (int i = 0; i < m.vertexCount(); ++i) {
    const double e = std::fabs((m.vertices.row(i).transpose() - c).norm() - r);
    s.meanAbs += e;
    s.maxAbs = std::max(s.maxAbs, e);
  }
  s.meanAbs /= std::max(1, m.vertexCount());
  return s;
}

// A cylinder r = 8 mm along z through the whole 1×1×3 mm grid (label 1), like a femur cut by the field of view.
msk::LabelMap cutCylinderLabels() {
  msk::Grid g;
  g.spacing = {1.0, 1.0, 3.0};
  g.dims = {30, 30, 12};
  g.origin = {-14.5, -14.5, 0};
  msk::LabelMap lab(g, 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (g.toWorld(Eigen::Vector3d(i, j, k)).head<2>().norm() <= 8) lab.at(i, j, k) = 1;
  return lab;
}

double voxelVolume(const msk::LabelMap& lab, int label) {
  return static_cast<double>(std::count(lab.data.begin(), lab.data.end(), label)) * lab.grid.spacing.prod();
}

}  // namespace

TEST(TemplateBuilder, BallOnThickSlicesIsSmoothClosedAndTrue) {
  const Eigen::Vector3d c(10, -20, 30);
  const double r = 15, exact = 4.0 / 3.0 * M_PI * r * r * r;
  for (bool oblique : {false, true}) {
    SCOPED_TRACE(oblique ? "oblique, det -1" : "axis-aligned");
    Eigen::Matrix3d dir = Eigen::Matrix3d::Identity();
    if (oblique) {
      dir = msk::Grid::rotationXYZ({20, -35, 50});
      dir.col(0) *= -1;
    }
    const msk::LabelMap lab = ballLabels(c, r, 7, dir);
    msk::TemplateReport rep;
    const msk::TriangleMesh m = msk::templateFromLabels(lab, 7, {}, &rep);
    ASSERT_EQ(msk::closedMeshProblem(m), "");
    EXPECT_DOUBLE_EQ(rep.sigmaMm, 1.5);  // default: half the largest spacing
    EXPECT_EQ(rep.componentsDropped, 0u);
    const double v = msk::enclosedVolume(m);
    EXPECT_NEAR(v, exact, 0.03 * exact);
    EXPECT_NEAR(v, voxelVolume(lab, 7), 0.005 * voxelVolume(lab, 7));  // the volume-preserving offset
    const RadiusStats st = radiusStats(m, c, r);
    EXPECT_LT(st.meanAbs, 0.5);
    EXPECT_LT(st.maxAbs, 1.5);  // no 3 mm staircase left
    EXPECT_GE(m.vertexCount(), 2700);
    EXPECT_LE(m.vertexCount(), 3000);
  }
}

TEST(TemplateBuilder, SmoothingAndVolumeOptions) {
  const Eigen::Vector3d c(0, 0, 0);
  const double r = 15, exact = 4.0 / 3.0 * M_PI * r * r * r;
  const msk::LabelMap lab = ballLabels(c, r, 2);
  msk::TemplateOptions o;
  o.vertices = 800;
  o.smoothingSigmaMm = 3.0;
  o.preserveVolume = false;
  msk::TemplateReport rep;
  const msk::TriangleMesh shrunk = msk::templateFromLabels(lab, 2, o, &rep);
  EXPECT_DOUBLE_EQ(rep.sigmaMm, 3.0);
  EXPECT_EQ(rep.offsetMm, 0.0);
  EXPECT_LT(msk::enclosedVolume(shrunk), 0.92 * exact);  // the 0.5 level of a blurred ball moves inward (≈ σ²·H)
  EXPECT_NEAR(shrunk.vertexCount(), 800, 80);
  o.preserveVolume = true;
  const msk::TriangleMesh kept = msk::templateFromLabels(lab, 2, o, &rep);
  EXPECT_GT(rep.offsetMm, 0.3);
  EXPECT_NEAR(msk::enclosedVolume(kept), exact, 0.02 * exact);
  EXPECT_EQ(msk::closedMeshProblem(kept), "");
}

TEST(TemplateBuilder, LargestComponentAndAbsentLabel) {
  msk::LabelMap lab = ballLabels({0, 0, 0}, 10, 3);
  msk::test::paintBall(lab, Eigen::Vector3d(0, 17, 0), 4.5, 3);  // a second, smaller ball of the same label, well apart
  msk::TemplateOptions o;
  o.vertices = 1000;
  msk::TemplateReport rep;
  const msk::TriangleMesh big = msk::templateFromLabels(lab, 3, o, &rep);
  EXPECT_EQ(rep.componentsDropped, 1u);
  EXPECT_NEAR(msk::enclosedVolume(big), 4.0 / 3.0 * M_PI * 1000, 0.03 * 4.0 / 3.0 * M_PI * 1000);
  o.largestComponent = false;
  const msk::TriangleMesh both = msk::templateFromLabels(lab, 3, o, &rep);
  EXPECT_EQ(rep.componentsDropped, 0u);
  EXPECT_EQ(msk::closedMeshProblem(both), "");
  EXPECT_NEAR(msk::enclosedVolume(both), voxelVolume(lab, 3), 0.01 * voxelVolume(lab, 3));

  try {
    msk::templateFromLabels(lab, 9);
    ADD_FAILURE() << "no error for an absent label";
  } catch (const msk::Error& e) {
    EXPECT_STREQ(e.what(), "label 9 not found");
  }
  o.vertices = 3;
  EXPECT_THROW(msk::templateFromLabels(lab, 3, o), msk::ParameterError);
  o.vertices = 100;
  o.smoothingSigmaMm = -1;
  EXPECT_THROW(msk::templateFromLabels(lab, 3, o), msk::ParameterError);
}

TEST(TemplateBuilder, StructureCutByTheGridGetsFlatCapsOnTheVoxelBoundary) {
  const msk::LabelMap lab = cutCylinderLabels();
  const msk::TriangleMesh m = msk::templateFromLabels(lab, 1);
  ASSERT_EQ(msk::closedMeshProblem(m), "");
  // Caps on the voxel boundaries z = −1.5 and z = 34.5 (voxel centres 0 … 33).
  EXPECT_NEAR(m.vertices.col(2).minCoeff(), -1.5, 0.3);
  EXPECT_NEAR(m.vertices.col(2).maxCoeff(), 34.5, 0.3);
  EXPECT_NEAR(msk::enclosedVolume(m), voxelVolume(lab, 1), 0.01 * voxelVolume(lab, 1));
}

// The same cut cylinder continued beyond the faces that cut it: its section repeated straight out by the slices that
// hold extendCutMm, the volume preserved with them; a ball that grazes a face (a section of a few voxels) is not.
TEST(TemplateBuilder, StructureCutByTheGridIsContinuedBeyondIt) {
  const msk::LabelMap lab = cutCylinderLabels();
  const msk::Grid& g = lab.grid;
  msk::TemplateOptions o;
  o.extendCutMm = 20;  // 7 slices of 3 mm: 21 mm
  msk::TemplateReport rep;
  const msk::TriangleMesh m = msk::templateFromLabels(lab, 1, o, &rep);
  ASSERT_EQ(msk::closedMeshProblem(m), "");
  EXPECT_EQ(rep.extendedFaces, (std::vector<std::string>{"inferior", "superior"}));
  EXPECT_DOUBLE_EQ(rep.extendedMm, 21.0);
  EXPECT_NEAR(m.vertices.col(2).minCoeff(), -1.5 - 21, 0.3);
  EXPECT_NEAR(m.vertices.col(2).maxCoeff(), 34.5 + 21, 0.3);
  // Straight out: the continued parts have the cut section's radius and centre.
  for (int v = 0; v < m.vertexCount(); ++v) {
    const Eigen::Vector3d p = m.vertices.row(v).transpose();
    if (p.z() < -10 || p.z() > 45) {
      EXPECT_LE(p.head<2>().norm(), 8.6) << p.transpose();
    }
  }
  const double continued = voxelVolume(lab, 1) * (12.0 + 14.0) / 12.0;
  EXPECT_NEAR(msk::enclosedVolume(m), continued, 0.01 * continued);

  // A ball whose edge just reaches the face z = 0: a graze, capped as before.
  msk::LabelMap ball(g, 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if ((g.toWorld(Eigen::Vector3d(i, j, k)) - Eigen::Vector3d(0, 0, 11.9)).norm() <= 12) ball.at(i, j, k) = 2;
  msk::TemplateReport ballRep;
  const msk::TriangleMesh b = msk::templateFromLabels(ball, 2, o, &ballRep);
  EXPECT_TRUE(ballRep.extendedFaces.empty());
  EXPECT_GT(b.vertices.col(2).minCoeff(), -2.0);

  // Along another axis on an oblique grid, the face is named by the direction it faces.
  msk::LabelMap side = lab;
  side.grid.direction = msk::Grid::rotationXYZ({0, 90, 0});  // k points to +x: the grid's last face looks right
  msk::TemplateReport sideRep;
  msk::templateFromLabels(side, 1, o, &sideRep);
  EXPECT_EQ(sideRep.extendedFaces, (std::vector<std::string>{"left", "right"}));

  o.extendCutMm = -1;
  EXPECT_THROW(msk::templateFromLabels(lab, 1, o), msk::ParameterError);
}

TEST(TemplateBuilder, MirrorReflectsAndKeepsNormalsOutward) {
  msk::TriangleMesh ball = msk::makeIcosphere(5, 2, Eigen::Vector3d(10, 3, -4));
  ball.pointData["id"] = Eigen::VectorXd::LinSpaced(ball.vertexCount(), 0, ball.vertexCount() - 1);
  const msk::TriangleMesh m = msk::mirrorMesh(ball, Eigen::Vector3d(2, 100, 7), Eigen::Vector3d(3, 0, 0));
  ASSERT_EQ(msk::closedMeshProblem(m), "");
  EXPECT_NEAR(msk::enclosedVolume(m), msk::enclosedVolume(ball), 1e-9);
  EXPECT_GT(msk::enclosedVolume(m), 0);
  const Eigen::Vector3d centre = m.vertices.colwise().mean();
  EXPECT_LT((centre - Eigen::Vector3d(-6, 3, -4)).norm(), 1e-9);
  for (int i = 0; i < m.vertexCount(); ++i) EXPECT_DOUBLE_EQ(m.vertices(i, 0), 4.0 - ball.vertices(i, 0));
  EXPECT_EQ(m.pointData.at("id"), ball.pointData.at("id"));
  // Twice is the identity; an oblique plane keeps the volume too.
  const msk::TriangleMesh back = msk::mirrorMesh(m, Eigen::Vector3d(2, 0, 0), Eigen::Vector3d(-1, 0, 0));
  EXPECT_LT((back.vertices - ball.vertices).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(back.faces, ball.faces);
  const msk::TriangleMesh obl = msk::mirrorMesh(ball, Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, -2, 0.5));
  EXPECT_NEAR(msk::enclosedVolume(obl), msk::enclosedVolume(ball), 1e-9);
  EXPECT_THROW(msk::mirrorMesh(ball, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()), msk::ParameterError);
}

TEST(TemplateBuilder, RealCtFemur) {
  const std::string shared = msk::test::sharedData();
  if (shared.empty()) GTEST_SKIP() << "shared data not available";
  const msk::LabelMap lab = msk::readNifti<int32_t>(shared + "/totalseg-ct/labels.nii.gz");
  msk::TemplateReport rep;
  const msk::TriangleMesh m = msk::templateFromLabels(lab, 75, {}, &rep);
  ASSERT_EQ(msk::closedMeshProblem(m), "");
  const double v = msk::enclosedVolume(m);
  EXPECT_NEAR(v, rep.maskVolumeMm3, 0.05 * rep.maskVolumeMm3);
  EXPECT_NEAR(m.vertexCount(), 3000, 300);
  // Every vertex near the label: within two voxels of the mask's bounding box.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  const msk::Grid& g = lab.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (lab.at(i, j, k) == 75) {
          const Eigen::Vector3d w = g.toWorld(Eigen::Vector3d(i, j, k));
          lo = lo.cwiseMin(w);
          hi = hi.cwiseMax(w);
        }
  EXPECT_LT((m.vertices.colwise().minCoeff().transpose() - lo).cwiseAbs().maxCoeff(), 6.0);
  EXPECT_LT((m.vertices.colwise().maxCoeff().transpose() - hi).cwiseAbs().maxCoeff(), 6.0);
  // Mirrored across the sagittal plane through its centroid: still closed, positive, same volume.
  const double cx = m.vertices.col(0).mean();
  const msk::TriangleMesh mirrored = msk::mirrorMesh(m, Eigen::Vector3d(cx, 0, 0), Eigen::Vector3d::UnitX());
  EXPECT_EQ(msk::closedMeshProblem(mirrored), "");
  EXPECT_NEAR(msk::enclosedVolume(mirrored), v, 1e-6 * v);
  EXPECT_GT(msk::enclosedVolume(mirrored), 0);
}
