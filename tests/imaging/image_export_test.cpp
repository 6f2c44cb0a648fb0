#include "msk/imaging/image_export.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <string>

#include "msk/core/error.h"
#include "msk/test/files.h"

using msk::MeshSpace;
using msk::test::ScratchDir;

namespace {

/// An oblique, anisotropic grid (rotated 20° about z, 10° about x) holding a distinct value per voxel.
msk::ImageF obliqueImage() {
  msk::ImageF img;
  img.grid.dims = Eigen::Vector3i(7, 5, 4);
  img.grid.spacing = Eigen::Vector3d(0.8, 1.1, 2.5);
  img.grid.origin = Eigen::Vector3d(-31.5, 12.25, 80.0);
  img.grid.direction = (Eigen::AngleAxisd(20 * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                        Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitX()))
                           .toRotationMatrix();
  img.data.resize(img.grid.voxelCount());
  for (size_t v = 0; v < img.data.size(); ++v) img.data[v] = 0.5f * static_cast<float>(v) - 3.0f;
  return img;
}

}  // namespace

// A volume written as .vti in either space reads back in RAS with its placement and values: each voxel lands at the
// same world position.
TEST(ImageExport, VtiKeepsTheWorldPlacementInEitherSpace) {
  ScratchDir dir;
  const msk::ImageF img = obliqueImage();
  for (MeshSpace space : {MeshSpace::LPS, MeshSpace::RAS}) {
    SCOPED_TRACE(msk::meshSpaceName(space));
    const std::string path = dir.file(std::string("image_") + msk::meshSpaceName(space) + ".vti");
    msk::writeVtkImage(path, img, space);
    const msk::ImageF back = msk::readVtkImage(path);
    ASSERT_EQ(back.grid.dims, img.grid.dims);
    EXPECT_TRUE(back.grid.spacing.isApprox(img.grid.spacing, 1e-6));
    for (const Eigen::Vector3d& ijk : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(6, 4, 3), Eigen::Vector3d(2, 3, 1)})
      EXPECT_LT((back.grid.toWorld(ijk) - img.grid.toWorld(ijk)).norm(), 1e-4) << ijk.transpose();
    EXPECT_EQ(back.data, img.data);
  }
  // Label maps keep their values.
  msk::LabelMap labels;
  labels.grid = img.grid;
  labels.data.assign(img.grid.voxelCount(), 0);
  labels.data[17] = 300;
  labels.data[18] = 2;
  msk::writeVtkImage(dir.file("labels.vti"), labels);
  const msk::ImageF back = msk::readVtkImage(dir.file("labels.vti"));
  EXPECT_EQ(back.data[17], 300.0f);
  EXPECT_EQ(back.data[18], 2.0f);
  labels.data[0] = 40000;
  EXPECT_THROW(msk::writeVtkImage(dir.file("big.vti"), labels), msk::IoError);
  msk::test::writeBytes(dir.file("garbage.vti"), "<VTKFile type=\"ImageData\"><ImageData");
  EXPECT_THROW(msk::readVtkImage(dir.file("garbage.vti")), msk::IoError);
}
