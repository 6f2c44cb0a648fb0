#pragma once
/// Volumes as VTK XML image data (.vti) with their world placement, for VTK-based viewers (ParaView), whose NIfTI
/// reader places an image by its spacing alone.
#include <string>

#include "msk/imaging/mesh_io.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Writes `image` as .vti (atomically): origin, spacing and direction matrix in `space` (LPS by default, the space of
/// mskseg's mesh files, so the two overlay), the values as point data "intensity", and a field data string "SPACE"
/// naming the space. Throws IoError naming the file.
void writeVtkImage(const std::string& path, const ImageF& image, MeshSpace space = MeshSpace::LPS);

/// The same for a label map (point data "labels", 16-bit integers; labels must lie in -32768..32767).
void writeVtkImage(const std::string& path, const LabelMap& labels, MeshSpace space = MeshSpace::LPS);

/// Reads a .vti written by writeVtkImage() (or any single-component image data) back as a volume in RAS: its
/// placement from origin, spacing and direction, honouring the SPACE field (LPS if there is none). VTK's XML reader
/// runs in a child process (see mesh_io_vtp.cpp). Throws IoError naming the file.
ImageF readVtkImage(const std::string& path);

}  // namespace msk
