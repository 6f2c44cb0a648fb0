// NIfTI-1 / NIfTI-2 reading and writing: the only file that talks to nifticlib.
//
// Headers are parsed by our own bounded read (so every malformed field gets a precise message)
// and then handed to nifticlib (nifti_convert_n{1,2}hdr2nim) for the qform/sform matrices.
// Voxels are streamed through zlib in bounded chunks instead of nifti_image_load(), because
// nifticlib silently replaces NaN/Inf by 0 and allocates whatever the header claims.
// Writing builds the header with nifticlib (nifti_convert_nim2n{1,2}hdr, nifti_dmat44_to_quatern)
// and writes header + data through znzlib into an AtomicFile, checking every write.
#include "msk/imaging/nifti_io.h"

#include <nifti2_io.h>
#include <unistd.h>
#include <zlib.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <type_traits>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"

namespace fs = std::filesystem;

namespace msk {

static_assert(sizeof(nifti_1_header) == 348, "nifti_1_header must be packed to 348 bytes");
static_assert(sizeof(nifti_2_header) == 540, "nifti_2_header must be packed to 540 bytes");

const char* dataTypeName(DataType t) {
  switch (t) {
    case DataType::UInt8:
      return "uint8";
    case DataType::Int8:
      return "int8";
    case DataType::Int16:
      return "int16";
    case DataType::UInt16:
      return "uint16";
    case DataType::Int32:
      return "int32";
    case DataType::UInt32:
      return "uint32";
    case DataType::Float32:
      return "float32";
    case DataType::Float64:
      return "float64";
  }
  return "unknown";
}

const char* affineSourceName(AffineSource s) {
  switch (s) {
    case AffineSource::Sform:
      return "sform";
    case AffineSource::Qform:
      return "qform";
    case AffineSource::Pixdim:
      return "pixdim";
  }
  return "unknown";
}

namespace {

constexpr size_t kChunkBytes = size_t(1) << 20;            // streaming buffer (multiple of every voxel size)
constexpr uint64_t kCountFirstBytes = uint64_t(64) << 20;  // gz data above this is counted before allocating
constexpr double kDisagreeMm = 0.1, kDisagreeDeg = 0.1;    // sform/qform disagreement thresholds

// ---------------------------------------------------------------------------------------------
// Datatypes

int niftiCode(DataType t) {
  switch (t) {
    case DataType::UInt8:
      return NIFTI_TYPE_UINT8;
    case DataType::Int8:
      return NIFTI_TYPE_INT8;
    case DataType::Int16:
      return NIFTI_TYPE_INT16;
    case DataType::UInt16:
      return NIFTI_TYPE_UINT16;
    case DataType::Int32:
      return NIFTI_TYPE_INT32;
    case DataType::UInt32:
      return NIFTI_TYPE_UINT32;
    case DataType::Float32:
      return NIFTI_TYPE_FLOAT32;
    case DataType::Float64:
      return NIFTI_TYPE_FLOAT64;
  }
  return DT_UNKNOWN;
}

bool fromNiftiCode(int code, DataType& out) {
  for (DataType t : {DataType::UInt8, DataType::Int8, DataType::Int16, DataType::UInt16, DataType::Int32,
                     DataType::UInt32, DataType::Float32, DataType::Float64})
    if (niftiCode(t) == code) {
      out = t;
      return true;
    }
  return false;
}

int bytesPerVoxel(DataType t) {
  switch (t) {
    case DataType::UInt8:
    case DataType::Int8:
      return 1;
    case DataType::Int16:
    case DataType::UInt16:
      return 2;
    case DataType::Int32:
    case DataType::UInt32:
    case DataType::Float32:
      return 4;
    case DataType::Float64:
      return 8;
  }
  return 0;
}

/// nifticlib's name of a datatype code without the "NIFTI_TYPE_" prefix ("RGB24").
std::string niftiCodeName(int code) {
  std::string s = nifti_datatype_to_string(code);
  const std::string prefix = "NIFTI_TYPE_";
  if (s.compare(0, prefix.size(), prefix) == 0) return s.substr(prefix.size());
  return "unknown";
}

template <typename S>
struct Tag {
  using type = S;
};

/// Calls f(Tag<S>{}) with S the C++ type stored for `t`.
template <typename F>
void dispatch(DataType t, F&& f) {
  switch (t) {
    case DataType::UInt8:
      f(Tag<uint8_t>{});
      return;
    case DataType::Int8:
      f(Tag<int8_t>{});
      return;
    case DataType::Int16:
      f(Tag<int16_t>{});
      return;
    case DataType::UInt16:
      f(Tag<uint16_t>{});
      return;
    case DataType::Int32:
      f(Tag<int32_t>{});
      return;
    case DataType::UInt32:
      f(Tag<uint32_t>{});
      return;
    case DataType::Float32:
      f(Tag<float>{});
      return;
    case DataType::Float64:
      f(Tag<double>{});
      return;
  }
}

template <typename T>
const char* cppTypeName() {
  if constexpr (std::is_same_v<T, float>)
    return "float";
  else if constexpr (std::is_same_v<T, double>)
    return "double";
  else if constexpr (std::is_same_v<T, int8_t>)
    return "int8";
  else if constexpr (std::is_same_v<T, uint8_t>)
    return "uint8";
  else if constexpr (std::is_same_v<T, int16_t>)
    return "int16";
  else if constexpr (std::is_same_v<T, uint16_t>)
    return "uint16";
  else if constexpr (std::is_same_v<T, int32_t>)
    return "int32";
  else if constexpr (std::is_same_v<T, uint32_t>)
    return "uint32";
  else
    return "the requested type";
}

/// Empty if `v` can be stored exactly in T (integers: integral and in range; floats: in range or non-finite).
template <typename T>
const char* fitProblem(double v) {
  if constexpr (std::is_integral_v<T>) {
    if (!std::isfinite(v)) return "is not finite";
    if (v != std::nearbyint(v)) return "is not an integer";
    if (v < static_cast<double>(std::numeric_limits<T>::lowest()) ||
        v > static_cast<double>(std::numeric_limits<T>::max()))
      return "is out of range";
  } else if constexpr (sizeof(T) < sizeof(double)) {
    if (std::isfinite(v) && std::fabs(v) > static_cast<double>(std::numeric_limits<T>::max())) return "is out of range";
  }
  return nullptr;
}

std::string fmt(double v, int precision = 17) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

std::string dimsText(int64_t a, int64_t b, int64_t c) {
  return std::to_string(a) + "×" + std::to_string(b) + "×" + std::to_string(c);
}

std::string voxelText(size_t index, const Eigen::Vector3i& dims) {
  const size_t nx = static_cast<size_t>(dims[0]), ny = static_cast<size_t>(dims[1]);
  return "(" + std::to_string(index % nx) + ", " + std::to_string((index / nx) % ny) + ", " +
         std::to_string(index / (nx * ny)) + ")";
}

// ---------------------------------------------------------------------------------------------
// Matrices

Eigen::Matrix4d toEigen(const nifti_dmat44& m) {
  Eigen::Matrix4d a;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) a(r, c) = m.m[r][c];
  return a;
}

nifti_dmat44 toNifti(const Eigen::Matrix4d& a) {
  nifti_dmat44 m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m.m[r][c] = a(r, c);
  return m;
}

/// Largest distance (mm) between the images of the 8 grid corners under two affines.
double cornerDistance(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b, const Eigen::Vector3i& dims) {
  double worst = 0;
  for (int c = 0; c < 8; ++c) {
    Eigen::Vector4d ijk((c & 1) ? dims[0] - 1 : 0, (c & 2) ? dims[1] - 1 : 0, (c & 4) ? dims[2] - 1 : 0, 1.0);
    worst = std::max(worst, ((a - b) * ijk).head<3>().norm());
  }
  return worst;
}

/// Largest angle (degrees) between corresponding axis columns of two 3×3 matrices.
double axisAngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  double worst = 0;
  for (int c = 0; c < 3; ++c) {
    Eigen::Vector3d u = a.col(c).normalized(), v = b.col(c).normalized();
    worst = std::max(worst, std::atan2(u.cross(v).norm(), u.dot(v)) * 180.0 / M_PI);
  }
  return worst;
}

// ---------------------------------------------------------------------------------------------
// Bounded reading through zlib (transparent for uncompressed files)

class GzReader {
 public:
  explicit GzReader(const std::string& path) : path_(path) {
    file_ = gzopen(path.c_str(), "rb");
    if (!file_) throw IoError(path, std::string("cannot open: ") + std::strerror(errno ? errno : EIO));
    gzbuffer(file_, 1u << 17);
  }
  ~GzReader() {
    if (file_) gzclose(file_);
  }
  GzReader(const GzReader&) = delete;
  GzReader& operator=(const GzReader&) = delete;

  /// Reads up to n bytes (fewer only at the end of the data or on a zlib error, see error()).
  size_t read(void* buf, size_t n) {
    size_t got = 0;
    auto* out = static_cast<unsigned char*>(buf);
    while (got < n && error_.empty()) {
      const unsigned want = static_cast<unsigned>(std::min<size_t>(n - got, kChunkBytes));
      const int r = gzread(file_, out + got, want);
      if (r > 0) {
        got += static_cast<size_t>(r);
        continue;
      }
      int code = Z_OK;
      const char* msg = gzerror(file_, &code);
      if (r < 0 || (code != Z_OK && code != Z_STREAM_END)) {
        error_ = msg && *msg ? msg : "zlib error";
        if (error_.compare(0, path_.size() + 2, path_ + ": ") == 0)
          error_ = error_.substr(path_.size() + 2);  // zlib prefixes the path
      }
      break;
    }
    return got;
  }
  /// Reads and discards up to n bytes; returns how many were there.
  uint64_t skip(uint64_t n) {
    std::vector<unsigned char> buf(static_cast<size_t>(std::min<uint64_t>(n, kChunkBytes)));
    uint64_t done = 0;
    while (done < n) {
      const size_t want = static_cast<size_t>(std::min<uint64_t>(n - done, buf.size()));
      const size_t got = read(buf.data(), want);
      done += got;
      if (got < want) break;
    }
    return done;
  }
  /// True if the file is gzip-compressed (valid after the first read).
  bool compressed() const { return gzdirect(file_) == 0; }
  /// zlib's message if reading failed (corrupt or truncated gzip stream), else empty.
  const std::string& error() const { return error_; }

 private:
  std::string path_;
  gzFile file_ = nullptr;
  std::string error_;
};

// ---------------------------------------------------------------------------------------------
// Header parsing and validation

struct NimDeleter {
  void operator()(nifti_image* n) const { nifti_image_free(n); }
};
using NimPtr = std::unique_ptr<nifti_image, NimDeleter>;

/// A validated header: what we checked ourselves plus nifticlib's interpretation.
struct Header {
  int version = 1;
  bool compressed = false;
  bool swapped = false;
  DataType type = DataType::Float32;
  int bytesPerVoxel = 4;
  int ndim = 3;
  Eigen::Vector3i dims = Eigen::Vector3i::Ones();
  uint64_t voxOffset = 352;         // where voxels start
  uint64_t dataBytes = 0;           // voxel bytes the header requires
  double pixdim[4] = {0, 1, 1, 1};  // raw pixdim[0..3]
  bool quaternFinite = true;        // raw quaternion fields are finite
  int xyzUnits = 0;
  NimPtr nim;  // nifticlib's view: qto_xyz, sto_xyz, codes, scaling
};

uint32_t swap32(uint32_t v) { return (v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24); }

/// Checks shared by NIfTI-1 and NIfTI-2 on a header already in native byte order.
template <typename H>
void validate(const H& h, const std::string& path, Header& out) {
  const int64_t ndim = static_cast<int64_t>(h.dim[0]);
  if (ndim < 1 || ndim > 7)
    throw IoError(path,
                  "invalid header: dim[0] = " + std::to_string(ndim) + " (the number of dimensions must be 1 to 7)");
  for (int64_t i = 1; i <= ndim; ++i)
    if (h.dim[i] <= 0)
      throw IoError(path, "invalid header: dim[" + std::to_string(i) + "] = " +
                              std::to_string(static_cast<int64_t>(h.dim[i])) + " (image dimensions must be positive)");
  for (int64_t i = 4; i <= ndim; ++i)
    if (h.dim[i] > 1)
      throw IoError(path, "image has more than 3 dimensions (dim[" + std::to_string(i) +
                              "] = " + std::to_string(static_cast<int64_t>(h.dim[i])) +
                              "); only single 3-D volumes are supported, extract one volume first");
  int64_t n[3];
  for (int a = 0; a < 3; ++a) {
    n[a] = (a + 1 <= ndim) ? static_cast<int64_t>(h.dim[a + 1]) : 1;
    if (n[a] > std::numeric_limits<int>::max())
      throw IoError(path, "dimension " + std::to_string(a + 1) + " = " + std::to_string(n[a]) + " is too large");
  }
  out.ndim = static_cast<int>(ndim);
  out.dims = Eigen::Vector3i(static_cast<int>(n[0]), static_cast<int>(n[1]), static_cast<int>(n[2]));

  const int code = h.datatype;
  if (!fromNiftiCode(code, out.type))
    throw IoError(path, "unsupported datatype " + niftiCodeName(code) + " (code " + std::to_string(code) +
                            "); supported: uint8, int8, int16, uint16, int32, uint32, float32, float64");
  out.bytesPerVoxel = bytesPerVoxel(out.type);

  uint64_t bytes = static_cast<uint64_t>(out.bytesPerVoxel);
  for (int a = 0; a < 3; ++a)
    if (__builtin_mul_overflow(bytes, static_cast<uint64_t>(n[a]), &bytes))
      throw IoError(path, "invalid header: image size " + dimsText(n[0], n[1], n[2]) + " × " +
                              std::to_string(out.bytesPerVoxel) + " bytes overflows");
  out.dataBytes = bytes;

  const double off = static_cast<double>(h.vox_offset);
  if (!std::isfinite(off) || off < 0 || off > 1e15) throw IoError(path, "invalid header: vox_offset = " + fmt(off));
  out.voxOffset = std::max<uint64_t>(static_cast<uint64_t>(off), static_cast<uint64_t>(h.sizeof_hdr));
  uint64_t total = 0;
  if (__builtin_add_overflow(out.voxOffset, out.dataBytes, &total))
    throw IoError(path, "invalid header: data size overflows");

  for (int i = 0; i < 4; ++i) out.pixdim[i] = static_cast<double>(h.pixdim[i]);
  out.quaternFinite =
      std::isfinite(static_cast<double>(h.quatern_b)) && std::isfinite(static_cast<double>(h.quatern_c)) &&
      std::isfinite(static_cast<double>(h.quatern_d)) && std::isfinite(static_cast<double>(h.qoffset_x)) &&
      std::isfinite(static_cast<double>(h.qoffset_y)) && std::isfinite(static_cast<double>(h.qoffset_z));
  out.xyzUnits = XYZT_TO_SPACE(h.xyzt_units);
}

/// nifticlib must not print to stderr: we throw or log instead.
void silenceNifticlib() {
  static std::once_flag once;
  std::call_once(once, [] { nifti_set_debug_level(0); });
}

/// Reads and validates the header of a single-file NIfTI-1/2 (.nii or .nii.gz). Throws IoError.
Header parseHeader(const std::string& path) {
  silenceNifticlib();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw IoError(path, "file not found");
  if (!fs::is_regular_file(path, ec)) throw IoError(path, "not a regular file");

  unsigned char buf[sizeof(nifti_2_header)] = {};
  Header out;
  size_t got = 0;
  std::string zerr;
  {
    GzReader in(path);
    got = in.read(buf, sizeof(buf));
    out.compressed = in.compressed();
    zerr = in.error();
  }
  if (got < sizeof(nifti_1_header)) {
    if (!zerr.empty()) throw IoError(path, "truncated or corrupt gzip data (" + zerr + ")");
    throw IoError(path, "not a NIfTI file (only " + std::to_string(got) + " bytes; a NIfTI header needs 348)");
  }
  uint32_t size = 0;
  std::memcpy(&size, buf, 4);
  const bool v1 = size == 348 || swap32(size) == 348;
  const bool v2 = size == 540 || swap32(size) == 540;
  out.swapped = (size != 348 && size != 540);
  if (v1) {
    const char* magic = reinterpret_cast<const char*>(buf) + 344;
    if (std::memcmp(magic, "ni1\0", 4) == 0)
      throw IoError(path, "two-file NIfTI (.hdr/.img) is not supported; convert it to a single .nii or .nii.gz");
    if (std::memcmp(magic, "n+1\0", 4) != 0)
      throw IoError(path, "not a NIfTI file (no NIfTI-1 magic; Analyze 7.5 is not supported)");
    nifti_1_header raw, h;
    std::memcpy(&raw, buf, sizeof(raw));
    h = raw;
    if (out.swapped) swap_nifti_header(&h, 1);
    out.version = 1;
    validate(h, path, out);
    out.nim.reset(nifti_convert_n1hdr2nim(raw, nullptr));
  } else if (v2) {
    if (got < sizeof(nifti_2_header))
      throw IoError(path, "truncated NIfTI-2 header (" + std::to_string(got) + " of 540 bytes)");
    const char* magic = reinterpret_cast<const char*>(buf) + 4;
    if (std::memcmp(magic, "ni2\0", 4) == 0)
      throw IoError(path, "two-file NIfTI (.hdr/.img) is not supported; convert it to a single .nii or .nii.gz");
    if (std::memcmp(magic, "n+2\0", 4) != 0) throw IoError(path, "not a NIfTI file (no NIfTI-2 magic)");
    nifti_2_header raw, h;
    std::memcpy(&raw, buf, sizeof(raw));
    h = raw;
    if (out.swapped) swap_nifti_header(&h, 2);
    out.version = 2;
    validate(h, path, out);
    out.nim.reset(nifti_convert_n2hdr2nim(raw, nullptr));
  } else {
    throw IoError(path, "not a NIfTI file (no NIfTI-1 or NIfTI-2 header)");
  }
  if (!out.nim) throw IoError(path, "nifticlib could not interpret the header");
  return out;
}

// ---------------------------------------------------------------------------------------------
// Orientation

/// Fills the geometry part of `info` and chooses the grid (see readNifti). Logs what it did.
Grid chooseGrid(const Header& h, const std::string& path, NiftiInfo& info) {
  const nifti_image& nim = *h.nim;
  info.sformCode = nim.sform_code;
  info.qformCode = nim.qform_code;
  info.sform = toEigen(nim.sto_xyz);
  info.qform = toEigen(nim.qto_xyz);
  if (info.sformCode <= 0) info.sform.setIdentity();
  if (info.qformCode <= 0) info.qform.setIdentity();

  // nifticlib replaces bad pixdim by 1 silently: reject such a qform instead.
  bool pixOk = true;
  for (int a = 1; a <= 3; ++a)
    if (a <= h.ndim && !(std::isfinite(h.pixdim[a]) && h.pixdim[a] != 0)) pixOk = false;

  Grid sGrid, qGrid;
  const bool sOk = info.sformCode > 0 && Grid::fromAffine(h.dims, info.sform, sGrid) && sGrid.problem().empty();
  bool qPixOk = pixOk;
  for (int a = 1; a <= 3; ++a)
    if (a <= h.ndim && h.pixdim[a] < 0) qPixOk = false;
  const bool qOk = info.qformCode > 0 && qPixOk && h.quaternFinite && Grid::fromAffine(h.dims, info.qform, qGrid) &&
                   qGrid.problem().empty();

  if (info.sformCode > 0 && !sOk)
    log::warn(path + ": sform (code " + std::to_string(info.sformCode) +
              ") is not a rotation times per-axis scaling (sheared, degenerate or non-finite); ignoring it");
  if (info.qformCode > 0 && !qOk)
    (sOk ? log::debug : log::warn)(path + ": qform (code " + std::to_string(info.qformCode) +
                                   ") is unusable (non-positive or non-finite pixdim, or bad quaternion); ignoring it");
  if (sOk && qOk) {
    const double mm = cornerDistance(info.sform, info.qform, h.dims);
    const double deg = axisAngleDeg(info.sform.topLeftCorner<3, 3>(), info.qform.topLeftCorner<3, 3>());
    if (mm > kDisagreeMm || deg > kDisagreeDeg)
      log::warn(path + ": sform and qform disagree (corners up to " + fmt(mm, 4) + " mm apart, axes up to " +
                fmt(deg, 4) + "° apart); using the sform");
  }
  if (h.xyzUnits != 0 && h.xyzUnits != NIFTI_UNITS_MM)
    log::warn(path + ": spatial units are " + nifti_units_string(h.xyzUnits) + ", not mm; coordinates are used as mm");

  Grid g;
  if (sOk) {
    g = sGrid;
    info.affineSource = AffineSource::Sform;
  } else if (qOk) {
    g = qGrid;
    info.affineSource = AffineSource::Qform;
  } else {
    g.dims = h.dims;
    for (int a = 0; a < 3; ++a) {
      const double p = h.pixdim[a + 1];
      const bool good = std::isfinite(p) && p != 0;
      if (!good && a + 1 <= h.ndim)
        throw IoError(path, "no usable sform or qform, and pixdim[" + std::to_string(a + 1) + "] = " + fmt(p) +
                                " is not a valid voxel size");
      g.spacing[a] = good ? std::fabs(p) : 1.0;
    }
    g.direction.setIdentity();
    g.origin.setZero();
    info.affineSource = AffineSource::Pixdim;
    log::warn(path +
              ": no usable sform or qform; using pixdim spacing with identity direction and origin 0 (world position "
              "unknown)");
  }
  log::debug(path + ": NIfTI-" + std::to_string(h.version) + " " + dataTypeName(h.type) + " " +
             dimsText(g.dims[0], g.dims[1], g.dims[2]) + " voxels of " + fmt(g.spacing[0], 6) + "×" +
             fmt(g.spacing[1], 6) + "×" + fmt(g.spacing[2], 6) + " mm, orientation from the " +
             affineSourceName(info.affineSource));
  return g;
}

/// Everything readNiftiHeader reports; scaling as nifticlib parsed it (non-finite -> 0 -> none).
NiftiInfo makeInfo(const Header& h, const std::string& path) {
  NiftiInfo info;
  info.path = path;
  info.version = h.version;
  info.datatype = h.type;
  info.sclSlope = h.nim->scl_slope;
  info.sclInter = h.nim->scl_inter;
  if (!std::isfinite(info.sclSlope)) info.sclSlope = 0;
  if (!std::isfinite(info.sclInter)) info.sclInter = 0;
  info.scaled = info.sclSlope != 0 && (info.sclSlope != 1 || info.sclInter != 0);
  return info;
}

uint64_t physicalMemory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return std::numeric_limits<uint64_t>::max();
  return static_cast<uint64_t>(pages) * static_cast<uint64_t>(page);
}

std::string shortData(const Header& h, uint64_t available, const std::string& zerr) {
  std::string s = "truncated: header claims " + std::to_string(h.dataBytes) +
                  " bytes of voxel data but the file holds " + std::to_string(available);
  if (!zerr.empty()) s += " (gzip stream ends early: " + zerr + ")";
  return s;
}

// ---------------------------------------------------------------------------------------------
// Voxel conversion

struct ReadStats {
  bool scale = false;
  double slope = 1, inter = 0;
  size_t nonFinite = 0;
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  bool bad = false;  // first value that does not fit T
  size_t badIndex = 0;
  double badValue = 0;
  const char* badWhy = nullptr;
};

template <typename S, typename T>
void decodeChunk(const unsigned char* raw, size_t n, size_t base, T* out, ReadStats& st) {
  for (size_t i = 0; i < n; ++i) {
    S s;
    std::memcpy(&s, raw + i * sizeof(S), sizeof(S));
    double v = static_cast<double>(s);
    if (st.scale) v = v * st.slope + st.inter;
    if (!std::isfinite(v)) {
      ++st.nonFinite;
      if constexpr (std::is_floating_point_v<T>)
        out[i] = static_cast<T>(v);
      else
        out[i] = T(0);
      continue;
    }
    st.lo = std::min(st.lo, v);
    st.hi = std::max(st.hi, v);
    if constexpr (std::is_same_v<S, T>) {
      if (!st.scale) {
        out[i] = s;
        continue;
      }
    }
    if (const char* why = fitProblem<T>(v)) {
      if (!st.bad) {
        st.bad = true;
        st.badIndex = base + i;
        st.badValue = v;
        st.badWhy = why;
      }
      out[i] = T(0);
      continue;
    }
    out[i] = static_cast<T>(v);
  }
}

template <typename T>
Volume<T> readVoxels(const std::string& path, const Header& h, const Grid& grid, NiftiInfo& info,
                     const NiftiReadOptions& opts) {
  const uint64_t total = h.voxOffset + h.dataBytes;  // overflow checked in validate()
  if (!h.compressed) {
    std::error_code ec;
    const uint64_t size = fs::file_size(path, ec);
    if (ec) throw IoError(path, "cannot determine the file size: " + ec.message());
    if (size < total) throw IoError(path, shortData(h, size > h.voxOffset ? size - h.voxOffset : 0, ""));
  }
  const uint64_t voxels = static_cast<uint64_t>(grid.voxelCount());
  uint64_t need = 0;
  const uint64_t memory = physicalMemory();
  const bool fitsMemory = !__builtin_mul_overflow(voxels, static_cast<uint64_t>(sizeof(T)), &need) && need <= memory;
  if (h.compressed && h.dataBytes > kCountFirstBytes) {
    // Decompress once with a bounded buffer to prove the data is there before allocating it. When it
    // would not fit in memory anyway, look only far enough to tell a truncated file from a huge one.
    const uint64_t limit = fitsMemory ? total : std::min(total, h.voxOffset + 4 * kCountFirstBytes);
    GzReader counter(path);
    const uint64_t avail = counter.skip(limit);
    if (avail < limit)
      throw IoError(path, shortData(h, avail > h.voxOffset ? avail - h.voxOffset : 0, counter.error()));
  }
  if (!fitsMemory)
    throw IoError(path, "image of " + dimsText(grid.dims[0], grid.dims[1], grid.dims[2]) + " voxels needs " +
                            (need ? std::to_string(need) + " bytes" : std::string("more than 2^64 bytes")) + " as " +
                            cppTypeName<T>() + ", more than this machine's memory (" + std::to_string(memory) +
                            " bytes)");

  Volume<T> vol(grid);
  ReadStats st;
  st.scale = info.scaled;
  st.slope = info.sclSlope;
  st.inter = info.sclInter;

  GzReader in(path);
  if (in.skip(h.voxOffset) < h.voxOffset) throw IoError(path, shortData(h, 0, in.error()));
  std::vector<unsigned char> buf(static_cast<size_t>(std::min<uint64_t>(h.dataBytes, kChunkBytes)));
  uint64_t done = 0;
  const size_t bpv = static_cast<size_t>(h.bytesPerVoxel);
  while (done < h.dataBytes) {
    const size_t want = static_cast<size_t>(std::min<uint64_t>(h.dataBytes - done, buf.size()));
    const size_t got = in.read(buf.data(), want);
    if (got < want) throw IoError(path, shortData(h, done + got, in.error()));
    const size_t n = got / bpv, base = static_cast<size_t>(done / bpv);
    if (h.swapped && bpv > 1) nifti_swap_Nbytes(static_cast<int64_t>(n), h.bytesPerVoxel, buf.data());
    dispatch(h.type, [&](auto tag) {
      using S = typename decltype(tag)::type;
      decodeChunk<S, T>(buf.data(), n, base, vol.data.data() + base, st);
    });
    done += got;
  }

  info.nonFiniteCount = st.nonFinite;
  info.minValue = st.lo <= st.hi ? st.lo : 0;
  info.maxValue = st.lo <= st.hi ? st.hi : 0;
  if (st.nonFinite > 0 && !opts.allowNonFinite)
    throw IoError(path, std::to_string(st.nonFinite) + " NaN/Inf voxels; non-finite values are not accepted");
  if (st.nonFinite > 0 && std::is_integral_v<T>)
    throw IoError(path, std::to_string(st.nonFinite) + " NaN/Inf voxels cannot be read as " + cppTypeName<T>());
  if (st.bad)
    throw IoError(path, std::string("voxel ") + voxelText(st.badIndex, grid.dims) + " value " + fmt(st.badValue) +
                            (info.scaled ? " (after scl_slope/scl_inter)" : "") + " " + st.badWhy + " for " +
                            cppTypeName<T>());
  if (st.nonFinite > 0) log::warn(path + ": " + std::to_string(st.nonFinite) + " NaN/Inf voxels");
  return vol;
}

// ---------------------------------------------------------------------------------------------
// Writing

/// Throws unless every voxel of `vol` is stored exactly by `type`.
template <typename T>
void checkFits(const std::string& path, const Volume<T>& vol, DataType type) {
  dispatch(type, [&](auto tag) {
    using S = typename decltype(tag)::type;
    if constexpr (!std::is_same_v<S, T>) {  // the same type always fits
      for (size_t i = 0; i < vol.data.size(); ++i) {
        const double v = static_cast<double>(vol.data[i]);
        if (const char* why = fitProblem<S>(v))
          throw IoError(path, "cannot store voxel " + voxelText(i, vol.grid.dims) + " value " + fmt(v) + " as " +
                                  dataTypeName(type) + ": it " + why);
      }
    }
  });
}

template <typename S, typename T>
void encodeChunk(const T* in, size_t n, unsigned char* out) {
  for (size_t i = 0; i < n; ++i) {
    const S s = static_cast<S>(in[i]);
    std::memcpy(out + i * sizeof(S), &s, sizeof(S));
  }
}

/// Closes a znzFile if the write bails out early.
struct ZnzCloser {
  znzFile fp = nullptr;
  ~ZnzCloser() {
    if (fp) znzclose(fp);
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public API

NiftiInfo readNiftiHeader(const std::string& path, Grid* grid) {
  Header h = parseHeader(path);
  NiftiInfo info = makeInfo(h, path);
  Grid g = chooseGrid(h, path, info);
  if (grid) *grid = g;
  return info;
}

template <typename T>
Volume<T> readNifti(const std::string& path, NiftiInfo* infoOut, const NiftiReadOptions& opts) {
  Header h = parseHeader(path);
  NiftiInfo info = makeInfo(h, path);
  Grid g = chooseGrid(h, path, info);
  Volume<T> vol = readVoxels<T>(path, h, g, info, opts);
  if (infoOut) *infoOut = info;
  return vol;
}

template <typename T>
void writeNifti(const std::string& path, const Volume<T>& vol, DataType type, const NiftiWriteOptions& opts) {
  silenceNifticlib();
  const std::string ext = fileExtension(path);
  if (ext != ".nii" && ext != ".nii.gz") throw IoError(path, "NIfTI file names must end in .nii or .nii.gz");
  if (opts.version != 1 && opts.version != 2)
    throw IoError(path, "NIfTI version must be 1 or 2, not " + std::to_string(opts.version));
  const Grid& g = vol.grid;
  if (std::string p = g.problem(); !p.empty()) throw IoError(path, "cannot write an invalid grid: " + p);
  if (vol.data.size() != g.voxelCount())
    throw IoError(path, "volume holds " + std::to_string(vol.data.size()) + " values but its grid has " +
                            std::to_string(g.voxelCount()) + " voxels");
  if (opts.version == 1 && g.dims.maxCoeff() > 32767)
    throw IoError(
        path, "dimension " + std::to_string(g.dims.maxCoeff()) + " exceeds the NIfTI-1 limit of 32767; write NIfTI-2");
  checkFits(path, vol, type);

  // Geometry: our affine in both forms, or the `like` header's forms copied exactly.
  const Eigen::Matrix4d affine = g.voxelToWorld();
  int sCode = NIFTI_XFORM_SCANNER_ANAT, qCode = NIFTI_XFORM_SCANNER_ANAT;
  Eigen::Matrix4d sMat = affine, qMat = affine;
  if (opts.like) {
    // The copied forms must describe the volume's grid, as reading them back would.
    const NiftiInfo& L = *opts.like;
    Grid expect;
    if (L.affineSource == AffineSource::Pixdim) {
      expect.dims = g.dims;
      expect.spacing = g.spacing;  // pixdim-only headers carry no direction or origin
    } else if (!Grid::fromAffine(g.dims, L.affineSource == AffineSource::Sform ? L.sform : L.qform, expect)) {
      throw IoError(path, "the 'like' header's " + std::string(affineSourceName(L.affineSource)) + " is not usable");
    }
    const double d = cornerDistance(expect.voxelToWorld(), affine, g.dims);
    if (d > 1e-3)
      throw IoError(path, "the volume's grid differs from the 'like' header (" + L.path + ") by " + fmt(d, 4) +
                              " mm; refusing to copy its sform/qform");
    sCode = std::max(0, L.sformCode);
    qCode = std::max(0, L.qformCode);
    sMat = L.sform;
    qMat = L.qform;
  }

  const int64_t dims[8] = {3, g.dims[0], g.dims[1], g.dims[2], 1, 1, 1, 1};
  NimPtr nim(nifti_make_new_nim(dims, niftiCode(type), 0));
  if (!nim) throw IoError(path, "nifticlib could not create a header");
  nim->nifti_type = opts.version == 2 ? NIFTI_FTYPE_NIFTI2_1 : NIFTI_FTYPE_NIFTI1_1;
  nim->iname_offset = opts.version == 2 ? 544 : 352;  // header + 4-byte extender, no extensions
  nim->dx = nim->pixdim[1] = g.spacing[0];
  nim->dy = nim->pixdim[2] = g.spacing[1];
  nim->dz = nim->pixdim[3] = g.spacing[2];
  nim->xyz_units = NIFTI_UNITS_MM;
  nim->time_units = NIFTI_UNITS_UNKNOWN;
  nim->scl_slope = 1.0;
  nim->scl_inter = 0.0;
  nim->sform_code = sCode;
  nim->sto_xyz = toNifti(sMat);
  nim->qform_code = qCode;
  if (qCode > 0) {
    double qb, qc, qd, qx, qy, qz, dx, dy, dz, qfac;
    nifti_dmat44_to_quatern(toNifti(qMat), &qb, &qc, &qd, &qx, &qy, &qz, &dx, &dy, &dz, &qfac);
    nim->quatern_b = qb;
    nim->quatern_c = qc;
    nim->quatern_d = qd;
    nim->qoffset_x = qx;
    nim->qoffset_y = qy;
    nim->qoffset_z = qz;
    nim->qfac = qfac;
    nim->pixdim[0] = qfac;
    if (opts.like) {  // the qform's scales are the pixdims: keep them with the copied quaternion
      nim->dx = nim->pixdim[1] = dx;
      nim->dy = nim->pixdim[2] = dy;
      nim->dz = nim->pixdim[3] = dz;
    }
  }
  std::strncpy(nim->descrip, opts.description.c_str(), 79);
  nim->descrip[79] = '\0';

  nifti_1_header h1;
  nifti_2_header h2;
  const void* hdr = nullptr;
  size_t hdrSize = 0;
  if (opts.version == 2) {
    if (nifti_convert_nim2n2hdr(nim.get(), &h2) != 0) throw IoError(path, "nifticlib could not build a NIfTI-2 header");
    static const char magic2[8] = {'n', '+', '2', '\0', '\r', '\n', '\032', '\n'};
    std::memcpy(h2.magic, magic2, 8);
    hdr = &h2;
    hdrSize = sizeof(h2);
  } else {
    if (nifti_convert_nim2n1hdr(nim.get(), &h1) != 0) throw IoError(path, "nifticlib could not build a NIfTI-1 header");
    hdr = &h1;
    hdrSize = sizeof(h1);
  }

  const bool gz = ext == ".nii.gz";
  writeAtomically(path, [&](const std::string& tmp) {
    ZnzCloser out;
    out.fp = znzopen(tmp.c_str(), "wb", gz ? 1 : 0);
    if (znz_isnull(out.fp))
      throw IoError(path, std::string("cannot create the file: ") + std::strerror(errno ? errno : EIO));
    const char extender[4] = {0, 0, 0, 0};
    if (znzwrite(hdr, 1, hdrSize, out.fp) != hdrSize || znzwrite(extender, 1, 4, out.fp) != 4)
      throw IoError(path, "cannot write the header (disk full?)");
    const size_t bpv = static_cast<size_t>(bytesPerVoxel(type));
    std::vector<unsigned char> buf(kChunkBytes);
    const size_t perChunk = kChunkBytes / bpv;
    for (size_t start = 0; start < vol.data.size(); start += perChunk) {
      const size_t n = std::min(perChunk, vol.data.size() - start);
      dispatch(type, [&](auto tag) {
        using S = typename decltype(tag)::type;
        encodeChunk<S, T>(vol.data.data() + start, n, buf.data());
      });
      if (znzwrite(buf.data(), 1, n * bpv, out.fp) != n * bpv)
        throw IoError(path, "cannot write voxel data (disk full?)");
    }
    znzFile fp = out.fp;
    out.fp = nullptr;
    if (znzclose(fp) != 0) throw IoError(path, "cannot finish writing the file (disk full?)");
  });
  log::debug(path + ": wrote NIfTI-" + std::to_string(opts.version) + " " + dataTypeName(type) + " " +
             dimsText(g.dims[0], g.dims[1], g.dims[2]));
}

#define MSK_NIFTI_INSTANTIATE(T)                                                            \
  template Volume<T> readNifti<T>(const std::string&, NiftiInfo*, const NiftiReadOptions&); \
  template void writeNifti<T>(const std::string&, const Volume<T>&, DataType, const NiftiWriteOptions&);
MSK_NIFTI_INSTANTIATE(float)
MSK_NIFTI_INSTANTIATE(double)
MSK_NIFTI_INSTANTIATE(int8_t)
MSK_NIFTI_INSTANTIATE(uint8_t)
MSK_NIFTI_INSTANTIATE(int16_t)
MSK_NIFTI_INSTANTIATE(uint16_t)
MSK_NIFTI_INSTANTIATE(int32_t)
MSK_NIFTI_INSTANTIATE(uint32_t)
#undef MSK_NIFTI_INSTANTIATE

}  // namespace msk
