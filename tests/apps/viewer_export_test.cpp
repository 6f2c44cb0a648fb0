// What a VTK-based viewer (ParaView) sees of `mskseg segment --image-export vti`: the outputs read with VTK's own
// readers (vtkXMLImageDataReader, vtkPolyDataReader), not mskseg's, in the files' own coordinates (LPS), the images
// placed by origin, spacing and direction matrix. Each mesh lies inside the image, and the box of each object's voxels
// in labels.vti is the box of its mesh to within about a voxel; a copy whose direction matrices were dropped fails.
#include <gtest/gtest.h>
#include <vtkDataArray.h>
#include <vtkFieldData.h>
#include <vtkImageData.h>
#include <vtkMatrix3x3.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkPolyDataReader.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkXMLImageDataReader.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <regex>
#include <string>
#include <vector>

#include "msk/test/cli.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;
using msk::test::runCli;

namespace {

const std::string kSample = msk::test::bundledSample();
/// The phantom's structures and labels (mskseg phantom's scene, also the bundled sample's).
const std::vector<std::pair<std::string, int>> kObjects = {
    {"femur", 1}, {"quadriceps", 2}, {"hamstrings", 3}, {"adductors", 4}};

constexpr double kHuge = std::numeric_limits<double>::max();

/// An axis-aligned box in mm.
struct Box {
  std::array<double, 3> lo{{kHuge, kHuge, kHuge}};
  std::array<double, 3> hi{{-kHuge, -kHuge, -kHuge}};
  void add(const double p[3]) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
  }
};

/// A .vti as vtkXMLImageDataReader gives it (as ParaView's reader does), failing the test if it cannot be read.
vtkSmartPointer<vtkImageData> readVti(const std::string& path) {
  vtkNew<vtkXMLImageDataReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  EXPECT_EQ(reader->GetErrorCode(), 0) << path;
  vtkSmartPointer<vtkImageData> image = reader->GetOutput();
  EXPECT_NE(image->GetPointData()->GetScalars(), nullptr) << path;
  return image;
}

/// The string field SPACE that mskseg writes into a .vti's field data ("" if absent).
std::string spaceField(vtkImageData* image) {
  auto* space = vtkStringArray::SafeDownCast(image->GetFieldData()->GetAbstractArray("SPACE"));
  return space && space->GetNumberOfValues() == 1 ? space->GetValue(0) : "";
}

/// The physical box of an image's voxel centres: its eight corner voxels mapped by origin + direction · (index ·
/// spacing).
Box physicalBounds(vtkImageData* image) {
  const int* e = image->GetExtent();
  Box box;
  for (int i : {e[0], e[1]})
    for (int j : {e[2], e[3]})
      for (int k : {e[4], e[5]}) {
        double p[3];
        image->TransformIndexToPhysicalPoint(i, j, k, p);
        box.add(p);
      }
  return box;
}

/// The extent of one voxel along each world axis, sum_j |D(a, j)| spacing_j (mm): the spacing on an axis-aligned grid.
std::array<double, 3> voxelExtent(vtkImageData* image) {
  std::array<double, 3> extent{};
  for (int a = 0; a < 3; ++a)
    for (int j = 0; j < 3; ++j)
      extent[a] += std::abs(image->GetDirectionMatrix()->GetElement(a, j)) * image->GetSpacing()[j];
  return extent;
}

/// The physical box of each label's voxel centres in a label image.
std::map<int, Box> labelBoxes(vtkImageData* labels) {
  std::map<int, Box> boxes;
  vtkDataArray* values = labels->GetPointData()->GetScalars();
  const int* e = labels->GetExtent();
  vtkIdType id = 0;
  for (int k = e[4]; k <= e[5]; ++k)
    for (int j = e[2]; j <= e[3]; ++j)
      for (int i = e[0]; i <= e[1]; ++i, ++id) {
        const int label = static_cast<int>(std::lround(values->GetComponent(id, 0)));
        if (label == 0) continue;
        double p[3];
        labels->TransformIndexToPhysicalPoint(i, j, k, p);
        boxes[label].add(p);
      }
  return boxes;
}

/// How far a viewer's reading of an output folder is from agreement. The sides of an object's voxel box are compared
/// with its mesh box's, in voxel extents along that axis: positive where the voxels reach beyond the mesh, negative
/// where they stop short of it.
struct ViewerAgreement {
  int meshesRead = 0;
  int verticesOutsideImage = 0;  ///< mesh vertices outside the image's voxels (half a voxel around the centres)
  int meshesOutsideBounds = 0;   ///< meshes whose box is not inside the image's physical box (grown by half a voxel)
  double mostBeyond = -std::numeric_limits<double>::infinity();  ///< largest overshoot of a voxel box side (voxels)
  double mostShort = -std::numeric_limits<double>::infinity();   ///< largest shortfall of a voxel box side (voxels)
  double mostBeyondMm = 0, mostShortMm = 0;                      ///< the same in mm
  std::string beyondWhere, shortWhere;                           ///< object, axis and side of each
};

/// Reads OUT/image.vti, OUT/labels.vti and OUT/<name>.vtk with VTK's readers and measures their agreement.
ViewerAgreement measureAgreement(const std::string& out) {
  ViewerAgreement m;
  const vtkSmartPointer<vtkImageData> image = readVti(out + "/image.vti");
  const vtkSmartPointer<vtkImageData> labels = readVti(out + "/labels.vti");
  EXPECT_EQ(spaceField(image), "LPS");
  EXPECT_EQ(spaceField(labels), "LPS");
  const Box bounds = physicalBounds(image);
  const std::array<double, 3> voxel = voxelExtent(labels);
  const std::map<int, Box> voxelBoxes = labelBoxes(labels);
  const int* e = image->GetExtent();
  for (const auto& [name, label] : kObjects) {
    vtkNew<vtkPolyDataReader> reader;
    const std::string path = out + "/" + name + ".vtk";
    reader->SetFileName(path.c_str());
    reader->Update();
    vtkPolyData* mesh = reader->GetOutput();
    if (reader->GetErrorCode() != 0 || mesh->GetNumberOfPoints() == 0) {
      ADD_FAILURE() << path << ": VTK cannot read it";
      continue;
    }
    ++m.meshesRead;
    EXPECT_NE(std::string(reader->GetHeader() ? reader->GetHeader() : "").find("SPACE=LPS"), std::string::npos) << path;
    Box meshBox;
    for (vtkIdType v = 0; v < mesh->GetNumberOfPoints(); ++v) {
      double p[3], ijk[3];
      mesh->GetPoint(v, p);
      meshBox.add(p);
      image->TransformPhysicalPointToContinuousIndex(p, ijk);
      bool inside = true;
      for (int a = 0; a < 3; ++a) inside = inside && ijk[a] >= e[2 * a] - 0.5 && ijk[a] <= e[2 * a + 1] + 0.5;
      m.verticesOutsideImage += inside ? 0 : 1;
    }
    bool within = true;
    for (int a = 0; a < 3; ++a)
      within = within && meshBox.lo[a] >= bounds.lo[a] - voxel[a] / 2 && meshBox.hi[a] <= bounds.hi[a] + voxel[a] / 2;
    m.meshesOutsideBounds += within ? 0 : 1;

    const auto found = voxelBoxes.find(label);
    if (found == voxelBoxes.end()) {
      m.mostShort = std::numeric_limits<double>::infinity();
      m.shortWhere = name + ": no voxel in labels.vti";
      continue;
    }
    for (int a = 0; a < 3; ++a)
      for (int side = 0; side < 2; ++side) {
        const double beyond =
            side == 0 ? meshBox.lo[a] - found->second.lo[a] : found->second.hi[a] - meshBox.hi[a];  // mm
        const std::string where = name + " " + "xyz"[a] + (side == 0 ? " min" : " max");
        if (beyond / voxel[a] > m.mostBeyond) {
          m.mostBeyond = beyond / voxel[a];
          m.mostBeyondMm = beyond;
          m.beyondWhere = where;
        }
        if (-beyond / voxel[a] > m.mostShort) {
          m.mostShort = -beyond / voxel[a];
          m.mostShortMm = -beyond;
          m.shortWhere = where;
        }
      }
  }
  return m;
}

/// A copy of the output folder with the direction matrix of image.vti and labels.vti replaced by the identity, as a
/// writer or reader that drops it would leave them.
std::string withoutDirections(const std::string& out, const std::string& copy) {
  fs::create_directories(copy);
  for (const auto& f : fs::directory_iterator(out))
    if (f.is_regular_file()) fs::copy_file(f.path(), copy + "/" + f.path().filename().string());
  for (const char* name : {"/image.vti", "/labels.vti"}) {
    const std::string bytes = msk::test::readBytes(copy + name);
    const std::regex direction("Direction=\"[^\"]*\"");
    EXPECT_TRUE(std::regex_search(bytes, direction)) << name;
    msk::test::writeBytes(copy + name, std::regex_replace(bytes, direction, "Direction=\"1 0 0 0 1 0 0 0 1\""));
  }
  return copy;
}

/// Checks the agreement of a run's outputs, and that the same check fails once the direction matrices are dropped.
/// mskseg labels the voxels whose centres are inside a mesh, so each object's voxel box lies inside its mesh box (up to
/// the files' float precision) and reaches to within about a voxel of it: measured up to 1.11 voxels short (1.33 mm at
/// 1.2 mm spacing, the hamstrings' wedge tip on the bundled sample, thinner there than a voxel), hence 1.5.
void expectViewerAgreement(const std::string& out, const msk::test::ScratchDir& dir) {
  const ViewerAgreement m = measureAgreement(out);
  EXPECT_EQ(m.meshesRead, static_cast<int>(kObjects.size()));
  EXPECT_EQ(m.verticesOutsideImage, 0);
  EXPECT_EQ(m.meshesOutsideBounds, 0);
  EXPECT_LE(m.mostBeyond, 0.01) << m.beyondWhere << ": the voxels reach " << m.mostBeyondMm << " mm beyond the mesh";
  EXPECT_LE(m.mostShort, 1.5) << m.shortWhere << ": the voxels stop " << m.mostShortMm << " mm short of the mesh";
  ::testing::Test::RecordProperty("voxels_beyond_mesh_mm", std::to_string(m.mostBeyondMm));
  ::testing::Test::RecordProperty("voxels_short_of_mesh_mm", std::to_string(m.mostShortMm));
  ::testing::Test::RecordProperty("voxels_short_of_mesh_voxels", std::to_string(m.mostShort));

  const ViewerAgreement dropped = measureAgreement(withoutDirections(out, dir.file("no-direction")));
  EXPECT_GT(std::max(dropped.mostBeyond, dropped.mostShort), 3.0)
      << "without its direction matrix labels.vti should lie elsewhere than the meshes";
  EXPECT_GT(dropped.verticesOutsideImage + dropped.meshesOutsideBounds, 0) << "and the meshes outside the image";
}

}  // namespace

// An oblique grid (rotated 12°, -18°, 25° about x, y, z): the direction matrix is a full rotation, so a viewer or a
// writer that ignored it would put the image and labels elsewhere than the meshes.
TEST(ViewerExport, ObliqueImageLabelsAndMeshesAgreeInVtkReaders) {
  msk::test::ScratchDir dir;
  const std::string phantom = dir.file("phantom"), out = dir.file("out");
  auto r = runCli({"phantom", "--seed", "3", "--oblique", "12,-18,25", "--spacing", "1.5,1.5,3", "--out", phantom});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = runCli({"segment", "--image", phantom + "/image.nii.gz", "--scene", phantom + "/scene.json", "--out", out,
              "--quality", "fast", "--no-qc", "--image-export", "vti"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const vtkSmartPointer<vtkImageData> image = readVti(out + "/image.vti");
  double offDiagonal = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      if (a != b) offDiagonal = std::max(offDiagonal, std::abs(image->GetDirectionMatrix()->GetElement(a, b)));
  ASSERT_GT(offDiagonal, 0.2) << "the test needs an oblique direction matrix";
  expectViewerAgreement(out, dir);
}

// The bundled sample: an axis-aligned RAS grid, whose direction in LPS is diag(-1, -1, 1).
TEST(ViewerExport, SampleImageLabelsAndMeshesAgreeInVtkReaders) {
  msk::test::ScratchDir dir;
  const std::string out = dir.file("out");
  const auto r = runCli({"segment", "--image", kSample + "image.nii.gz", "--scene", kSample + "scene.json", "--out",
                         out, "--quality", "fast", "--no-qc", "--image-export", "vti"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const vtkSmartPointer<vtkImageData> image = readVti(out + "/image.vti");
  EXPECT_DOUBLE_EQ(image->GetDirectionMatrix()->GetElement(0, 0), -1.0);
  EXPECT_DOUBLE_EQ(image->GetDirectionMatrix()->GetElement(1, 1), -1.0);
  expectViewerAgreement(out, dir);
}
