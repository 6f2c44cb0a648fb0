#pragma once
/// NIfTI-1 / NIfTI-2 reading and writing (.nii, .nii.gz) in world space (RAS mm).
#include <Eigen/Core>
#include <string>

#include "msk/imaging/volume.h"

namespace msk {

/// Voxel datatypes mskseg reads and writes.
enum class DataType { UInt8, Int8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// Where the voxel→world affine came from.
enum class AffineSource { Sform, Qform, Pixdim };

/// Name of a datatype ("int16", ...).
const char* dataTypeName(DataType t);
/// Name of an affine source ("sform", "qform", "pixdim").
const char* affineSourceName(AffineSource s);

/// What a NIfTI header said, beyond the grid.
struct NiftiInfo {
  std::string path;                                     ///< file read
  int version = 1;                                      ///< 1 or 2
  DataType datatype = DataType::Float32;                ///< stored datatype
  AffineSource affineSource = AffineSource::Pixdim;     ///< which form gave the grid
  int sformCode = 0, qformCode = 0;                     ///< header codes
  Eigen::Matrix4d sform = Eigen::Matrix4d::Identity();  ///< sform as stored (valid if sformCode > 0)
  Eigen::Matrix4d qform =
      Eigen::Matrix4d::Identity();    ///< qform as computed from the quaternion (valid if qformCode > 0)
  double sclSlope = 1, sclInter = 0;  ///< scaling applied on read (slope 0 means none)
  bool scaled = false;                ///< true if slope/intercept changed the values
  size_t nonFiniteCount = 0;          ///< NaN/Inf voxels found (after scaling)
  double minValue = 0, maxValue = 0;  ///< range of finite values (after scaling)
};

/// Options for reading.
struct NiftiReadOptions {
  bool allowNonFinite = false;  ///< false: NaN/Inf voxels are an error naming their count
};

/// Reads the header only (validated, no voxel data); fills the grid and info. Throws IoError.
NiftiInfo readNiftiHeader(const std::string& path, Grid* grid = nullptr);

/// Reads a volume, applying scl_slope/scl_inter, converting to T (integer T: values must be integral and fit).
/// Orientation: sform if code > 0 and orthogonal up to scale, else qform (code > 0), else pixdim (warns).
/// Warns when both forms are set and disagree by > 0.1 mm or 0.1°; logs which one was used. Throws IoError.
template <typename T>
Volume<T> readNifti(const std::string& path, NiftiInfo* info = nullptr, const NiftiReadOptions& opts = {});

/// Options for writing.
struct NiftiWriteOptions {
  int version = 1;                  ///< 1 or 2 (NIfTI-2 for dims > 32767)
  const NiftiInfo* like = nullptr;  ///< copy sform/qform exactly from this header (label maps on the input grid)
  std::string description;          ///< descrip field (truncated to 79 characters)
};

/// Writes `vol` stored as `type` (values must fit; no scaling), gzipped if the name ends in .gz, atomically.
/// Both sform and qform are written (code 1 = scanner anatomical unless `like` gives others). Throws IoError.
template <typename T>
void writeNifti(const std::string& path, const Volume<T>& vol, DataType type, const NiftiWriteOptions& opts = {});

}  // namespace msk
