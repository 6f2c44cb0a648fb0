// VTK XML polydata (.vtp), read and written by VTK. The SPACE tag is the field data string array "SPACE";
// an XML comment "<!-- SPACE=... -->" is honoured when reading.
#include <vtkNew.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include "isolated_reader.h"
#include "mesh_io_detail.h"
#include "vtk_mesh.h"

namespace msk::detail {

namespace {

/// Space tag of a VTP file: field data "SPACE" (a string array), else an XML comment "<!-- SPACE=... -->".
bool vtpSpace(const std::string& path, vtkPolyData* pd, MeshSpace& out) {
  if (fieldDataSpace(pd->GetFieldData(), path, out)) return true;
  std::string head = readBytes(path, kHeadBytes);
  head = head.substr(0, head.find("<AppendedData"));
  for (size_t open = head.find("<!--"); open != std::string::npos; open = head.find("<!--", open + 4)) {
    const size_t close = head.find("-->", open);
    if (findSpaceToken(head.substr(open + 4, close == std::string::npos ? std::string::npos : close - open - 4), path,
                       out))
      return true;
  }
  return false;
}

/// VTK's XML reader in this process.
TriangleMesh readVtpHere(const std::string& path, MeshSpace& space) {
  VtkQuiet quiet;
  vtkNew<vtkXMLPolyDataReader> r;
  r->SetFileName(path.c_str());
  vtkSmartPointer<vtkPolyData> pd = runReader(r, path, "VTK XML polydata");
  vtpSpace(path, pd, space);
  pd = triangulate(pd, false);
  return toMesh(pd, path);
}

}  // namespace

// VTK's XML reader crashes (null pointers, division by zero, unbounded recursion) and exhausts memory or time on
// malformed files, and validating its XML, base64 and compressed blocks ahead of it would mean writing a reader: it
// runs in a child process instead, where a crash is one error naming the file.
TriangleMesh readVtp(const std::string& path, MeshSpace& space) {
  return readInChildProcess(path, space, "VTK XML", readVtpHere);
}

void writeVtp(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  VtkQuiet quiet;
  const vtkSmartPointer<vtkPolyData> pd = toPolyData(m);
  addPointArrays(pd, m, path);
  addSpaceField(pd->GetFieldData(), space);
  vtkNew<vtkXMLPolyDataWriter> w;
  w->SetInputData(pd);
  w->SetFileName(file.c_str());
  if (!(w->Write() && w->GetErrorCode() == 0)) throw IoError(path, "VTK could not write the file");
}

}  // namespace msk::detail
