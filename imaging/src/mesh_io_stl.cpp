// STL (.stl), read and written by VTK: ASCII or binary in, binary out (float32 coordinates). The SPACE tag is in
// the 80-byte binary header or on the ASCII "solid" line.
#include <vtkNew.h>
#include <vtkSTLReader.h>
#include <vtkSTLWriter.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>

#include "isolated_reader.h"
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

/// Refuses a binary STL whose triangle count asks for more bytes than the file has, before VTK reserves memory for
/// it (VTK takes the count as given). A file is read as binary, as VTK reads it, unless its first 256 bytes are all
/// text (no NUL, nothing above 127).
void checkStlSize(const std::string& path) {
  const std::string head = readBytes(path, 256);
  const bool text = std::all_of(head.begin(), head.end(), [](char ch) {
    const unsigned char c = static_cast<unsigned char>(ch);
    return c != 0 && c < 128;
  });
  if (text && head.rfind("solid", 0) == 0) return;
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw IoError(path, "cannot read the file size: " + ec.message());
  if (head.size() < 84 || size < 84) throw IoError(path, "binary STL shorter than its 84-byte header");
  uint32_t n = 0;
  for (int b = 3; b >= 0; --b) n = (n << 8) | static_cast<unsigned char>(head[80 + static_cast<size_t>(b)]);
  if (static_cast<uintmax_t>(n) * 50 + 84 > size)
    throw IoError(path, "binary STL header says " + std::to_string(n) + " triangles (" +
                            std::to_string(static_cast<uintmax_t>(n) * 50 + 84) + " bytes) but the file has " +
                            std::to_string(size) + " bytes");
}

/// VTK's STL reader in this process.
TriangleMesh readStlHere(const std::string& path, MeshSpace& space) {
  VtkQuiet quiet;
  stlSpace(path, space);
  vtkNew<vtkSTLReader> r;
  r->SetFileName(path.c_str());
  r->MergingOn();
  // STL stores each face's corners: merge them so the surface is closed.
  return toMesh(triangulate(runReader(r, path, "STL"), true), path);
}

}  // namespace

// A file that starts as ASCII ("solid ...") but does not parse as ASCII is read by VTK as binary, with the triangle
// count of bytes 80-83 taken as given (a 125-byte file asked for 17 GB): after the binary count check, VTK's reader
// runs in a child process, where such an allocation ends in one error naming the file.
TriangleMesh readStl(const std::string& path, MeshSpace& space) {
  checkStlSize(path);
  return readInChildProcess(path, space, "VTK STL", readStlHere);
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
