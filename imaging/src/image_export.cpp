// Volumes as VTK XML image data (VTK confined to this file and vtk_mesh.h).
#include "msk/imaging/image_export.h"

#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkMatrix3x3.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkShortArray.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLImageDataWriter.h>

#include <cmath>
#include <cstdint>

#include "isolated_reader.h"
#include "mesh_io_detail.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "vtk_mesh.h"

namespace msk {

namespace {

/// RAS <-> LPS: x and y change sign.
const Eigen::Matrix3d kFlip = Eigen::Vector3d(-1, -1, 1).asDiagonal();

/// Image data with `grid`'s placement in `space` and `values` as its point data.
template <typename Array, typename Values>
void writeGrid(const std::string& path, const Grid& grid, const Values& values, const char* name, MeshSpace space) {
  detail::VtkQuiet quiet;
  const Eigen::Matrix3d flip = space == MeshSpace::LPS ? kFlip : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d origin = flip * grid.origin;
  const Eigen::Matrix3d direction = flip * grid.direction;
  vtkNew<vtkImageData> img;
  img->SetDimensions(grid.dims[0], grid.dims[1], grid.dims[2]);
  img->SetOrigin(origin[0], origin[1], origin[2]);
  img->SetSpacing(grid.spacing[0], grid.spacing[1], grid.spacing[2]);
  img->SetDirectionMatrix(direction(0, 0), direction(0, 1), direction(0, 2), direction(1, 0), direction(1, 1),
                          direction(1, 2), direction(2, 0), direction(2, 1), direction(2, 2));
  vtkNew<Array> data;
  data->SetName(name);
  data->SetNumberOfComponents(1);
  data->SetNumberOfTuples(static_cast<vtkIdType>(values.size()));
  for (size_t v = 0; v < values.size(); ++v) data->SetValue(static_cast<vtkIdType>(v), values[v]);
  img->GetPointData()->SetScalars(data);
  detail::addSpaceField(img->GetFieldData(), space);
  writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkXMLImageDataWriter> w;
    w->SetInputData(img);
    w->SetFileName(tmp.c_str());
    if (!(w->Write() && w->GetErrorCode() == 0)) throw IoError(path, "VTK could not write the file");
  });
}

/// The file as a volume as stored (not yet in RAS), and its space.
ImageF readHere(const std::string& path, MeshSpace& space) {
  detail::VtkQuiet quiet;
  vtkNew<vtkXMLImageDataReader> r;
  r->SetFileName(path.c_str());
  r->Update();
  vtkImageData* img = r->GetOutput();
  vtkDataArray* data = img ? img->GetPointData()->GetScalars() : nullptr;
  if (r->GetErrorCode() != 0 || !img || !data || data->GetNumberOfComponents() != 1)
    throw IoError(path, "cannot read the file as VTK XML image data with one value per point");
  detail::fieldDataSpace(img->GetFieldData(), path, space);
  int dims[3];
  img->GetDimensions(dims);
  ImageF out;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1) throw IoError(path, "empty image");
    out.grid.dims[a] = dims[a];
    out.grid.spacing[a] = img->GetSpacing()[a];
    out.grid.origin[a] = img->GetOrigin()[a];
    for (int b = 0; b < 3; ++b) out.grid.direction(a, b) = img->GetDirectionMatrix()->GetElement(a, b);
  }
  if (static_cast<size_t>(data->GetNumberOfTuples()) != out.grid.voxelCount())
    throw IoError(path, "its point data does not match its dimensions");
  out.data.resize(out.grid.voxelCount());
  for (size_t v = 0; v < out.data.size(); ++v)
    out.data[v] = static_cast<float>(data->GetComponent(static_cast<vtkIdType>(v), 0));
  return out;
}

}  // namespace

void writeVtkImage(const std::string& path, const ImageF& image, MeshSpace space) {
  writeGrid<vtkFloatArray>(path, image.grid, image.data, "intensity", space);
}

void writeVtkImage(const std::string& path, const LabelMap& labels, MeshSpace space) {
  std::vector<int16_t> values(labels.data.size());
  for (size_t v = 0; v < values.size(); ++v) {
    if (labels.data[v] < -32768 || labels.data[v] > 32767)
      throw IoError(path, "label " + std::to_string(labels.data[v]) + " does not fit 16 bits");
    values[v] = static_cast<int16_t>(labels.data[v]);
  }
  writeGrid<vtkShortArray>(path, labels.grid, values, "labels", space);
}

ImageF readVtkImage(const std::string& path) {
  detail::requireRegularFile(path);
  MeshSpace space = MeshSpace::LPS;
  const std::string bytes = detail::runInChildProcess(path, "VTK XML", [&] {
    MeshSpace found = MeshSpace::LPS;
    const ImageF img = readHere(path, found);
    detail::ByteWriter out;
    out.value<int32_t>(found == MeshSpace::LPS ? 0 : 1);
    for (int a = 0; a < 3; ++a) out.value<int32_t>(img.grid.dims[a]);
    for (int a = 0; a < 3; ++a) out.value<double>(img.grid.spacing[a]);
    for (int a = 0; a < 3; ++a) out.value<double>(img.grid.origin[a]);
    for (int a = 0; a < 9; ++a) out.value<double>(img.grid.direction(a / 3, a % 3));
    for (float v : img.data) out.value<float>(v);
    return std::move(out.bytes());
  });
  detail::ByteReader in(bytes, path);
  space = in.value<int32_t>() == 0 ? MeshSpace::LPS : MeshSpace::RAS;
  ImageF img;
  for (int a = 0; a < 3; ++a) img.grid.dims[a] = in.value<int32_t>();
  for (int a = 0; a < 3; ++a) img.grid.spacing[a] = in.value<double>();
  for (int a = 0; a < 3; ++a) img.grid.origin[a] = in.value<double>();
  for (int a = 0; a < 9; ++a) img.grid.direction(a / 3, a % 3) = in.value<double>();
  if ((img.grid.dims.array() < 1).any() || img.grid.voxelCount() * 4 != in.left()) in.malformed();
  img.data.resize(img.grid.voxelCount());
  for (float& v : img.data) v = in.value<float>();
  if (space == MeshSpace::LPS) {
    img.grid.origin = kFlip * img.grid.origin;
    img.grid.direction = kFlip * img.grid.direction;
  }
  return img;
}

}  // namespace msk
