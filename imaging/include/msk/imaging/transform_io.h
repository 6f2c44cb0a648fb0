#pragma once
/// Linear transform files: where an atlas (the reference: template meshes, atlas image) lies in a subject, as the 4×4
/// affine map M of atlas world points to subject world points, RAS mm: x_subject = M·x_atlas.
#include <Eigen/Core>
#include <string>

namespace msk {

/// Reads the atlas→subject map M (RAS mm, x_subject = M·x_atlas) from a file, recognised by its content:
/// - ITK / 3D Slicer text transform (.tfm, .txt; first line "#Insight Transform File V1.0") holding one
///   AffineTransform, MatrixOffsetTransformBase (12 parameters: 3×3 matrix A row by row, then translation t),
///   Euler3DTransform (angles about x, y, z in radians, then t; R = Rz·Rx·Ry, or Rz·Ry·Rx when the fourth fixed
///   parameter is 1), VersorRigid3DTransform (versor vector part, then t) or Similarity3DTransform (versor, t, scale),
///   of double or float, with FixedParameters the centre c (zero if absent). The file's map y = A·(x − c) + t + c
///   is in LPS, and in ITK's resampling direction, which is how Slicer saves a transform (it writes the inverse of
///   the "to parent" transform it displays): it is read as a transform that, applied in Slicer to the atlas (its
///   template meshes or image), moves them onto the subject. So the file maps subject points to atlas points
///   (an ITK registration with the subject fixed and the atlas moving gives the same file), and
///   M = C·F⁻¹·C with F the file's 4×4 LPS map and C = diag(−1, −1, 1, 1).
/// - JSON: {"matrix": [[4 numbers] × 4]} (or 3 rows, the last row then 0 0 0 1), optionally "space": "RAS" (default)
///   or "LPS" (converted as C·M·C), or the bare array of rows; atlas→subject.
/// - Plain text: 4 rows (or 3) of 4 numbers separated by spaces, tabs or commas, '#' starting a comment; RAS,
///   atlas→subject.
/// Throws IoError naming the file and the problem (missing file, unknown content, wrong count, non-finite number,
/// unsupported ITK transform type, and every problem of linearTransformProblem()).
Eigen::Matrix4d readLinearTransform(const std::string& path);

/// Writes M (atlas→subject, RAS mm) as the ITK text transform that 3D Slicer loads as a linear transform that moves
/// the atlas onto the subject (AffineTransform_double_3_3 of C·M⁻¹·C, centre 0, 17 significant digits), atomically.
/// readLinearTransform() reads it back to within round-off of the double inversion (≈1e-15 relative). Throws
/// ParameterError naming "atlasToSubjectRas" if linearTransformProblem(M) is not empty, IoError if writing fails.
void writeSlicerTransform(const std::string& path, const Eigen::Matrix4d& atlasToSubjectRas);

/// Empty if `m` is a usable linear transform, otherwise what is wrong: a non-finite entry, a last row other than
/// 0 0 0 1, a singular 3×3 part (|det| ≤ 1e-6) or one whose condition number (largest / smallest singular value)
/// exceeds 1e6.
std::string linearTransformProblem(const Eigen::Matrix4d& m);

}  // namespace msk
