#include "msk/imaging/tet_mesh_io.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/test/files.h"

namespace {

using msk::MeshSpace;
using msk::TetMesh;
using msk::test::ScratchDir;

/// A 2×3×2 block of 4 mm cubes away from the origin, each cube cut into six tets along its main diagonal
/// (positively oriented), nodes moved by a small deterministic amount so no coordinate is round.
TetMesh block() {
  const int nx = 2, ny = 3, nz = 2;
  TetMesh m;
  m.nodes.resize((nx + 1) * (ny + 1) * (nz + 1), 3);
  auto node = [&](int i, int j, int k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i)
        m.nodes.row(node(i, j, k)) << 17.25 + 4 * i + 0.1 * std::sin(i + 2 * j + 3 * k),
            -42.5 + 4 * j + 0.1 * std::cos(3 * i + j), 101.125 + 4 * k + 0.05 * (i * j % 3);
  // The six paths from corner (0,0,0) to (1,1,1) along the axes, one tet each.
  const int axisOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  std::vector<Eigen::Vector4i> tets;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& order : axisOrders) {
          int c[3] = {i, j, k};
          Eigen::Vector4i t;
          t[0] = node(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[order[s]];
            t[s + 1] = node(c[0], c[1], c[2]);
          }
          if (msk::signedTetVolume(m.nodes.row(t[0]), m.nodes.row(t[1]), m.nodes.row(t[2]), m.nodes.row(t[3])) < 0)
            std::swap(t[2], t[3]);
          tets.push_back(t);
        }
  m.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (size_t t = 0; t < tets.size(); ++t) m.tets.row(static_cast<Eigen::Index>(t)) = tets[t].transpose();
  return m;
}

/// Expects `f()` to throw one IoError naming `path` whose message holds `phrase`.
template <class F>
void expectIoError(F f, const std::string& path, const std::string& phrase) {
  try {
    f();
    ADD_FAILURE() << "no error; wanted: " << phrase;
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0u) << e.what();  // the message starts with the file
    EXPECT_NE(std::string(e.what()).find(phrase), std::string::npos) << "wanted '" << phrase << "' in: " << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
  }
}

/// An ASCII .vtu holding one tet (or one triangle if `triangle`), optionally tagged with field data SPACE = `space`.
std::string handWritten(bool triangle, const std::string& space = "") {
  std::string field;
  if (!space.empty()) {
    std::string codes;
    for (char ch : space) codes += std::to_string(static_cast<int>(ch)) + " ";
    field = "<FieldData><Array type=\"String\" Name=\"SPACE\" NumberOfTuples=\"1\" format=\"ascii\">" + codes +
            "0</Array></FieldData>";
  }
  return std::string(
             "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" "
             "byte_order=\"LittleEndian\">\n<UnstructuredGrid>") +
         field + "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n" +
         "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
         "1 2 3  11 2 3  1 12 3  1 2 13</DataArray></Points>\n"
         "<Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">" +
         (triangle ? "0 1 2" : "0 1 2 3") +
         "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">" + (triangle ? "3" : "4") +
         "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">" + (triangle ? "5" : "10") +
         "</DataArray></Cells>\n</Piece></UnstructuredGrid></VTKFile>\n";
}

}  // namespace

TEST(TetMeshIo, RoundTripInEitherSpace) {
  const TetMesh m = block();
  ASSERT_EQ(msk::tetMeshProblem(m), "");
  ScratchDir dir;
  for (MeshSpace space : {MeshSpace::LPS, MeshSpace::RAS}) {
    SCOPED_TRACE(msk::meshSpaceName(space));
    const std::string path = dir.file(std::string("block_") + msk::meshSpaceName(space) + ".vtu");
    msk::writeTetMesh(path, m, space);
    MeshSpace found = space == MeshSpace::LPS ? MeshSpace::RAS : MeshSpace::LPS;
    const TetMesh back = msk::readTetMesh(path, &found);
    EXPECT_EQ(found, space);
    ASSERT_EQ(back.nodeCount(), m.nodeCount());
    ASSERT_EQ(back.tetCount(), m.tetCount());
    EXPECT_LE((back.nodes - m.nodes).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_TRUE(back.tets == m.tets);
    EXPECT_NEAR(msk::totalVolume(back), msk::totalVolume(m), 1e-9);
    // The tag is VTK field data, visible to any VTK reader (ParaView, 3D Slicer).
    EXPECT_NE(msk::test::readBytes(path).find("Name=\"SPACE\""), std::string::npos);
  }
  // The default is LPS.
  msk::writeTetMesh(dir.file("default.vtu"), m);
  MeshSpace found = MeshSpace::RAS;
  msk::readTetMesh(dir.file("default.vtu"), &found);
  EXPECT_EQ(found, MeshSpace::LPS);
}

TEST(TetMeshIo, TagIsHonouredAndUntaggedFilesAreLps) {
  ScratchDir dir;
  const std::string untagged = dir.file("untagged.vtu"), ras = dir.file("ras.vtu"), lps = dir.file("lps.vtu");
  msk::test::writeBytes(untagged, handWritten(false));
  msk::test::writeBytes(ras, handWritten(false, "RAS"));
  msk::test::writeBytes(lps, handWritten(false, "LPS"));
  MeshSpace found = MeshSpace::RAS;
  const TetMesh u = msk::readTetMesh(untagged, &found);
  EXPECT_EQ(found, MeshSpace::LPS);
  ASSERT_EQ(u.nodeCount(), 4);
  EXPECT_EQ(u.nodes.row(1), Eigen::RowVector3d(-11, -2, 3));  // LPS (11, 2, 3) is RAS (−11, −2, 3)
  const TetMesh r = msk::readTetMesh(ras, &found);
  EXPECT_EQ(found, MeshSpace::RAS);
  EXPECT_EQ(r.nodes.row(1), Eigen::RowVector3d(11, 2, 3));
  const TetMesh l = msk::readTetMesh(lps, &found);
  EXPECT_EQ(found, MeshSpace::LPS);
  EXPECT_TRUE(l.nodes == u.nodes);
  // The flip has determinant +1: the tet read from LPS is still positively oriented.
  EXPECT_GT(msk::totalVolume(u), 0);
  EXPECT_NEAR(msk::totalVolume(u), 1000.0 / 6, 1e-9);
}

TEST(TetMeshIo, BadFilesGiveOneErrorNamingTheFile) {
  ScratchDir dir;
  const std::string good = dir.file("good.vtu");
  msk::writeTetMesh(good, block());
  const std::string bytes = msk::test::readBytes(good);

  expectIoError([&] { msk::readTetMesh(dir.file("absent.vtu")); }, dir.file("absent.vtu"), "does not exist");
  expectIoError([&] { msk::readTetMesh(dir.path()); }, dir.path(), "");
  const std::string wrongExt = dir.file("mesh.vtk");
  msk::test::writeBytes(wrongExt, bytes);
  expectIoError([&] { msk::readTetMesh(wrongExt); }, wrongExt, "unsupported tetrahedral mesh format '.vtk'");

  const std::string truncated = dir.file("truncated.vtu");
  msk::test::writeBytes(truncated, bytes.substr(0, bytes.size() / 2));
  expectIoError([&] { msk::readTetMesh(truncated); }, truncated, "cannot read");
  const std::string garbage = dir.file("garbage.vtu");
  msk::test::writeBytes(garbage, "this is not XML at all\n\x01\x02\x03");
  expectIoError([&] { msk::readTetMesh(garbage); }, garbage, "cannot read");
  const std::string empty = dir.file("empty.vtu");
  msk::test::writeBytes(empty, "");
  expectIoError([&] { msk::readTetMesh(empty); }, empty, "cannot read");
  const std::string triangle = dir.file("triangle.vtu");
  msk::test::writeBytes(triangle, handWritten(true));
  expectIoError([&] { msk::readTetMesh(triangle); }, triangle, "cell 0 is not a tetrahedron (VTK cell type 5)");
  const std::string badTag = dir.file("badtag.vtu");
  msk::test::writeBytes(badTag, handWritten(false, "XYZ"));
  expectIoError([&] { msk::readTetMesh(badTag); }, badTag, "unknown coordinate space 'XYZ'");
  // A tet whose orientation is flipped in the file (nodes 2 and 3 swapped) is not a valid tet mesh.
  std::string inverted = handWritten(false, "RAS");
  inverted.replace(inverted.find("0 1 2 3"), 7, "0 1 3 2");
  const std::string invertedPath = dir.file("inverted.vtu");
  msk::test::writeBytes(invertedPath, inverted);
  expectIoError([&] { msk::readTetMesh(invertedPath); }, invertedPath, "not a valid tetrahedral mesh");
}

TEST(TetMeshIo, FailedWritesLeaveNothingBehind) {
  ScratchDir dir;
  TetMesh bad = block();
  std::swap(bad.tets(0, 2), bad.tets(0, 3));  // one inverted tet
  const std::string path = dir.file("bad.vtu");
  expectIoError([&] { msk::writeTetMesh(path, bad); }, path, "refusing to write an invalid tetrahedral mesh");
  TetMesh outOfRange = block();
  outOfRange.tets(3, 1) = outOfRange.nodeCount();
  expectIoError([&] { msk::writeTetMesh(path, outOfRange); }, path, "refusing to write");
  expectIoError([&] { msk::writeTetMesh(dir.file("mesh.vtp"), block()); }, dir.file("mesh.vtp"), "use .vtu");
  EXPECT_TRUE(dir.list().empty());  // no file, no temporary left over

  // A failed write never replaces an existing file.
  msk::writeTetMesh(path, block());
  const std::string before = msk::test::readBytes(path);
  expectIoError([&] { msk::writeTetMesh(path, bad); }, path, "refusing to write");
  EXPECT_EQ(msk::test::readBytes(path), before);
  EXPECT_EQ(dir.list().size(), 1u);
  // A folder that does not exist.
  const std::string nowhere = dir.file("no/such/folder/m.vtu");
  EXPECT_THROW(msk::writeTetMesh(nowhere, block()), msk::IoError);
  EXPECT_EQ(dir.list().size(), 1u);
}
