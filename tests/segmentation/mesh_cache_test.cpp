#include "msk/segmentation/mesh_cache.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <string>

#include "msk/core/triangle_mesh.h"
#include "msk/test/files.h"

namespace fs = std::filesystem;

namespace {

bool sameBytes(const msk::TriangleMesh& a, const msk::TriangleMesh& b) {
  return a.vertices.rows() == b.vertices.rows() && a.faces.rows() == b.faces.rows() &&
         std::memcmp(a.vertices.data(), b.vertices.data(), sizeof(double) * a.vertices.size()) == 0 &&
         (a.faces.array() == b.faces.array()).all();
}

/// A derivation that counts its calls: the input's vertices moved by a third of a millimetre (not exact in binary).
struct Counted {
  int calls = 0;
  msk::TriangleMesh operator()(const msk::TriangleMesh& in) {
    ++calls;
    msk::TriangleMesh out = in;
    out.vertices.array() += 1.0 / 3.0;
    return out;
  }
};

}  // namespace

// A derived mesh is stored once and read back with the same bytes; another operation or another input is another
// entry; a damaged entry is derived again and rewritten.
TEST(MeshCache, StoresOnceReadsTheSameBytesAndRederivesDamage) {
  msk::test::ScratchDir dir;
  const std::string folder = dir.file("cache");
  const msk::TriangleMesh sphere = msk::makeIcosphere(10.0, 2), other = msk::makeIcosphere(11.0, 2);
  Counted derive;
  const auto fromSphere = [&] { return derive(sphere); };
  msk::MeshCache cache(folder);
  const msk::TriangleMesh first = cache.get("op 1", sphere, fromSphere);
  EXPECT_EQ(derive.calls, 1);
  EXPECT_EQ(cache.misses(), 1);

  msk::MeshCache again(folder);  // another run
  const msk::TriangleMesh second = again.get("op 1", sphere, fromSphere);
  EXPECT_EQ(derive.calls, 1) << "read from the folder";
  EXPECT_EQ(again.hits(), 1);
  EXPECT_TRUE(sameBytes(first, second));

  again.get("op 2", sphere, fromSphere);
  again.get("op 1", other, [&] { return derive(other); });
  EXPECT_EQ(derive.calls, 3) << "another operation and another input are other entries";
  ASSERT_EQ(std::distance(fs::directory_iterator(folder), fs::directory_iterator()), 3);

  // Damage every entry: one byte of the body changed in one, another cut short, the third emptied.
  int k = 0;
  for (const auto& e : fs::directory_iterator(folder)) {
    std::string bytes = msk::test::readBytes(e.path().string());
    if (k == 0) bytes[bytes.size() / 2] ^= 1;
    if (k == 1) bytes.resize(bytes.size() - 10);
    if (k == 2) bytes.clear();
    msk::test::writeBytes(e.path().string(), bytes);
    ++k;
  }
  msk::MeshCache damaged(folder);
  const msk::TriangleMesh third = damaged.get("op 1", sphere, fromSphere);
  damaged.get("op 2", sphere, fromSphere);
  damaged.get("op 1", other, [&] { return derive(other); });
  EXPECT_EQ(derive.calls, 6) << "every damaged entry derived again";
  EXPECT_EQ(damaged.misses(), 3);
  EXPECT_TRUE(sameBytes(first, third));
  msk::MeshCache repaired(folder);
  repaired.get("op 1", sphere, fromSphere);
  EXPECT_EQ(repaired.hits(), 1) << "and rewritten";
  EXPECT_EQ(derive.calls, 6);
}

// Entries are keyed by the program's build ID (hexadecimal; every toolchain this project builds with writes one).
TEST(MeshCache, ProgramBuildIdIsHexadecimal) {
  const std::string id = msk::programBuildId();
  ASSERT_FALSE(id.empty());
  EXPECT_EQ(id.size() % 2, 0u);
  for (char c : id) EXPECT_TRUE(std::isxdigit(static_cast<unsigned char>(c))) << id;
}
