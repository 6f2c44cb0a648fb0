// Linear transform files (ITK / Slicer text, JSON, plain text) as the atlas→subject map in RAS mm.
#include "msk/imaging/transform_io.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/imaging/json.h"

namespace msk {

namespace {

constexpr const char* kItkHeader = "#Insight Transform File V1.0";
constexpr double kLastRowTolerance = 1e-9;

// The LPS↔RAS change of basis C = diag(−1, −1, 1, 1) applied on both sides: C·m·C.
Eigen::Matrix4d flipRasLps(const Eigen::Matrix4d& m) {
  const Eigen::Vector4d c(-1, -1, 1, 1);
  return c.asDiagonal() * m * c.asDiagonal();
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, "cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw IoError(path, "read failed");
  return text.str();
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r\n") - a + 1);
}

// The numbers of `text` separated by blanks or commas; throws IoError naming `what` for a token that is not a number
// or not finite.
std::vector<double> parseNumbers(const std::string& path, const std::string& text, const std::string& what) {
  std::vector<double> out;
  std::istringstream in(text);
  std::string word, token;
  while (in >> word) {
    std::istringstream parts(word);
    while (std::getline(parts, token, ',')) {
      if (token.empty()) continue;
      errno = 0;
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') throw IoError(path, what + ": '" + token + "' is not a number");
      if (!std::isfinite(v)) throw IoError(path, what + ": '" + token + "' is not a finite number");
      out.push_back(v);
    }
  }
  return out;
}

// Rotation of the unit quaternion whose vector part is `v` (ITK's versor parameters; w = √(1 − |v|²) ≥ 0).
Eigen::Matrix3d versorRotation(const std::string& path, const Eigen::Vector3d& v) {
  const double n2 = v.squaredNorm();
  if (n2 > 1 + 1e-12) throw IoError(path, "versor parameters have norm > 1 (not a unit quaternion)");
  return Eigen::Quaterniond(std::sqrt(std::max(0.0, 1 - n2)), v[0], v[1], v[2]).toRotationMatrix();
}

// The 4×4 LPS map y = A·(x − c) + t + c of one ITK transform.
Eigen::Matrix4d itkMap(const std::string& path, const std::string& type, const std::vector<double>& p,
                       const std::vector<double>& fixed) {
  auto is = [&](const char* name) {
    return type == std::string(name) + "_double_3_3" || type == std::string(name) + "_float_3_3";
  };
  auto needParameters = [&](size_t n) {
    if (p.size() != n)
      throw IoError(path, type + " needs " + std::to_string(n) + " Parameters, found " + std::to_string(p.size()));
  };
  Eigen::Matrix3d a;
  Eigen::Vector3d t;
  if (is("AffineTransform") || is("MatrixOffsetTransformBase")) {
    needParameters(12);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a(r, c) = p[static_cast<size_t>(3 * r + c)];
    t = Eigen::Vector3d(p[9], p[10], p[11]);
  } else if (is("Euler3DTransform")) {
    needParameters(6);
    const Eigen::Matrix3d rx = Eigen::AngleAxisd(p[0], Eigen::Vector3d::UnitX()).toRotationMatrix();
    const Eigen::Matrix3d ry = Eigen::AngleAxisd(p[1], Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Matrix3d rz = Eigen::AngleAxisd(p[2], Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const bool zyx = fixed.size() == 4 && fixed[3] != 0;
    a = zyx ? Eigen::Matrix3d(rz * ry * rx) : Eigen::Matrix3d(rz * rx * ry);
    t = Eigen::Vector3d(p[3], p[4], p[5]);
  } else if (is("VersorRigid3DTransform")) {
    needParameters(6);
    a = versorRotation(path, Eigen::Vector3d(p[0], p[1], p[2]));
    t = Eigen::Vector3d(p[3], p[4], p[5]);
  } else if (is("Similarity3DTransform")) {
    needParameters(7);
    a = p[6] * versorRotation(path, Eigen::Vector3d(p[0], p[1], p[2]));
    t = Eigen::Vector3d(p[3], p[4], p[5]);
  } else {
    throw IoError(path, "unsupported ITK transform type '" + type +
                            "' (read: AffineTransform, MatrixOffsetTransformBase, Euler3DTransform, "
                            "VersorRigid3DTransform, Similarity3DTransform; 3-D, double or float)");
  }
  const bool euler = is("Euler3DTransform");
  if (!fixed.empty() && fixed.size() != 3 && !(euler && fixed.size() == 4))
    throw IoError(path, type + " needs 3 FixedParameters (the centre), found " + std::to_string(fixed.size()));
  const Eigen::Vector3d c = fixed.size() >= 3 ? Eigen::Vector3d(fixed[0], fixed[1], fixed[2]) : Eigen::Vector3d::Zero();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = a;
  m.topRightCorner<3, 1>() = t + c - a * c;
  return m;
}

// An ITK text transform file: the map it holds (LPS, subject → atlas), turned into atlas → subject in RAS.
Eigen::Matrix4d readItk(const std::string& path, const std::string& text) {
  std::istringstream in(text);
  std::string line, type;
  std::vector<double> parameters, fixed;
  bool haveParameters = false;
  int transforms = 0;
  while (std::getline(in, line)) {
    line = trim(line);
    if (line.empty() || line[0] == '#') continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) throw IoError(path, "unexpected line '" + line + "' in an ITK transform file");
    const std::string key = trim(line.substr(0, colon)), value = trim(line.substr(colon + 1));
    if (key == "Transform") {
      // A composite of a single transform is that transform; anything longer is not one linear map.
      if (value.rfind("CompositeTransform_", 0) == 0) continue;
      if (++transforms > 1) throw IoError(path, "holds more than one transform; only a single linear one is read");
      type = value;
    } else if (key == "Parameters") {
      if (transforms == 0) throw IoError(path, "Parameters before any Transform line");
      parameters = parseNumbers(path, value, "Parameters");
      haveParameters = true;
    } else if (key == "FixedParameters") {
      if (transforms == 0) throw IoError(path, "FixedParameters before any Transform line");
      fixed = parseNumbers(path, value, "FixedParameters");
    } else {
      throw IoError(path, "unknown key '" + key + "' in an ITK transform file");
    }
  }
  if (transforms == 0) throw IoError(path, "ITK transform file without a Transform line");
  if (!haveParameters) throw IoError(path, "ITK transform file without a Parameters line");
  const Eigen::Matrix4d lps = itkMap(path, type, parameters, fixed);
  const std::string problem = linearTransformProblem(lps);
  if (!problem.empty()) throw IoError(path, "the ITK transform " + problem);
  return flipRasLps(lps).inverse();
}

// Rows of 4 numbers (3 or 4 rows) as a 4×4 matrix, the missing last row 0 0 0 1.
Eigen::Matrix4d fromRows(const std::string& path, const std::vector<std::vector<double>>& rows) {
  for (size_t r = 0; r < rows.size() && r < 4; ++r)
    if (rows[r].size() != 4)
      throw IoError(path, "row " + std::to_string(r + 1) + " has " + std::to_string(rows[r].size()) +
                              " numbers; each row needs 4");
  if (rows.size() != 3 && rows.size() != 4)
    throw IoError(path, "found " + std::to_string(rows.size()) + " rows; a matrix needs 4 (or 3) rows of 4 numbers");
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (size_t r = 0; r < rows.size(); ++r)
    for (size_t c = 0; c < 4; ++c) m(static_cast<int>(r), static_cast<int>(c)) = rows[r][c];
  return m;
}

Eigen::Matrix4d readJsonMatrix(const std::string& path) {
  const Json doc = readJsonFile(path);
  const Json* rows = &doc;
  bool lps = false;
  if (doc.is_object()) {
    for (const auto& item : doc.items())
      if (item.key() != "matrix" && item.key() != "space")
        throw IoError(path, "unknown key \"" + item.key() + "\" (known: matrix, space)");
    rows = jsonMember(doc, "matrix");
    if (!rows) throw IoError(path, "no \"matrix\" member");
    if (const Json* space = jsonMember(doc, "space")) {
      if (!space->is_string() || (*space != "RAS" && *space != "LPS"))
        throw IoError(path, "\"space\" must be \"RAS\" or \"LPS\"");
      lps = *space == "LPS";
    }
  }
  if (!rows->is_array()) throw IoError(path, "the matrix must be an array of rows");
  std::vector<std::vector<double>> values;
  for (const Json& row : *rows) {
    if (!row.is_array()) throw IoError(path, "the matrix must be an array of rows of numbers");
    values.emplace_back();
    for (const Json& x : row) {
      if (!x.is_number()) throw IoError(path, "matrix row " + std::to_string(values.size()) + " holds a non-number");
      values.back().push_back(x.get<double>());
    }
  }
  const Eigen::Matrix4d m = fromRows(path, values);
  return lps ? flipRasLps(m) : m;
}

Eigen::Matrix4d readPlainMatrix(const std::string& path, const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    line = trim(line.substr(0, line.find('#')));
    if (line.empty()) continue;
    rows.push_back(parseNumbers(path, line, "row " + std::to_string(rows.size() + 1)));
  }
  if (rows.empty()) throw IoError(path, "empty file: expected 4 (or 3) rows of 4 numbers");
  return fromRows(path, rows);
}

}  // namespace

std::string linearTransformProblem(const Eigen::Matrix4d& m) {
  if (!m.allFinite()) return "has a non-finite entry";
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kLastRowTolerance)
    return "is not affine: its last row must be 0 0 0 1";
  const Eigen::Matrix3d a = m.topLeftCorner<3, 3>();
  if (std::fabs(a.determinant()) <= 1e-6) return "is singular (|det| ≤ 1e-6)";
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(a).singularValues();
  if (sv[0] > 1e6 * sv[2])
    return "is ill-conditioned (singular values " + std::to_string(sv[0]) + " / " + std::to_string(sv[2]) + " > 1e6)";
  return "";
}

Eigen::Matrix4d readLinearTransform(const std::string& path) {
  const std::string ext = fileExtension(path);
  if (ext == ".h5" || ext == ".hdf5" || ext == ".mat")
    throw IoError(path, "binary ITK transforms are not read; save the transform as a text .tfm");
  const std::string text = readText(path);
  const std::string start = trim(text.substr(0, text.find('\n')));
  Eigen::Matrix4d m;
  if (start.rfind(kItkHeader, 0) == 0) {
    m = readItk(path, text);
  } else if (ext == ".tfm") {
    throw IoError(path, std::string("not an ITK text transform (first line is not '") + kItkHeader + "')");
  } else {
    const std::string body = trim(text);
    m = !body.empty() && (body[0] == '{' || body[0] == '[') ? readJsonMatrix(path) : readPlainMatrix(path, text);
  }
  const std::string problem = linearTransformProblem(m);
  if (!problem.empty()) throw IoError(path, "the transform " + problem);
  m.row(3) = Eigen::RowVector4d(0, 0, 0, 1);
  return m;
}

void writeSlicerTransform(const std::string& path, const Eigen::Matrix4d& atlasToSubjectRas) {
  const std::string problem = linearTransformProblem(atlasToSubjectRas);
  if (!problem.empty()) throw ParameterError("atlasToSubjectRas", "(4×4 matrix)", "the transform " + problem);
  Eigen::Matrix4d m = atlasToSubjectRas;
  m.row(3) = Eigen::RowVector4d(0, 0, 0, 1);
  const Eigen::Matrix4d lps = flipRasLps(m.inverse());  // Slicer's "from parent" in LPS: subject → atlas
  std::ostringstream out;
  out << std::setprecision(17);
  auto put = [&](double v) { out << ' ' << (v == 0 ? 0.0 : v); };  // no "-0"
  out << kItkHeader << "\n#Transform 0\nTransform: AffineTransform_double_3_3\nParameters:";
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) put(lps(r, c));
  for (int r = 0; r < 3; ++r) put(lps(r, 3));
  out << "\nFixedParameters: 0 0 0\n";
  writeAtomically(path, [&](const std::string& temp) {
    std::ofstream f(temp, std::ios::binary);
    if (!f) throw IoError(path, "cannot open for writing");
    f << out.str();
    f.close();
    if (!f) throw IoError(path, "write failed");
  });
}

}  // namespace msk
