#include "targets.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <new>

#include "msk/core/error.h"
#include "msk/imaging/image_export.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/tet_mesh_io.h"
#include "msk/imaging/transform_io.h"
#include "msk/segmentation/atlas.h"
#include "msk/segmentation/scene.h"

namespace fs = std::filesystem;

namespace msk::fuzz {

namespace {

/// A private scratch folder for the inputs, made once per process and removed at exit, holding the fixtures the
/// scene and atlas targets refer to: a template (template.vtk) and a small atlas's files (atlas/).
const std::string& scratch() {
  // Never freed: the exit handler that removes the folder runs after static objects are destroyed.
  static const std::string& dir = *new std::string([] {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern = std::string(tmp && *tmp ? tmp : "/tmp") + "/mskseg-fuzz-XXXXXX";
    if (!::mkdtemp(pattern.data())) {
      std::perror("mskseg fuzz: cannot make a scratch folder");
      std::abort();
    }
    const fs::path fixtures = fs::path(MSK_FUZZ_FIXTURES);
    fs::copy(fixtures, pattern, fs::copy_options::recursive);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(scratch(), ec);
    });
    return pattern;
  }());
  return dir;
}

/// Writes the input to scratch()/name and returns that path.
std::string put(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = scratch() + "/" + name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) {
    std::fprintf(stderr, "mskseg fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
  return path;
}

/// Runs `read`; an msk::Error is the reader refusing the input, as it should; anything else aborts.
template <typename F>
void expectOnlyMskErrors(const char* target, F&& read) {
  try {
    read();
  } catch (const Error&) {
    // Refused with a message naming the file: the expected outcome for a malformed input.
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "mskseg fuzz %s: std::bad_alloc escaped the reader\n", target);
    std::abort();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mskseg fuzz %s: an exception that is not an msk::Error escaped: %s\n", target, e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "mskseg fuzz %s: an unknown exception escaped the reader\n", target);
    std::abort();
  }
}

void nifti(const uint8_t* data, size_t size) {
  const std::string path = put("input.nii", data, size);
  expectOnlyMskErrors("nifti", [&] { (void)readNifti<float>(path); });
}

template <const char* Ext>
void mesh(const uint8_t* data, size_t size) {
  const std::string path = put(std::string("input") + Ext, data, size);
  expectOnlyMskErrors(Ext, [&] { (void)readMesh(path); });
}
constexpr char kVtk[] = ".vtk", kVtp[] = ".vtp", kStl[] = ".stl", kObj[] = ".obj", kPly[] = ".ply";

void tetMesh(const uint8_t* data, size_t size) {
  const std::string path = put("input_tets.vtu", data, size);
  expectOnlyMskErrors("tet_vtu", [&] { (void)readTetMesh(path); });
}

void vtkImage(const uint8_t* data, size_t size) {
  const std::string path = put("input.vti", data, size);
  expectOnlyMskErrors("image_vti", [&] { (void)readVtkImage(path); });
}

/// scene.json beside the fixture template.vtk, which a scene may name.
void scene(const uint8_t* data, size_t size) {
  const std::string path = put("scene.json", data, size);
  expectOnlyMskErrors("scene", [&] { (void)loadScene(path); });
}

/// atlas.json in a copy of a small atlas's folder (reference image, templates, scene, all with the checksums the
/// fixture's own atlas.json records).
void atlas(const uint8_t* data, size_t size) {
  (void)put("atlas/atlas.json", data, size);
  expectOnlyMskErrors("atlas", [&] { (void)loadAtlas(scratch() + "/atlas"); });
}

/// A linear transform as .txt, which takes all three forms (ITK text, JSON matrix, plain 4×4).
void transform(const uint8_t* data, size_t size) {
  const std::string path = put("input_transform.txt", data, size);
  expectOnlyMskErrors("transform", [&] { (void)readLinearTransform(path); });
}

}  // namespace

const std::vector<Target>& targets() {
  static const std::vector<Target> all = {{"nifti", nifti},         {"mesh_vtk", mesh<kVtk>}, {"mesh_vtp", mesh<kVtp>},
                                          {"mesh_stl", mesh<kStl>}, {"mesh_obj", mesh<kObj>}, {"mesh_ply", mesh<kPly>},
                                          {"tet_vtu", tetMesh},     {"image_vti", vtkImage},  {"scene", scene},
                                          {"atlas", atlas},         {"transform", transform}};
  return all;
}

const Target* findTarget(const std::string& name) {
  for (const Target& t : targets())
    if (name == t.name) return &t;
  return nullptr;
}

}  // namespace msk::fuzz
