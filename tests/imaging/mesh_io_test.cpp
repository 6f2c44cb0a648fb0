#include "msk/imaging/mesh_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/test/files.h"

namespace {

using msk::MeshSpace;
using msk::TriangleMesh;

/// An off-centre icosphere with two point arrays.
TriangleMesh sampleMesh() {
  TriangleMesh m = msk::makeIcosphere(15.0, 3, {12.5, -30.25, 47.125});
  Eigen::VectorXd thickness(m.vertexCount()), region(m.vertexCount());
  for (int i = 0; i < m.vertexCount(); ++i) {
    thickness[i] = 0.1 * m.vertices(i, 0) + 0.37 * m.vertices(i, 1) - 0.013 * m.vertices(i, 2);
    region[i] = i % 7;
  }
  m.pointData["thickness"] = thickness;
  m.pointData["region"] = region;
  return m;
}

/// Largest distance from a vertex of `a` to the nearest vertex of `b` (order-independent).
double nearestMismatch(const TriangleMesh& a, const TriangleMesh& b) {
  double worst = 0;
  for (int i = 0; i < a.vertexCount(); ++i) {
    double best = INFINITY;
    for (int j = 0; j < b.vertexCount(); ++j) best = std::min(best, (a.vertices.row(i) - b.vertices.row(j)).norm());
    worst = std::max(worst, best);
  }
  return worst;
}

/// A legacy VTK ASCII polydata file, written by hand (no VTK involved).
std::string legacyText(const TriangleMesh& m, const std::string& title) {
  std::ostringstream s;
  s.precision(17);
  s << "# vtk DataFile Version 3.0\n"
    << title << "\nASCII\nDATASET POLYDATA\nPOINTS " << m.vertexCount() << " double\n";
  for (int i = 0; i < m.vertexCount(); ++i)
    s << m.vertices(i, 0) << ' ' << m.vertices(i, 1) << ' ' << m.vertices(i, 2) << '\n';
  s << "POLYGONS " << m.faceCount() << ' ' << 4 * m.faceCount() << '\n';
  for (int f = 0; f < m.faceCount(); ++f)
    s << "3 " << m.faces(f, 0) << ' ' << m.faces(f, 1) << ' ' << m.faces(f, 2) << '\n';
  return s.str();
}

/// A tetrahedron with outward faces: (0,0,0), (10,0,0), (0,10,0), (0,0,10).
TriangleMesh tetrahedron() {
  TriangleMesh m;
  m.vertices.resize(4, 3);
  m.vertices << 0, 0, 0, 10, 0, 0, 0, 10, 0, 0, 0, 10;
  m.faces.resize(4, 3);
  m.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return m;
}

/// The coordinates stored in a binary legacy VTK file ("POINTS n double", big-endian).
std::vector<double> legacyBinaryPoints(const std::string& bytes, int n) {
  const std::string key = "POINTS " + std::to_string(n) + " double\n";
  const size_t at = bytes.find(key);
  if (at == std::string::npos || bytes.size() < at + key.size() + 24 * static_cast<size_t>(n)) return {};
  std::vector<double> out(static_cast<size_t>(3 * n));
  const unsigned char* p = reinterpret_cast<const unsigned char*>(bytes.data() + at + key.size());
  for (size_t i = 0; i < out.size(); ++i) {
    uint64_t u = 0;
    for (int b = 0; b < 8; ++b) u = (u << 8) | p[8 * i + static_cast<size_t>(b)];
    std::memcpy(&out[i], &u, sizeof u);
  }
  return out;
}

/// Expects `f` to throw msk::IoError naming `path`.
template <typename F>
void expectIoError(F&& f, const std::string& path, const std::string& fragment = "") {
  try {
    f();
    ADD_FAILURE() << "no exception for " << path;
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    if (!fragment.empty()) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  }
}

struct RoundTripCase {
  std::string ext;
  MeshSpace space;
};

class MeshIoRoundTrip : public ::testing::TestWithParam<RoundTripCase> {};

TEST_P(MeshIoRoundTrip, KeepsGeometryOrientationSpaceAndPointData) {
  const auto& [ext, space] = GetParam();
  msk::test::ScratchDir dir;
  const std::string path = dir.file("sphere" + ext);
  const TriangleMesh in = sampleMesh();
  msk::writeMesh(path, in, space);
  ASSERT_EQ(dir.list(), std::vector<std::string>{"sphere" + ext});  // no temporary file left behind

  MeshSpace found = space == MeshSpace::LPS ? MeshSpace::RAS : MeshSpace::LPS;
  const TriangleMesh out = msk::readMesh(path, &found);
  EXPECT_EQ(found, space);
  EXPECT_EQ(msk::closedMeshProblem(out), "");
  ASSERT_EQ(out.vertexCount(), in.vertexCount());
  ASSERT_EQ(out.faceCount(), in.faceCount());
  const bool float32 = ext == ".stl";
  const double tol = ext == ".stl" ? 1e-4 : 1e-5;
  if (ext == ".stl") {
    EXPECT_LT(nearestMismatch(in, out), tol);  // STL has no shared vertices: merged in face order
    EXPECT_LT(nearestMismatch(out, in), tol);
  } else {
    EXPECT_LT((out.vertices - in.vertices).cwiseAbs().maxCoeff(), tol);
    EXPECT_EQ(out.faces, in.faces);
  }
  const double v0 = msk::enclosedVolume(in), v1 = msk::enclosedVolume(out);
  EXPECT_GT(v1, 0);
  EXPECT_NEAR(v1, v0, (float32 ? 1e-5 : 1e-9) * v0);
  if (ext == ".vtk" || ext == ".vtp" || ext == ".ply") {
    ASSERT_EQ(out.pointData.size(), in.pointData.size());
    for (const auto& [name, values] : in.pointData) {
      ASSERT_TRUE(out.pointData.count(name)) << name;
      EXPECT_LT((out.pointData.at(name) - values).cwiseAbs().maxCoeff(), 1e-12) << name;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(MeshIo, MeshIoRoundTrip,
                         ::testing::Values(RoundTripCase{".vtk", MeshSpace::LPS}, RoundTripCase{".vtk", MeshSpace::RAS},
                                           RoundTripCase{".vtp", MeshSpace::LPS}, RoundTripCase{".vtp", MeshSpace::RAS},
                                           RoundTripCase{".stl", MeshSpace::LPS}, RoundTripCase{".stl", MeshSpace::RAS},
                                           RoundTripCase{".obj", MeshSpace::LPS}, RoundTripCase{".obj", MeshSpace::RAS},
                                           RoundTripCase{".ply", MeshSpace::LPS},
                                           RoundTripCase{".ply", MeshSpace::RAS}),
                         [](const ::testing::TestParamInfo<RoundTripCase>& info) {
                           return info.param.ext.substr(1) + "_" + msk::meshSpaceName(info.param.space);
                         });

TEST(MeshIo, LegacyVtkIsVersion42TaggedAndStoresLpsCoordinates) {
  msk::test::ScratchDir dir;
  const TriangleMesh ras = sampleMesh();
  for (MeshSpace space : {MeshSpace::LPS, MeshSpace::RAS}) {
    const std::string path = dir.file(std::string("m_") + msk::meshSpaceName(space) + ".vtk");
    msk::writeMesh(path, ras, space);
    const std::string bytes = msk::test::readBytes(path);
    ASSERT_EQ(bytes.rfind("# vtk DataFile Version 4.2\n", 0), 0u) << bytes.substr(0, 40);
    const std::string title = bytes.substr(27, bytes.find('\n', 27) - 27);
    EXPECT_LE(title.size(), 255u);
    EXPECT_NE(title.find(std::string("SPACE=") + msk::meshSpaceName(space)), std::string::npos) << title;
    const std::vector<double> raw = legacyBinaryPoints(bytes, ras.vertexCount());
    ASSERT_EQ(raw.size(), static_cast<size_t>(3 * ras.vertexCount()));
    const double s = space == MeshSpace::LPS ? -1.0 : 1.0;
    for (int i = 0; i < ras.vertexCount(); ++i) {
      EXPECT_EQ(raw[3 * i + 0], s * ras.vertices(i, 0));
      EXPECT_EQ(raw[3 * i + 1], s * ras.vertices(i, 1));
      EXPECT_EQ(raw[3 * i + 2], ras.vertices(i, 2));
    }
  }
}

TEST(MeshIo, OtherFormatsCarryTheSpaceTag) {
  msk::test::ScratchDir dir;
  const TriangleMesh ras = sampleMesh();
  msk::writeMesh(dir.file("a.vtp"), ras, MeshSpace::LPS);
  msk::writeMesh(dir.file("a.stl"), ras, MeshSpace::LPS);
  msk::writeMesh(dir.file("a.obj"), ras, MeshSpace::LPS);
  msk::writeMesh(dir.file("a.ply"), ras, MeshSpace::RAS);
  const std::string vtp = msk::test::readBytes(dir.file("a.vtp"));
  EXPECT_NE(vtp.find("<FieldData>"), std::string::npos);
  EXPECT_NE(vtp.find("Name=\"SPACE\""), std::string::npos);
  const std::string stl = msk::test::readBytes(dir.file("a.stl"));
  ASSERT_GE(stl.size(), 84u);
  EXPECT_EQ(stl.size(), 84u + 50u * static_cast<size_t>(ras.faceCount()));  // binary STL
  EXPECT_NE(stl.substr(0, 80).find("SPACE=LPS"), std::string::npos);
  const std::string obj = msk::test::readBytes(dir.file("a.obj"));
  EXPECT_NE(obj.find("# SPACE=LPS\n"), std::string::npos);
  // OBJ is ASCII: its first vertex is the RAS vertex with x and y negated.
  std::istringstream first(obj.substr(obj.find("\nv ") + 3));
  double x, y, z;
  first >> x >> y >> z;
  EXPECT_EQ(x, -ras.vertices(0, 0));
  EXPECT_EQ(y, -ras.vertices(0, 1));
  EXPECT_EQ(z, ras.vertices(0, 2));
  const std::string ply = msk::test::readBytes(dir.file("a.ply"));
  const std::string plyHeader = ply.substr(0, ply.find("end_header"));
  EXPECT_EQ(ply.rfind("ply\n", 0), 0u);
  EXPECT_NE(plyHeader.find("comment SPACE=RAS\n"), std::string::npos) << plyHeader;
}

TEST(MeshIo, UntaggedLegacyFileIsReadAsLps) {
  msk::test::ScratchDir dir;
  const std::string path = dir.file("tet.vtk");
  msk::test::writeBytes(path, legacyText(tetrahedron(), "written by hand"));
  MeshSpace found = MeshSpace::RAS;
  const TriangleMesh m = msk::readMesh(path, &found);
  EXPECT_EQ(found, MeshSpace::LPS);
  ASSERT_EQ(m.vertexCount(), 4);
  EXPECT_EQ(m.vertices.row(1), Eigen::RowVector3d(-10, 0, 0));
  EXPECT_EQ(m.vertices.row(2), Eigen::RowVector3d(0, -10, 0));
  EXPECT_EQ(m.vertices.row(3), Eigen::RowVector3d(0, 0, 10));
  EXPECT_NEAR(msk::enclosedVolume(m), 1000.0 / 6.0, 1e-9);  // orientation kept: still outward

  // A Slicer-style title token selects RAS; an unknown one is an error, not a silent default.
  msk::test::writeBytes(path, legacyText(tetrahedron(), "vtk output SPACE=RAS"));
  const TriangleMesh r = msk::readMesh(path, &found);
  EXPECT_EQ(found, MeshSpace::RAS);
  EXPECT_EQ(r.vertices.row(1), Eigen::RowVector3d(10, 0, 0));
  msk::test::writeBytes(path, legacyText(tetrahedron(), "SPACE=XYZ"));
  expectIoError([&] { msk::readMesh(path); }, path, "SPACE=XYZ");
}

TEST(MeshIo, LegacyVersion51WithAttributesIsRead) {
  msk::test::ScratchDir dir;
  const std::string path = dir.file("tet51.vtk");
  msk::test::writeBytes(path,
                        "# vtk DataFile Version 5.1\n"
                        "written by hand SPACE=RAS\n"
                        "ASCII\n"
                        "DATASET POLYDATA\n"
                        "POINTS 5 float\n"
                        "0 0 0 10 0 0 0 10 0 0 0 10 99 99 99\n"
                        "VERTICES 2 1\n"
                        "OFFSETS vtktypeint64\n0 1\n"
                        "CONNECTIVITY vtktypeint64\n4\n"
                        "POLYGONS 5 12\n"
                        "OFFSETS vtktypeint64\n0 3 6 9 12\n"
                        "CONNECTIVITY vtktypeint64\n0 2 1 0 1 3 0 3 2 1 2 3\n"
                        "POINT_DATA 5\n"
                        "SCALARS wall%20thickness float 1\nLOOKUP_TABLE default\n1.5 2.5 3.5 4.5 5.5\n"
                        "NORMALS Normals float\n0 0 1 0 0 1 0 0 1 0 0 1 0 0 1\n"
                        "FIELD FieldData 2\nlabel 1 5 int\n7 8 9 10 11\npair 2 5 float\n0 0 1 1 2 2 3 3 4 4\n"
                        "CELL_DATA 5\n"
                        "SCALARS region int 1\nLOOKUP_TABLE default\n1 2 3 4 5\n");
  MeshSpace found = MeshSpace::LPS;
  const TriangleMesh m = msk::readMesh(path, &found);
  EXPECT_EQ(found, MeshSpace::RAS);
  EXPECT_EQ(m.vertexCount(), 4);  // the free-standing vertex is dropped
  EXPECT_EQ(m.faceCount(), 4);
  EXPECT_NEAR(msk::enclosedVolume(m), 1000.0 / 6.0, 1e-9);
  ASSERT_EQ(m.pointData.size(), 2u);  // 1-component point arrays only
  ASSERT_TRUE(m.pointData.count("wall thickness"));
  ASSERT_TRUE(m.pointData.count("label"));
  EXPECT_EQ(m.pointData.at("wall thickness"), Eigen::Vector4d(1.5, 2.5, 3.5, 4.5));
  EXPECT_EQ(m.pointData.at("label"), Eigen::Vector4d(7, 8, 9, 10));
}

TEST(MeshIo, TruncatedFilesOfEveryFormatAreIoErrors) {
  msk::test::ScratchDir dir;
  for (const std::string ext : {".vtk", ".vtp", ".stl", ".obj", ".ply"}) {
    SCOPED_TRACE(ext);
    const std::string good = dir.file("good" + ext);
    msk::writeMesh(good, sampleMesh());
    const std::string bytes = msk::test::readBytes(good);
    // Cut inside the data (the last cut drops 100 bytes: VTP's closing XML tags alone are not missed by VTK).
    const size_t n = bytes.size();
    for (size_t keep : {n / 20, n * 3 / 10, n / 2, n * 4 / 5, n * 19 / 20, n - 100}) {
      SCOPED_TRACE(keep);
      const std::string cut = dir.file("cut" + ext);
      msk::test::writeBytes(cut, bytes.substr(0, keep));
      expectIoError([&] { msk::readMesh(cut); }, cut);
    }
  }
}

TEST(MeshIo, AsciiStlWithSolidNameTagIsMergedAndClosed) {
  msk::test::ScratchDir dir;
  const std::string path = dir.file("tet.stl");
  const TriangleMesh t = tetrahedron();
  std::ostringstream s;
  s << "solid tet SPACE=RAS\n";
  for (int f = 0; f < t.faceCount(); ++f) {
    s << " facet normal 0 0 0\n  outer loop\n";
    for (int c = 0; c < 3; ++c)
      s << "   vertex " << t.vertices(t.faces(f, c), 0) << ' ' << t.vertices(t.faces(f, c), 1) << ' '
        << t.vertices(t.faces(f, c), 2) << '\n';
    s << "  endloop\n endfacet\n";
  }
  s << "endsolid tet\n";
  msk::test::writeBytes(path, s.str());
  MeshSpace found = MeshSpace::LPS;
  const TriangleMesh m = msk::readMesh(path, &found);
  EXPECT_EQ(found, MeshSpace::RAS);
  EXPECT_EQ(m.vertexCount(), 4);
  EXPECT_EQ(m.faceCount(), 4);
  EXPECT_NEAR(msk::enclosedVolume(m), 1000.0 / 6.0, 1e-9);
}

TEST(MeshIo, MissingGarbageAndUnsupportedFilesAreIoErrors) {
  msk::test::ScratchDir dir;
  expectIoError([&] { msk::readMesh(dir.file("missing.vtk")); }, dir.file("missing.vtk"), "does not exist");
  std::mt19937 rng(7);
  std::string garbage(3000, '\0');
  for (char& c : garbage) c = static_cast<char>(rng() & 0xff);
  for (const std::string ext : {".vtk", ".vtp", ".stl", ".obj", ".ply"}) {
    SCOPED_TRACE(ext);
    const std::string path = dir.file("garbage" + ext);
    msk::test::writeBytes(path, garbage);
    expectIoError([&] { msk::readMesh(path); }, path);
    msk::test::writeBytes(path, "");
    expectIoError([&] { msk::readMesh(path); }, path);
  }
  const std::string off = dir.file("mesh.off");
  msk::test::writeBytes(off, "OFF\n");
  expectIoError([&] { msk::readMesh(off); }, off, "unsupported");
  expectIoError([&] { msk::writeMesh(dir.file("out.off"), sampleMesh()); }, dir.file("out.off"), "unsupported");
  EXPECT_FALSE(msk::isMeshFile(off));
  EXPECT_TRUE(msk::isMeshFile("a/b/Femur.VTK"));
  EXPECT_TRUE(msk::isMeshFile("x.vtp"));
  EXPECT_TRUE(msk::isMeshFile("x.stl"));
  EXPECT_TRUE(msk::isMeshFile("x.obj"));
  EXPECT_TRUE(msk::isMeshFile("x.ply"));
  EXPECT_FALSE(msk::isMeshFile("x.nii.gz"));
}

TEST(MeshIo, TruncatedEmptyAndNonFiniteFilesAreIoErrors) {
  msk::test::ScratchDir dir;
  const std::string good = dir.file("good.vtk");
  msk::writeMesh(good, sampleMesh());
  const std::string bytes = msk::test::readBytes(good);
  const std::string cut = dir.file("cut.vtk");
  msk::test::writeBytes(cut, bytes.substr(0, bytes.size() / 2));
  expectIoError([&] { msk::readMesh(cut); }, cut);

  const std::string empty = dir.file("empty.vtk");
  msk::test::writeBytes(empty, "# vtk DataFile Version 3.0\nempty\nASCII\nDATASET POLYDATA\nPOINTS 0 float\n");
  expectIoError([&] { msk::readMesh(empty); }, empty);

  const std::string nan = dir.file("nan.vtk");
  std::string text = legacyText(tetrahedron(), "nan");
  text.replace(text.find("\n10 0 0\n"), 8, "\nnan 0 0\n");
  msk::test::writeBytes(nan, text);
  expectIoError([&] { msk::readMesh(nan); }, nan);
}

/// Coordinates, offsets and indices declared as strings are not numbers: the reader says so (a string array
/// is otherwise skipped, leaving nothing to read the vertices or cells from).
TEST(MeshIo, NumericArraysDeclaredAsStringsAreIoErrors) {
  msk::test::ScratchDir dir;
  const std::string points = dir.file("points.vtk");
  msk::test::writeBytes(points,
                        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 string\n"
                        "a\nb\nc\nd\ne\nf\ng\nh\ni\nPOLYGONS 1 4\n3 0 1 2\n");
  expectIoError([&] { msk::readMesh(points); }, points, "POINTS of type string");

  const std::string offsets = dir.file("offsets.vtk");
  msk::test::writeBytes(offsets,
                        "# vtk DataFile Version 5.1\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n"
                        "0 0 0 1 0 0 0 1 0\nPOLYGONS 2 3\nOFFSETS string\na\nb\nCONNECTIVITY vtktypeint64\n0 1 2\n");
  expectIoError([&] { msk::readMesh(offsets); }, offsets, "OFFSETS of type string");

  const std::string connectivity = dir.file("connectivity.vtk");
  msk::test::writeBytes(connectivity,
                        "# vtk DataFile Version 5.1\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n"
                        "0 0 0 1 0 0 0 1 0\nPOLYGONS 2 3\nOFFSETS vtktypeint64\n0 3\nCONNECTIVITY string\na\nb\nc\n");
  expectIoError([&] { msk::readMesh(connectivity); }, connectivity, "CONNECTIVITY of type string");
}

/// An icosphere of radius 10 mm without the faces above z = 5 mm: open by a hole far too large to fill.
TriangleMesh cutSphere() {
  const TriangleMesh sphere = msk::makeIcosphere(10.0, 2);
  std::vector<int> kept;
  for (int f = 0; f < sphere.faceCount(); ++f) {
    double z = 0;
    for (int k = 0; k < 3; ++k) z += sphere.vertices(sphere.faces(f, k), 2) / 3;
    if (z <= 5) kept.push_back(f);
  }
  TriangleMesh open = sphere;
  open.faces.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t i = 0; i < kept.size(); ++i) open.faces.row(static_cast<Eigen::Index>(i)) = sphere.faces.row(kept[i]);
  return open;
}

TEST(MeshIo, OpenMeshIsRefusedOnReadAndWrite) {
  msk::test::ScratchDir dir;
  const TriangleMesh open = cutSphere();
  const std::string path = dir.file("open.vtk");
  msk::test::writeBytes(path, legacyText(open, "open SPACE=RAS"));
  expectIoError([&] { msk::readMesh(path); }, path, "not closed");

  for (const std::string ext : {".vtk", ".vtp", ".stl", ".obj", ".ply"}) {
    const std::string out = dir.file("refused" + ext);
    expectIoError([&] { msk::writeMesh(out, open); }, out, "not closed");
    expectIoError([&] { msk::writeMesh(out, TriangleMesh{}); }, out, "empty");
  }
  EXPECT_EQ(dir.list(), std::vector<std::string>{"open.vtk"});  // nothing written, no temporary left

  const std::string nowhere = dir.file("no/such/folder/m.vtk");
  expectIoError([&] { msk::writeMesh(nowhere, sampleMesh()); }, nowhere, "folder");
  EXPECT_EQ(dir.list(), std::vector<std::string>{"open.vtk"});
}

// What exporters commonly leave in a sound surface is mended on reading, with a warning naming the file and what was
// done: a vertex written once per face (an OBJ or a soup of triangles), a missing face or two (small holes).
TEST(MeshIo, DuplicateVerticesAndSmallHolesAreMendedWithAWarning) {
  msk::test::ScratchDir dir;
  std::vector<std::string> warnings;
  const auto old = msk::log::setSink([&](msk::LogLevel l, const std::string& m) {
    if (l == msk::LogLevel::Warn) warnings.push_back(m);
  });
  const TriangleMesh sphere = msk::makeIcosphere(10.0, 2);

  // Every face with vertices of its own (a triangle soup), as OBJ.
  std::ostringstream soup;
  for (int f = 0; f < sphere.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto v = sphere.vertices.row(sphere.faces(f, k));
      soup << "v " << v(0) << " " << v(1) << " " << v(2) << "\n";
    }
  for (int f = 0; f < sphere.faceCount(); ++f)
    soup << "f " << 3 * f + 1 << " " << 3 * f + 2 << " " << 3 * f + 3 << "\n";
  const std::string soupPath = dir.file("soup.obj");
  msk::test::writeBytes(soupPath, soup.str());
  const TriangleMesh merged = msk::readMesh(soupPath);
  EXPECT_EQ(merged.vertexCount(), sphere.vertexCount());
  EXPECT_EQ(merged.faceCount(), sphere.faceCount());
  EXPECT_NEAR(msk::enclosedVolume(merged), msk::enclosedVolume(sphere), 1e-6 * msk::enclosedVolume(sphere));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("soup.obj"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("merged " + std::to_string(3 * sphere.faceCount() - sphere.vertexCount()) +
                             " duplicate vertices"),
            std::string::npos)
      << warnings[0];

  // Two faces missing far apart: two holes of three edges, closed again without a new vertex.
  TriangleMesh holed = sampleMesh();
  const int faces = holed.faceCount();
  holed.faces.row(3) = holed.faces.row(faces - 1);
  holed.faces.row(faces / 2) = holed.faces.row(faces - 2);
  holed.faces.conservativeResize(faces - 2, 3);
  const std::string holedPath = dir.file("holed.vtk");
  msk::test::writeBytes(holedPath, legacyText(holed, "holed SPACE=RAS"));
  warnings.clear();
  const TriangleMesh filled = msk::readMesh(holedPath);
  EXPECT_EQ(filled.vertexCount(), holed.vertexCount());
  EXPECT_EQ(filled.faceCount(), faces);
  EXPECT_EQ(msk::closedMeshProblem(filled), "");
  EXPECT_GT(msk::enclosedVolume(filled), 0.0);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("filled 2 hole(s) of up to 3 edges"), std::string::npos) << warnings[0];
  msk::log::setSink(old);
}

TEST(MeshIo, FailedOverwriteKeepsTheOldFile) {
  msk::test::ScratchDir dir;
  const std::string path = dir.file("keep.ply");
  msk::writeMesh(path, sampleMesh());
  const std::string before = msk::test::readBytes(path);
  TriangleMesh bad = sampleMesh();
  bad.vertices(3, 1) = std::nan("");
  expectIoError([&] { msk::writeMesh(path, bad); }, path);
  EXPECT_EQ(msk::test::readBytes(path), before);
  EXPECT_EQ(dir.list(), std::vector<std::string>{"keep.ply"});
}

TEST(MeshIo, SpaceNamesParseAndPrint) {
  EXPECT_EQ(msk::parseMeshSpace("lps"), MeshSpace::LPS);
  EXPECT_EQ(msk::parseMeshSpace("RAS"), MeshSpace::RAS);
  EXPECT_EQ(msk::parseMeshSpace("Ras"), MeshSpace::RAS);
  EXPECT_STREQ(msk::meshSpaceName(MeshSpace::LPS), "LPS");
  EXPECT_STREQ(msk::meshSpaceName(MeshSpace::RAS), "RAS");
  EXPECT_THROW(msk::parseMeshSpace("xyz"), msk::ParameterError);
  EXPECT_THROW(msk::parseMeshSpace(""), msk::ParameterError);
}

}  // namespace

// A binary STL whose triangle count asks for more bytes than the file has is refused before anything is allocated:
// one error naming the file and the count (the shared crasher made VTK reserve about 7 GB).
TEST(MeshIo, BinaryStlCountBeyondTheFileIsRefused) {
  msk::test::ScratchDir dir;
  std::string bytes(84 + 50, '\0');
  bytes.replace(0, 5, "solid");  // binary despite the word: VTK reads it as binary (non-text bytes)
  const uint32_t n = 100000000;
  std::memcpy(&bytes[80], &n, 4);
  const std::string path = dir.file("huge.stl");
  msk::test::writeBytes(path, bytes);
  try {
    msk::readMesh(path);
    ADD_FAILURE() << "no error";
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(std::string(e.what()).find("100000000 triangles"), std::string::npos) << e.what();
  }
  const std::string data = msk::test::sharedData();
  if (data.empty()) return;
  const std::string crasher = data + "/../inputs/crashers/stl_fuzz_oom_malloc7GB_benign_in_release.stl";
  if (!std::ifstream(crasher)) return;
  EXPECT_THROW(msk::readMesh(crasher), msk::IoError);
}

// Files that crash VTK's XML reader or exhaust it (the shared crashers, and 200,000 nested elements, which overflow its
// stack) end with one error naming the file, quickly, in this process.
TEST(MeshIo, MalformedVtpFilesAreOneErrorNamingTheFile) {
  msk::test::ScratchDir dir;
  std::string nested = "<VTKFile type=\"PolyData\">";
  for (int i = 0; i < 200000; ++i) nested += "<a>";
  const std::string deep = dir.file("deep.vtp");
  msk::test::writeBytes(deep, nested);
  std::vector<std::string> files = {deep};
  const std::string data = msk::test::sharedData();
  const std::string crashers = data + "/../inputs/crashers/";
  for (const char* name : {"vtp_segv_ReadXMLInformation.vtp", "vtp_segv_ReadBlock.vtp",
                           "vtp_sigfpe_ReadCompressedData.vtp", "vtp_oom_12GB.vtp", "vtp_slow_over60s.vtp"})
    if (!data.empty() && std::ifstream(crashers + name)) files.push_back(crashers + name);
  for (const std::string& f : files) {
    try {
      msk::readMesh(f);
      ADD_FAILURE() << "no error for " << f;
    } catch (const msk::IoError& e) {
      EXPECT_EQ(e.file(), f);
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
}
