#include "msk/imaging/nifti_io.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/test/files.h"

namespace {

using msk::AffineSource;
using msk::DataType;
using msk::Grid;
using msk::IoError;
using msk::LogLevel;
using msk::NiftiInfo;
using msk::test::ScratchDir;

const DataType kAllTypes[] = {DataType::UInt8, DataType::Int8,   DataType::Int16,   DataType::UInt16,
                              DataType::Int32, DataType::UInt32, DataType::Float32, DataType::Float64};

/// An oblique, anisotropic grid with an improper (det −1) direction.
Grid obliqueGrid() {
  Grid g;
  g.dims = {5, 4, 3};
  g.spacing = {0.7, 1.3, 2.1};
  g.direction = Grid::rotationXYZ({20, -35, 50});
  g.direction.col(2) *= -1;
  g.origin = {-90.5, 20.25, 60.125};
  return g;
}

/// Largest distance (mm) between corresponding grid corners.
double cornerDistance(const Grid& a, const Grid& b) {
  double worst = 0;
  for (int c = 0; c < 8; ++c) {
    Eigen::Vector3d ijk((c & 1) ? a.dims[0] - 1 : 0, (c & 2) ? a.dims[1] - 1 : 0, (c & 4) ? a.dims[2] - 1 : 0);
    worst = std::max(worst, (a.toWorld(ijk) - b.toWorld(ijk)).norm());
  }
  return worst;
}

/// Values spanning each datatype's range, all exactly representable in it.
std::vector<double> valuesFor(DataType t) {
  switch (t) {
    case DataType::UInt8:
      return {0, 255, 1, 17, 128, 254};
    case DataType::Int8:
      return {-128, 127, 0, -1, 1, 42};
    case DataType::Int16:
      return {-32768, 32767, 0, -1, 1234, -1234};
    case DataType::UInt16:
      return {0, 65535, 1, 40000, 12345};
    case DataType::Int32:
      return {-2147483648.0, 2147483647.0, 0, -1, 123456789};
    case DataType::UInt32:
      return {0, 4294967295.0, 1, 3000000000.0};
    case DataType::Float32:
      return {std::numeric_limits<float>::lowest(),     std::numeric_limits<float>::max(), 0, -1.5, 3.25,
              std::numeric_limits<float>::denorm_min(), static_cast<double>(1e-20f)};
    case DataType::Float64:
      return {std::numeric_limits<double>::lowest(),    std::numeric_limits<double>::max(), 0, M_PI, -1e-300,
              std::numeric_limits<double>::denorm_min()};
  }
  return {};
}

msk::Volume<double> filled(const Grid& g, const std::vector<double>& values) {
  msk::Volume<double> v(g);
  for (size_t i = 0; i < v.data.size(); ++i) v.data[i] = values[i % values.size()];
  return v;
}

// --- raw header access (little-endian files as written on this machine) ---------------------

template <typename V>
V get(const std::string& b, size_t off) {
  V v;
  std::memcpy(&v, b.data() + off, sizeof(V));
  return v;
}
template <typename V>
void put(std::string& b, size_t off, V v) {
  std::memcpy(&b[off], &v, sizeof(V));
}

/// Byte offsets of the header fields the tests patch (NIfTI-1 / NIfTI-2 layouts).
struct Layout {
  size_t dim, datatype, bitpix, pixdim, sclSlope, sclInter, qformCode, sformCode, quatern, srow;
  bool v2;
};
const Layout kV1{40, 70, 72, 76, 112, 116, 252, 254, 256, 280, false};
const Layout kV2{16, 12, 14, 104, 176, 184, 344, 348, 352, 400, true};

void setReal(std::string& b, const Layout& L, size_t off, int idx, double v) {
  if (L.v2)
    put<double>(b, off + 8 * idx, v);
  else
    put<float>(b, off + 4 * idx, static_cast<float>(v));
}
double getReal(const std::string& b, const Layout& L, size_t off, int idx) {
  return L.v2 ? get<double>(b, off + 8 * idx) : get<float>(b, off + 4 * idx);
}
void setCode(std::string& b, const Layout& L, size_t off, int v) {
  if (L.v2)
    put<int32_t>(b, off, v);
  else
    put<int16_t>(b, off, static_cast<int16_t>(v));
}
void setDim(std::string& b, const Layout& L, int idx, int64_t v) {
  if (L.v2)
    put<int64_t>(b, L.dim + 8 * idx, v);
  else
    put<int16_t>(b, L.dim + 2 * idx, static_cast<int16_t>(v));
}
/// srow entry (row r = x,y,z; column c = 0..3).
void setSrow(std::string& b, const Layout& L, int r, int c, double v) { setReal(b, L, L.srow, 4 * r + c, v); }
double getSrow(const std::string& b, const Layout& L, int r, int c) { return getReal(b, L, L.srow, 4 * r + c); }

/// Rewrites an uncompressed file in place.
void patch(const std::string& path, const std::function<void(std::string&)>& edit) {
  std::string b = msk::test::readBytes(path);
  edit(b);
  msk::test::writeBytes(path, b);
}

/// A valid gzip stream made of stored (uncompressed) deflate blocks: lets tests gzip crafted bytes.
std::string gzipStored(const std::string& data) {
  uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char c : data) {
    crc ^= c;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  crc = ~crc;
  std::string out("\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xff", 10);
  size_t pos = 0;
  do {
    const size_t n = std::min<size_t>(65535, data.size() - pos);
    out += static_cast<char>(pos + n == data.size() ? 1 : 0);
    out += static_cast<char>(n & 0xff);
    out += static_cast<char>(n >> 8);
    out += static_cast<char>(~n & 0xff);
    out += static_cast<char>((~n >> 8) & 0xff);
    out.append(data, pos, n);
    pos += n;
  } while (pos < data.size());
  for (uint32_t v : {crc, static_cast<uint32_t>(data.size())})
    for (int k = 0; k < 4; ++k) out += static_cast<char>((v >> (8 * k)) & 0xff);
  return out;
}

/// Captures log messages (all levels) while alive.
class LogCapture {
 public:
  LogCapture() : level_(msk::log::level()) {
    old_ = msk::log::setSink([this](LogLevel l, const std::string& m) { messages.emplace_back(l, m); });
    msk::log::setLevel(LogLevel::Debug);
  }
  ~LogCapture() {
    msk::log::setSink(old_);
    msk::log::setLevel(level_);
  }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  /// True if a message at `level` contains every phrase.
  bool has(LogLevel level, std::initializer_list<const char*> phrases) const {
    for (const auto& [l, m] : messages) {
      if (l != level) continue;
      bool all = true;
      for (const char* p : phrases) all = all && m.find(p) != std::string::npos;
      if (all) return true;
    }
    return false;
  }
  size_t count(LogLevel level) const {
    return static_cast<size_t>(
        std::count_if(messages.begin(), messages.end(), [&](const auto& e) { return e.first == level; }));
  }
  std::vector<std::pair<LogLevel, std::string>> messages;

 private:
  msk::LogSink old_;
  LogLevel level_;
};

/// Runs f, expecting an IoError naming `path` whose text contains `phrase`; returns the message.
std::string expectIoError(const std::function<void()>& f, const std::string& path, const std::string& phrase) {
  try {
    f();
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find(phrase), std::string::npos) << "expected '" << phrase << "' in: " << what;
    return what;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected IoError, got: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected IoError containing '" << phrase << "', nothing thrown";
  return "";
}

/// Writes a small float32 oblique volume (values 0..n−1) as uncompressed NIfTI of the given version.
std::string writeSample(const ScratchDir& dir, const std::string& name, int version = 1,
                        DataType type = DataType::Float32) {
  msk::Volume<float> v(obliqueGrid());
  for (size_t i = 0; i < v.data.size(); ++i) v.data[i] = static_cast<float>(i);
  msk::NiftiWriteOptions o;
  o.version = version;
  const std::string path = dir.file(name);
  msk::writeNifti(path, v, type, o);
  return path;
}

}  // namespace

// =============================================================================================
// Round trips

TEST(NiftiRoundTrip, EveryDatatypeFormatAndVersionIsExact) {
  ScratchDir dir;
  LogCapture log;
  const Grid g = obliqueGrid();
  ASSERT_LT(g.direction.determinant(), 0);
  for (DataType t : kAllTypes) {
    const std::vector<double> values = valuesFor(t);
    const msk::Volume<double> vol = filled(g, values);
    for (const char* ext : {".nii", ".nii.gz"}) {
      for (int version : {1, 2}) {
        SCOPED_TRACE(std::string(msk::dataTypeName(t)) + ext + " v" + std::to_string(version));
        const std::string path = dir.file(std::string(msk::dataTypeName(t)) + "_v" + std::to_string(version) + ext);
        msk::NiftiWriteOptions o;
        o.version = version;
        o.description = "round trip";
        msk::writeNifti(path, vol, t, o);

        NiftiInfo info;
        const msk::Volume<double> back = msk::readNifti<double>(path, &info);
        ASSERT_EQ(back.data.size(), vol.data.size());
        for (size_t i = 0; i < vol.data.size(); ++i) ASSERT_EQ(back.data[i], vol.data[i]) << "voxel " << i;
        EXPECT_EQ(info.datatype, t);
        EXPECT_EQ(info.version, version);
        EXPECT_EQ(info.affineSource, AffineSource::Sform);
        EXPECT_EQ(info.sformCode, 1);
        EXPECT_EQ(info.qformCode, 1);
        EXPECT_FALSE(info.scaled);
        EXPECT_EQ(info.nonFiniteCount, 0u);
        EXPECT_EQ(info.minValue, *std::min_element(values.begin(), values.end()));
        EXPECT_EQ(info.maxValue, *std::max_element(values.begin(), values.end()));
        EXPECT_EQ(back.grid.dims, g.dims);
        EXPECT_LT(cornerDistance(back.grid, g), 1e-5);
        EXPECT_TRUE(back.grid.sameGeometry(g, 1e-5));
        EXPECT_LT((back.grid.direction - g.direction).cwiseAbs().maxCoeff(), 1e-6);
        // The qform written beside the sform describes the same grid (qfac = −1 here).
        EXPECT_LT((info.qform - info.sform).cwiseAbs().maxCoeff(), 1e-4);

        Grid hg;
        const NiftiInfo hi = msk::readNiftiHeader(path, &hg);
        EXPECT_EQ(hi.datatype, t);
        EXPECT_TRUE(hg.sameGeometry(back.grid, 0));
      }
    }
  }
  EXPECT_EQ(log.count(LogLevel::Warn), 0u) << "forms written together must agree";
  EXPECT_TRUE(log.has(LogLevel::Debug, {"orientation from the sform"}));
}

TEST(NiftiRoundTrip, NiftiTwoHasFullMagicAndFileLayout) {
  ScratchDir dir;
  const std::string p1 = writeSample(dir, "a.nii", 1), p2 = writeSample(dir, "b.nii", 2);
  const std::string b1 = msk::test::readBytes(p1), b2 = msk::test::readBytes(p2);
  const size_t voxels = obliqueGrid().voxelCount();
  EXPECT_EQ(b1.size(), 352 + 4 * voxels);
  EXPECT_EQ(b2.size(), 544 + 4 * voxels);
  EXPECT_EQ(get<int32_t>(b1, 0), 348);
  EXPECT_EQ(b1.substr(344, 4), std::string("n+1\0", 4));
  EXPECT_EQ(get<int32_t>(b2, 0), 540);
  EXPECT_EQ(b2.substr(4, 8), std::string("n+2\0\r\n\032\n", 8));
  EXPECT_EQ(get<uint8_t>(b1, 123) & 7, 2) << "xyzt_units = mm";
  EXPECT_EQ(get<int32_t>(b2, 500) & 7, 2) << "xyzt_units = mm";
  EXPECT_EQ(getReal(b1, kV1, kV1.pixdim, 0), -1.0) << "qfac of the improper direction";
}

TEST(NiftiRoundTrip, ReadsIntoNarrowTypesAndRejectsWhatDoesNotFit) {
  ScratchDir dir;
  msk::Volume<int16_t> v(obliqueGrid());
  for (size_t i = 0; i < v.data.size(); ++i) v.data[i] = static_cast<int16_t>(static_cast<int>(i) * 100 - 2000);
  const std::string path = dir.file("s.nii.gz");
  msk::writeNifti(path, v, DataType::Int16);
  const msk::Volume<int16_t> same = msk::readNifti<int16_t>(path);
  EXPECT_EQ(same.data, v.data);
  const msk::Volume<float> f = msk::readNifti<float>(path);
  for (size_t i = 0; i < v.data.size(); ++i) EXPECT_EQ(f.data[i], static_cast<float>(v.data[i]));
  const msk::LabelMap l = msk::readNifti<int32_t>(path);
  EXPECT_EQ(l.data[3], v.data[3]);
  expectIoError([&] { msk::readNifti<uint8_t>(path); }, path, "out of range for uint8");
}

TEST(NiftiRoundTrip, ReadsByteSwappedFiles) {
  ScratchDir dir;
  const std::string path = writeSample(dir, "le.nii", 1, DataType::Int16);
  const NiftiInfo le = msk::readNiftiHeader(path);
  // Turn it into a big-endian file: swap every numeric header field and every voxel.
  patch(path, [](std::string& b) {
    auto swapAt = [&b](size_t off, size_t n) { std::reverse(b.begin() + off, b.begin() + off + n); };
    swapAt(0, 4);                                             // sizeof_hdr
    swapAt(32, 4);                                            // extents
    swapAt(36, 2);                                            // session_error
    for (size_t o = 40; o < 56; o += 2) swapAt(o, 2);         // dim
    for (size_t o = 56; o < 68; o += 4) swapAt(o, 4);         // intent_p1..3
    for (size_t o = 68; o < 76; o += 2) swapAt(o, 2);         // intent_code, datatype, bitpix, slice_start
    for (size_t o = 76; o < 120; o += 4) swapAt(o, 4);        // pixdim, vox_offset, scl_slope, scl_inter
    swapAt(120, 2);                                           // slice_end
    for (size_t o = 124; o < 148; o += 4) swapAt(o, 4);       // cal_max .. glmin
    swapAt(252, 2);                                           // qform_code
    swapAt(254, 2);                                           // sform_code
    for (size_t o = 256; o < 328; o += 4) swapAt(o, 4);       // quatern, qoffset, srow
    for (size_t o = 352; o < b.size(); o += 2) swapAt(o, 2);  // int16 voxels
  });
  NiftiInfo info;
  const msk::Volume<int16_t> v = msk::readNifti<int16_t>(path, &info);
  for (size_t i = 0; i < v.data.size(); ++i) ASSERT_EQ(v.data[i], static_cast<int16_t>(i));
  EXPECT_EQ(info.affineSource, AffineSource::Sform);
  EXPECT_EQ(info.sform, le.sform);
  EXPECT_EQ(info.qform, le.qform);
  EXPECT_LT(cornerDistance(v.grid, obliqueGrid()), 1e-5);
}

// =============================================================================================
// Orientation

TEST(NiftiOrientation, SformOnlyIsUsedWithoutWarning) {
  ScratchDir dir;
  for (int version : {1, 2}) {
    const Layout& L = version == 2 ? kV2 : kV1;
    const std::string path = writeSample(dir, "s" + std::to_string(version) + ".nii", version);
    patch(path, [&](std::string& b) {
      setCode(b, L, L.qformCode, 0);
      setReal(b, L, L.quatern, 0, 0.7);  // garbage quaternion: must be ignored
    });
    LogCapture log;
    Grid g;
    const NiftiInfo info = msk::readNiftiHeader(path, &g);
    EXPECT_EQ(info.affineSource, AffineSource::Sform);
    EXPECT_EQ(info.qformCode, 0);
    EXPECT_LT(cornerDistance(g, obliqueGrid()), 1e-5);
    EXPECT_EQ(log.count(LogLevel::Warn), 0u);
    EXPECT_TRUE(log.has(LogLevel::Debug, {path.c_str(), "sform"}));
  }
}

TEST(NiftiOrientation, QformOnlyWithImproperDirectionIsUsed) {
  ScratchDir dir;
  for (int version : {1, 2}) {
    const Layout& L = version == 2 ? kV2 : kV1;
    const std::string path = dir.file("q" + std::to_string(version) + ".nii.gz");
    const std::string raw = writeSample(dir, "q" + std::to_string(version) + ".nii", version);
    patch(raw, [&](std::string& b) {
      EXPECT_EQ(getReal(b, L, L.pixdim, 0), -1.0) << "qfac";
      setCode(b, L, L.sformCode, 0);
      setSrow(b, L, 0, 0, 1000.0);  // garbage sform: must be ignored
    });
    msk::test::writeBytes(path, gzipStored(msk::test::readBytes(raw)));
    for (const std::string& p : {raw, path}) {
      LogCapture log;
      NiftiInfo info;
      const msk::Volume<float> v = msk::readNifti<float>(p, &info);
      EXPECT_EQ(info.affineSource, AffineSource::Qform);
      EXPECT_LT(v.grid.direction.determinant(), 0);
      EXPECT_LT(cornerDistance(v.grid, obliqueGrid()), 1e-4);
      EXPECT_EQ(v.data[7], 7.0f);
      EXPECT_EQ(log.count(LogLevel::Warn), 0u);
      EXPECT_TRUE(log.has(LogLevel::Debug, {"qform"}));
    }
  }
}

TEST(NiftiOrientation, DisagreeingFormsWarnAndUseSform) {
  ScratchDir dir;
  {  // translation: 0.5 mm
    const std::string path = writeSample(dir, "t.nii");
    patch(path, [](std::string& b) { setSrow(b, kV1, 0, 3, getSrow(b, kV1, 0, 3) + 0.5); });
    LogCapture log;
    Grid g;
    const NiftiInfo info = msk::readNiftiHeader(path, &g);
    EXPECT_EQ(info.affineSource, AffineSource::Sform);
    EXPECT_NEAR(g.origin.x(), obliqueGrid().origin.x() + 0.5, 1e-5);
    EXPECT_TRUE(log.has(LogLevel::Warn, {path.c_str(), "disagree", "sform"}));
  }
  {  // rotation: 1° about z, same origin
    const std::string path = writeSample(dir, "r.nii");
    patch(path, [](std::string& b) {
      Eigen::Matrix3d m;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m(r, c) = getSrow(b, kV1, r, c);
      m = Grid::rotationXYZ({0, 0, 1}) * m;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) setSrow(b, kV1, r, c, m(r, c));
    });
    LogCapture log;
    const NiftiInfo info = msk::readNiftiHeader(path);
    EXPECT_EQ(info.affineSource, AffineSource::Sform);
    EXPECT_TRUE(log.has(LogLevel::Warn, {"disagree", "°"}));
  }
  {  // within tolerance (0.05 mm): no warning
    const std::string path = writeSample(dir, "ok.nii");
    patch(path, [](std::string& b) { setSrow(b, kV1, 1, 3, getSrow(b, kV1, 1, 3) + 0.05); });
    LogCapture log;
    msk::readNiftiHeader(path);
    EXPECT_EQ(log.count(LogLevel::Warn), 0u);
  }
}

TEST(NiftiOrientation, ShearedSformFallsBackToQformWithWarning) {
  ScratchDir dir;
  const std::string path = writeSample(dir, "shear.nii");
  patch(path, [](std::string& b) { setSrow(b, kV1, 0, 1, getSrow(b, kV1, 0, 1) + 0.5); });
  LogCapture log;
  Grid g;
  const NiftiInfo info = msk::readNiftiHeader(path, &g);
  EXPECT_EQ(info.affineSource, AffineSource::Qform);
  EXPECT_EQ(info.sformCode, 1);
  EXPECT_LT(cornerDistance(g, obliqueGrid()), 1e-4);
  EXPECT_TRUE(log.has(LogLevel::Warn, {path.c_str(), "sform", "ignoring"}));
}

TEST(NiftiOrientation, PixdimOnlyUsesAbsoluteSpacingAndWarns) {
  ScratchDir dir;
  const std::string path = writeSample(dir, "p.nii");
  patch(path, [](std::string& b) {
    setCode(b, kV1, kV1.qformCode, 0);
    setCode(b, kV1, kV1.sformCode, 0);
    setReal(b, kV1, kV1.pixdim, 1, -0.7);
  });
  LogCapture log;
  Grid g;
  const NiftiInfo info = msk::readNiftiHeader(path, &g);
  EXPECT_EQ(info.affineSource, AffineSource::Pixdim);
  EXPECT_NEAR(g.spacing[0], 0.7, 1e-6);
  EXPECT_NEAR(g.spacing[1], 1.3, 1e-6);
  EXPECT_NEAR(g.spacing[2], 2.1, 1e-6);
  EXPECT_TRUE(g.direction.isIdentity());
  EXPECT_TRUE(g.origin.isZero());
  EXPECT_TRUE(log.has(LogLevel::Warn, {path.c_str(), "pixdim"}));
}

// =============================================================================================
// Scaling

TEST(NiftiScaling, SlopeAndInterceptAreApplied) {
  ScratchDir dir;
  for (int version : {1, 2}) {
    const Layout& L = version == 2 ? kV2 : kV1;
    msk::Volume<int16_t> v(obliqueGrid());
    for (size_t i = 0; i < v.data.size(); ++i) v.data[i] = static_cast<int16_t>(static_cast<int>(i) - 20);
    const std::string path = dir.file("scaled" + std::to_string(version) + ".nii");
    msk::NiftiWriteOptions o;
    o.version = version;
    msk::writeNifti(path, v, DataType::Int16, o);
    patch(path, [&](std::string& b) {
      setReal(b, L, L.sclSlope, 0, 2.0);
      setReal(b, L, L.sclInter, 0, -10.0);
    });
    NiftiInfo info;
    const msk::Volume<double> d = msk::readNifti<double>(path, &info);
    for (size_t i = 0; i < v.data.size(); ++i) ASSERT_EQ(d.data[i], 2.0 * v.data[i] - 10.0);
    EXPECT_TRUE(info.scaled);
    EXPECT_EQ(info.sclSlope, 2.0);
    EXPECT_EQ(info.sclInter, -10.0);
    EXPECT_EQ(info.datatype, DataType::Int16);
    EXPECT_EQ(info.minValue, 2.0 * -20 - 10);
    EXPECT_EQ(info.maxValue, 2.0 * (static_cast<double>(v.data.size()) - 21) - 10);
    const msk::Volume<int16_t> asInt = msk::readNifti<int16_t>(path);  // integral after scaling: fine
    EXPECT_EQ(asInt.data[5], 2 * v.data[5] - 10);

    patch(path, [&](std::string& b) { setReal(b, L, L.sclSlope, 0, 0.5); });
    expectIoError([&] { msk::readNifti<int16_t>(path); }, path, "is not an integer");
    EXPECT_EQ(msk::readNifti<float>(path).data[1], 0.5f * v.data[1] - 10.0f);

    patch(path, [&](std::string& b) { setReal(b, L, L.sclSlope, 0, 0.0); });  // slope 0: no scaling
    NiftiInfo none;
    EXPECT_EQ(msk::readNifti<int16_t>(path, &none).data, v.data);
    EXPECT_FALSE(none.scaled);
  }
}

// =============================================================================================
// Real scans

TEST(NiftiRealScans, TotalSegCtHeaderAndLabels) {
  const std::string shared = msk::test::sharedData();
  if (shared.empty()) GTEST_SKIP() << "shared data not available";
  const std::string ct = shared + "/totalseg-ct/ct.nii.gz", labels = shared + "/totalseg-ct/labels.nii.gz";
  NiftiInfo info;
  const msk::ImageF img = msk::readNifti<float>(ct, &info);
  EXPECT_EQ(img.grid.dims, Eigen::Vector3i(122, 101, 112));
  EXPECT_LT((img.grid.spacing - Eigen::Vector3d::Constant(3.0)).cwiseAbs().maxCoeff(), 1e-4);
  const Eigen::Vector3d w0 = img.grid.toWorld({0, 0, 0});
  EXPECT_LT((w0 - Eigen::Vector3d(-177.96, 11.32, 94.30)).cwiseAbs().maxCoeff(), 0.01) << w0.transpose();
  EXPECT_EQ(info.affineSource, AffineSource::Sform);
  EXPECT_EQ(info.datatype, DataType::Int32);
  EXPECT_LT(info.minValue, -500);  // air in HU
  EXPECT_GT(info.maxValue, 500);   // bone in HU

  NiftiInfo linfo;
  const msk::LabelMap lab = msk::readNifti<int32_t>(labels, &linfo);
  EXPECT_TRUE(lab.grid.sameGeometry(img.grid, 1e-6));
  EXPECT_GT(std::count(lab.data.begin(), lab.data.end(), 25), 0) << "sacrum label";
  EXPECT_EQ(linfo.minValue, 0);
}

TEST(NiftiRealScans, TotalSegMrAndLabelsShareTheGrid) {
  const std::string shared = msk::test::sharedData();
  if (shared.empty()) GTEST_SKIP() << "shared data not available";
  const std::string mr = shared + "/totalseg-mr/mr.nii.gz", labels = shared + "/totalseg-mr/labels.nii.gz";
  const msk::ImageF img = msk::readNifti<float>(mr);
  EXPECT_EQ(img.grid.dims, Eigen::Vector3i(117, 91, 20));
  const msk::LabelMap lab = msk::readNifti<int32_t>(labels);
  EXPECT_TRUE(lab.grid.sameGeometry(img.grid, 1e-6));
  EXPECT_LT(img.grid.direction(0, 0), 0) << "negative-diagonal affine";
  Grid hg;
  msk::readNiftiHeader(labels, &hg);
  EXPECT_TRUE(hg.sameGeometry(lab.grid, 0));
}

// =============================================================================================
// Writing "like" an input header

TEST(NiftiLike, CopiesFormsExactly) {
  ScratchDir dir;
  // Source: sform code 2, qform code 1, the sform nudged 0.05 mm (within tolerance) so that the
  // forms differ and a writer recomputing either one from the grid would be caught.
  const std::string src = writeSample(dir, "src.nii");
  patch(src, [](std::string& b) {
    setCode(b, kV1, kV1.sformCode, 2);
    setSrow(b, kV1, 2, 3, getSrow(b, kV1, 2, 3) + 0.05);
  });
  NiftiInfo info;
  const msk::ImageF img = msk::readNifti<float>(src, &info);
  msk::LabelMap labels(img.grid, 0);
  labels.data[3] = 7;
  msk::NiftiWriteOptions o;
  o.like = &info;
  for (const char* name : {"lab.nii", "lab.nii.gz"}) {
    const std::string out = dir.file(name);
    msk::writeNifti(out, labels, DataType::UInt8, o);
    Grid g;
    const NiftiInfo back = msk::readNiftiHeader(out, &g);
    EXPECT_EQ(back.sformCode, 2);
    EXPECT_EQ(back.qformCode, 1);
    EXPECT_LT((back.sform - info.sform).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_LT((back.qform - info.qform).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_TRUE(g.sameGeometry(img.grid, 1e-6));
    EXPECT_EQ(msk::readNifti<int32_t>(out).data, labels.data);
  }
  // Byte-identical sform/qform fields (qform_code .. srow_z) and pixdim.
  const std::string a = msk::test::readBytes(src), b = msk::test::readBytes(dir.file("lab.nii"));
  EXPECT_EQ(a.substr(252, 328 - 252), b.substr(252, 328 - 252));
  EXPECT_EQ(a.substr(76, 16), b.substr(76, 16));
}

TEST(NiftiLike, CopiesTheRealCtHeader) {
  const std::string shared = msk::test::sharedData();
  if (shared.empty()) GTEST_SKIP() << "shared data not available";
  ScratchDir dir;
  NiftiInfo info;
  const msk::LabelMap lab = msk::readNifti<int32_t>(shared + "/totalseg-ct/labels.nii.gz", &info);
  msk::NiftiWriteOptions o;
  o.like = &info;
  const std::string out = dir.file("copy.nii.gz");
  msk::writeNifti(out, lab, DataType::UInt8, o);
  const NiftiInfo back = msk::readNiftiHeader(out);
  EXPECT_EQ(back.sformCode, info.sformCode);
  EXPECT_EQ(back.qformCode, info.qformCode);
  EXPECT_LT((back.sform - info.sform).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((back.qform - info.qform).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_EQ(msk::readNifti<int32_t>(out).data, lab.data);
}

TEST(NiftiLike, RefusesAVolumeOnAnotherGrid) {
  ScratchDir dir;
  const std::string src = writeSample(dir, "src.nii");
  const NiftiInfo info = msk::readNiftiHeader(src);
  Grid other = obliqueGrid();
  other.origin.x() += 2.0;
  msk::NiftiWriteOptions o;
  o.like = &info;
  const std::string out = dir.file("bad.nii");
  expectIoError([&] { msk::writeNifti(out, msk::LabelMap(other, 1), DataType::UInt8, o); }, out,
                "differs from the 'like' header");
  EXPECT_FALSE(std::filesystem::exists(out));

  // A pixdim-only header has no orientation to give an oblique volume.
  const std::string plain = writeSample(dir, "plain.nii");
  patch(plain, [](std::string& b) {
    setCode(b, kV1, kV1.qformCode, 0);
    setCode(b, kV1, kV1.sformCode, 0);
  });
  Grid pg;
  const NiftiInfo pinfo = msk::readNiftiHeader(plain, &pg);
  ASSERT_EQ(pinfo.affineSource, AffineSource::Pixdim);
  o.like = &pinfo;
  expectIoError([&] { msk::writeNifti(out, msk::LabelMap(obliqueGrid(), 1), DataType::UInt8, o); }, out, "differs");
  msk::writeNifti(out, msk::LabelMap(pg, 1), DataType::UInt8, o);  // its own grid is fine
  Grid back;
  EXPECT_EQ(msk::readNiftiHeader(out, &back).affineSource, AffineSource::Pixdim);
  EXPECT_TRUE(back.sameGeometry(pg, 1e-6));
}

// =============================================================================================
// Bad input

TEST(NiftiBadInput, MissingFileAndNonNiftiContent) {
  ScratchDir dir;
  const std::string missing = dir.file("nope.nii.gz");
  expectIoError([&] { msk::readNifti<float>(missing); }, missing, "file not found");
  expectIoError([&] { msk::readNiftiHeader(missing); }, missing, "file not found");

  const std::string text = dir.file("notes.nii");
  msk::test::writeBytes(text, std::string(400, 'x') + "\nthis is a text file, not an image\n");
  expectIoError([&] { msk::readNifti<float>(text); }, text, "not a NIfTI file");

  const std::string png = dir.file("picture.nii");
  std::string pngBytes("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16);
  pngBytes += std::string(600, '\x01');
  msk::test::writeBytes(png, pngBytes);
  expectIoError([&] { msk::readNiftiHeader(png); }, png, "not a NIfTI file");

  const std::string tiny = dir.file("tiny.nii");
  msk::test::writeBytes(tiny, "abc");
  expectIoError([&] { msk::readNifti<float>(tiny); }, tiny, "not a NIfTI file");

  const std::string pair = writeSample(dir, "pair.nii");
  patch(pair, [](std::string& b) { b[345] = 'i'; });  // "ni1": header of a .hdr/.img pair
  expectIoError([&] { msk::readNifti<float>(pair); }, pair, "two-file");
}

TEST(NiftiBadInput, TruncatedFiles) {
  ScratchDir dir;
  Grid g;
  g.dims = {64, 64, 16};
  msk::Volume<float> v(g);
  uint32_t s = 12345;
  for (float& x : v.data) x = static_cast<float>((s = s * 1664525u + 1013904223u) >> 8);  // incompressible
  const std::string gz = dir.file("cut.nii.gz"), nii = dir.file("cut.nii");
  msk::writeNifti(gz, v, DataType::Float32);
  msk::writeNifti(nii, v, DataType::Float32);

  std::string bytes = msk::test::readBytes(gz);
  msk::test::writeBytes(gz, bytes.substr(0, bytes.size() / 2));
  expectIoError([&] { msk::readNifti<float>(gz); }, gz, "truncated");

  bytes = msk::test::readBytes(nii);
  msk::test::writeBytes(nii, bytes.substr(0, bytes.size() - 100));
  const size_t need = 4 * g.voxelCount();
  expectIoError([&] { msk::readNifti<float>(nii); }, nii,
                "header claims " + std::to_string(need) + " bytes of voxel data but the file holds " +
                    std::to_string(need - 100));
  EXPECT_NO_THROW(msk::readNiftiHeader(nii));  // the header alone is fine
}

TEST(NiftiBadInput, HugeHeaderFromTinyFileFailsWithoutAllocating) {
  ScratchDir dir;
  msk::Volume<double> one(Grid{}, 1.0);
  const std::string path = dir.file("huge.nii");
  msk::writeNifti(path, one, DataType::Float64);
  patch(path, [](std::string& b) {
    b.resize(352);
    for (int a = 1; a <= 3; ++a) setDim(b, kV1, a, 2000);
  });
  ASSERT_EQ(msk::test::readBytes(path).size(), 352u);
  expectIoError([&] { msk::readNifti<double>(path); }, path,
                "header claims 64000000000 bytes of voxel data but the file holds 0");
  EXPECT_NO_THROW(msk::readNiftiHeader(path));

  // The same header gzipped: the decompressed length is counted before anything is allocated.
  const std::string gz = dir.file("huge.nii.gz");
  msk::test::writeBytes(gz, gzipStored(msk::test::readBytes(path)));
  expectIoError([&] { msk::readNifti<float>(gz); }, gz, "header claims 64000000000 bytes");

  // NIfTI-2 sizes whose product overflows 64 bits.
  const std::string v2 = writeSample(dir, "overflow.nii", 2);
  patch(v2, [](std::string& b) {
    for (int a = 1; a <= 3; ++a) setDim(b, kV2, a, 2000000000);
  });
  expectIoError([&] { msk::readNifti<float>(v2); }, v2, "overflows");
  expectIoError([&] { msk::readNiftiHeader(v2); }, v2, "overflows");
}

TEST(NiftiBadInput, BadDimensions) {
  ScratchDir dir;
  const std::string zero = writeSample(dir, "zero.nii");
  patch(zero, [](std::string& b) { setDim(b, kV1, 2, 0); });
  expectIoError([&] { msk::readNifti<float>(zero); }, zero, "dim[2] = 0");
  expectIoError([&] { msk::readNiftiHeader(zero); }, zero, "must be positive");

  const std::string neg = writeSample(dir, "neg.nii", 2);
  patch(neg, [](std::string& b) { setDim(b, kV2, 3, -5); });
  expectIoError([&] { msk::readNifti<float>(neg); }, neg, "dim[3] = -5");

  const std::string ndim = writeSample(dir, "ndim.nii");
  patch(ndim, [](std::string& b) { setDim(b, kV1, 0, 9); });
  expectIoError([&] { msk::readNifti<float>(ndim); }, ndim, "dim[0] = 9");

  // 4-D with several volumes is refused; a 4-D header with a single volume is a 3-D image.
  const std::string t3 = writeSample(dir, "t3.nii");
  patch(t3, [](std::string& b) {
    setDim(b, kV1, 0, 4);
    setDim(b, kV1, 4, 3);
  });
  expectIoError([&] { msk::readNifti<float>(t3); }, t3, "only single 3-D volumes are supported");
  const std::string t1 = writeSample(dir, "t1.nii");
  patch(t1, [](std::string& b) {
    setDim(b, kV1, 0, 4);
    setDim(b, kV1, 4, 1);
  });
  EXPECT_EQ(msk::readNifti<float>(t1).grid.dims, obliqueGrid().dims);
}

TEST(NiftiBadInput, UnsupportedDatatypesAreNamed) {
  ScratchDir dir;
  for (const auto& entry : {std::pair<int, const char*>{128, "RGB24"}, {32, "COMPLEX64"}, {1024, "INT64"}}) {
    const int code = entry.first;
    const char* name = entry.second;
    const std::string path = writeSample(dir, std::string(name) + ".nii");
    patch(path, [&](std::string& b) { setCode(b, kV1, kV1.datatype, code); });
    expectIoError([&] { msk::readNifti<float>(path); }, path, std::string("unsupported datatype ") + name);
    expectIoError([&] { msk::readNiftiHeader(path); }, path, "unsupported datatype");
  }
}

TEST(NiftiBadInput, NonFiniteVoxelsAreCountedAndRefusedByDefault) {
  ScratchDir dir;
  msk::Volume<float> v(obliqueGrid(), 1.5f);
  v.data[0] = std::numeric_limits<float>::quiet_NaN();
  v.data[9] = std::numeric_limits<float>::infinity();
  v.data[17] = -std::numeric_limits<float>::infinity();
  v.data[20] = -4.0f;
  v.data[21] = 8.0f;
  for (const char* name : {"nan.nii", "nan.nii.gz"}) {
    const std::string path = dir.file(name);
    msk::writeNifti(path, v, DataType::Float32);
    expectIoError([&] { msk::readNifti<float>(path); }, path, "3 NaN/Inf voxels");
    NiftiInfo info;
    msk::NiftiReadOptions allow;
    allow.allowNonFinite = true;
    const msk::ImageF back = msk::readNifti<float>(path, &info, allow);
    EXPECT_EQ(info.nonFiniteCount, 3u);
    EXPECT_EQ(info.minValue, -4.0);
    EXPECT_EQ(info.maxValue, 8.0);
    EXPECT_TRUE(std::isnan(back.data[0]));
    EXPECT_TRUE(std::isinf(back.data[9]));
    expectIoError([&] { msk::readNifti<int32_t>(path, nullptr, allow); }, path, "cannot be read as int32");
  }
}

// =============================================================================================
// Writing failures

TEST(NiftiWrite, FailuresLeaveNoFile) {
  ScratchDir dir;
  const msk::Volume<double> vol(obliqueGrid(), 3.0);

  const std::string noFolder = dir.file("missing/sub/out.nii.gz");
  EXPECT_THROW(msk::writeNifti(noFolder, vol, DataType::Float32), IoError);
  EXPECT_FALSE(std::filesystem::exists(dir.file("missing")));

  msk::Volume<double> big = vol;
  big.data[4] = 1e6;
  const std::string out = dir.file("out.nii.gz");
  expectIoError([&] { msk::writeNifti(out, big, DataType::Int16); }, out, "as int16");
  msk::Volume<double> frac = vol;
  frac.data[2] = 2.5;
  expectIoError([&] { msk::writeNifti(out, frac, DataType::UInt8); }, out, "not an integer");
  msk::Volume<double> nan = vol;
  nan.data[1] = std::nan("");
  expectIoError([&] { msk::writeNifti(out, nan, DataType::Int32); }, out, "not finite");
  expectIoError([&] { msk::writeNifti(dir.file("x.img"), vol, DataType::Float32); }, dir.file("x.img"),
                ".nii or .nii.gz");
  msk::NiftiWriteOptions v3;
  v3.version = 3;
  expectIoError([&] { msk::writeNifti(out, vol, DataType::Float32, v3); }, out, "version must be 1 or 2");
  EXPECT_TRUE(dir.list().empty()) << "no output and no temporary file may remain";

  // A failed overwrite keeps the previous file intact.
  msk::writeNifti(out, vol, DataType::Int16);
  const std::string before = msk::test::readBytes(out);
  EXPECT_THROW(msk::writeNifti(out, big, DataType::Int16), IoError);
  EXPECT_EQ(msk::test::readBytes(out), before);
  EXPECT_EQ(dir.list(), std::vector<std::string>{"out.nii.gz"});
}

TEST(NiftiWrite, NiftiOneDimensionLimit) {
  ScratchDir dir;
  Grid g;
  g.dims = {40000, 1, 1};
  const msk::Volume<uint8_t> v(g, 1);
  const std::string p1 = dir.file("long1.nii"), p2 = dir.file("long2.nii.gz");
  expectIoError([&] { msk::writeNifti(p1, v, DataType::UInt8); }, p1, "NIfTI-1 limit");
  msk::NiftiWriteOptions o;
  o.version = 2;
  msk::writeNifti(p2, v, DataType::UInt8, o);
  NiftiInfo info;
  EXPECT_EQ(msk::readNifti<uint8_t>(p2, &info).grid.dims, g.dims);
  EXPECT_EQ(info.version, 2);
}
