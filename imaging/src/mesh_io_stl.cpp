// STL (.stl), read and written by VTK: ASCII or binary in, binary out (float32 coordinates). The SPACE tag is in
// the 80-byte binary header or on the ASCII "solid" line.
#include <vtkNew.h>
#include <vtkSTLReader.h>
#include <vtkSTLWriter.h>

#include <cstdint>
#include <filesystem>

#include "mesh_io_detail.h"
#include "vtk_mesh.h"

namespace msk::detail {

namespace {

/// Space tag from the STL header: the 80-byte binary header or the ASCII "solid" line.
bool stlSpace(const std::string& path, MeshSpace& out) {
  std::string head = readBytes(path, 256);
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && head.size() >= 84) {
    uint32_t n = 0;
    for (int b = 3; b >= 0; --b) n = (n << 8) | static_cast<unsigned char>(head[80 + static_cast<size_t>(b)]);
    if (static_cast<uintmax_t>(n) * 50 + 84 == size) head.resize(80);  // binary: the header only
  }
  head = head.substr(0, head.find('\n'));
  head = head.substr(0, head.find('\0'));
  return findSpaceToken(head, path, out);
}

}  // namespace

TriangleMesh readStl(const std::string& path, MeshSpace& space) {
  VtkQuiet quiet;
  stlSpace(path, space);
  vtkNew<vtkSTLReader> r;
  r->SetFileName(path.c_str());
  r->MergingOn();
  // STL stores each face's corners: merge them so the surface is closed.
  return toMesh(triangulate(runReader(r, path, "STL"), true), path);
}

void writeStl(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  VtkQuiet quiet;
  const std::string header = headerText(space);
  vtkNew<vtkSTLWriter> w;
  w->SetInputData(toPolyData(m));
  w->SetFileName(file.c_str());
  w->SetFileTypeToBinary();
  w->SetHeader(header.c_str());
  if (!(w->Write() && w->GetErrorCode() == 0)) throw IoError(path, "VTK could not write the file");
}

}  // namespace msk::detail
