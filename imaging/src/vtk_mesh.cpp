// VTK adapter behind vtk_mesh.h.
#include "vtk_mesh.h"

#include <vtkCellArray.h>
#include <vtkCleanPolyData.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStringArray.h>
#include <vtkTriangleFilter.h>

#include "msk/core/error.h"

namespace msk::detail {

vtkSmartPointer<vtkPolyData> runReader(vtkAlgorithm* reader, const std::string& path, const std::string& what) {
  reader->Update();
  auto* out = vtkPolyData::SafeDownCast(reader->GetOutputDataObject(0));
  if (reader->GetErrorCode() != 0 || !out || out->GetNumberOfPoints() == 0)
    throw IoError(path, "cannot read the file as " + what + " (unreadable, corrupt or empty)");
  auto copy = vtkSmartPointer<vtkPolyData>::New();
  copy->ShallowCopy(out);
  return copy;
}

vtkSmartPointer<vtkPolyData> triangulate(vtkPolyData* in, bool mergePoints) {
  vtkSmartPointer<vtkPolyData> current = in;
  if (mergePoints) {
    vtkNew<vtkCleanPolyData> clean;
    clean->SetInputData(current);
    clean->PointMergingOn();
    clean->SetTolerance(0.0);
    clean->Update();
    current = clean->GetOutput();
  }
  vtkNew<vtkTriangleFilter> tri;
  tri->SetInputData(current);
  tri->PassVertsOff();
  tri->PassLinesOff();
  tri->Update();
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->ShallowCopy(tri->GetOutput());
  return out;
}

TriangleMesh toMesh(vtkPolyData* pd, const std::string& path) {
  TriangleMesh m;
  vtkCellArray* polys = pd->GetPolys();
  const vtkIdType nv = pd->GetNumberOfPoints();
  if (!polys || polys->GetNumberOfCells() == 0 || nv == 0)
    throw IoError(path, "the file holds no triangles (empty mesh, or a truncated or corrupt file)");
  m.faces.resize(polys->GetNumberOfCells(), 3);
  vtkIdType npts = 0;
  const vtkIdType* ids = nullptr;
  int f = 0;
  polys->InitTraversal();
  while (polys->GetNextCell(npts, ids)) {
    if (npts != 3) throw IoError(path, "a polygon could not be triangulated");
    for (int k = 0; k < 3; ++k) {
      if (ids[k] < 0 || ids[k] >= nv) throw IoError(path, "a triangle refers to a missing vertex");
      m.faces(f, k) = static_cast<int>(ids[k]);
    }
    ++f;
  }
  m.vertices.resize(nv, 3);
  vtkPoints* pts = pd->GetPoints();
  for (vtkIdType i = 0; i < nv; ++i) {
    double p[3];
    pts->GetPoint(i, p);
    m.vertices.row(i) << p[0], p[1], p[2];
  }
  vtkPointData* pdata = pd->GetPointData();
  for (int a = 0; pdata && a < pdata->GetNumberOfArrays(); ++a) {
    vtkDataArray* arr = pdata->GetArray(a);  // null for non-numeric arrays
    if (!arr || arr->GetNumberOfComponents() != 1 || !arr->GetName() || !*arr->GetName()) continue;
    if (arr->GetNumberOfTuples() != nv)
      throw IoError(path, std::string("point array '") + arr->GetName() + "' has the wrong length");
    Eigen::VectorXd values(nv);
    for (vtkIdType i = 0; i < nv; ++i) values[i] = arr->GetTuple1(i);
    m.pointData[arr->GetName()] = values;
  }
  return m;
}

vtkSmartPointer<vtkPolyData> toPolyData(const TriangleMesh& m) {
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(m.vertexCount());
  for (int i = 0; i < m.vertexCount(); ++i) points->SetPoint(i, m.vertices(i, 0), m.vertices(i, 1), m.vertices(i, 2));
  vtkNew<vtkCellArray> polys;
  polys->AllocateExact(m.faceCount(), 3 * m.faceCount());
  for (int f = 0; f < m.faceCount(); ++f) {
    const vtkIdType ids[3] = {m.faces(f, 0), m.faces(f, 1), m.faces(f, 2)};
    polys->InsertNextCell(3, ids);
  }
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  pd->SetPoints(points);
  pd->SetPolys(polys);
  return pd;
}

void addPointArrays(vtkPolyData* pd, const TriangleMesh& m, const std::string& path) {
  for (const auto& [name, values] : m.pointData) {
    if (name.empty()) throw IoError(path, "a point array has an empty name and cannot be stored");
    vtkNew<vtkDoubleArray> arr;
    arr->SetName(name.c_str());
    arr->SetNumberOfComponents(1);
    arr->SetNumberOfTuples(values.size());
    for (Eigen::Index i = 0; i < values.size(); ++i) arr->SetValue(i, values[i]);
    pd->GetPointData()->AddArray(arr);
  }
}

void addSpaceField(vtkFieldData* fd, MeshSpace space) {
  vtkNew<vtkStringArray> s;
  s->SetName("SPACE");
  s->InsertNextValue(meshSpaceName(space));
  fd->AddArray(s);
}

bool fieldDataSpace(vtkFieldData* fd, const std::string& path, MeshSpace& out) {
  if (!fd) return false;
  auto* s = vtkStringArray::SafeDownCast(fd->GetAbstractArray("SPACE"));
  if (!s || s->GetNumberOfValues() <= 0) return false;
  const std::string value = s->GetValue(0);
  try {
    out = parseMeshSpace(value);
  } catch (const ParameterError&) {
    throw IoError(path, "unknown coordinate space '" + value + "' in field data SPACE (expected LPS or RAS)");
  }
  return true;
}

}  // namespace msk::detail
