#include "test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <sys/wait.h>

#include "msk/core/error.h"

namespace fs = std::filesystem;

namespace msk::test {

ScratchDir::ScratchDir() {
  std::random_device rd;
  for (;;) {
    fs::path p = fs::temp_directory_path() / ("mskseg_test_" + std::to_string(rd()));
    std::error_code ec;
    if (fs::create_directory(p, ec)) {
      path_ = p.string();
      return;
    }
  }
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::vector<std::string> ScratchDir::list() const {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string sharedData() {
  const char* env = std::getenv("MSK_SHARED_DATA");
  std::string p = env ? env : MSK_SHARED_DATA;
  std::error_code ec;
  return fs::is_directory(p, ec) ? p : "";
}

namespace {
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

CliResult runCli(const std::vector<std::string>& args) {
  ScratchDir tmp;
  std::string cmd = quote(MSKSEG_EXE);
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " >" + quote(tmp.file("out")) + " 2>" + quote(tmp.file("err")) + " </dev/null";
  int status = std::system(cmd.c_str());
  CliResult r;
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = readBytes(tmp.file("out"));
  r.err = readBytes(tmp.file("err"));
  return r;
}

int lineCount(const std::string& text) { return static_cast<int>(std::count(text.begin(), text.end(), '\n')); }

void expectOneLineError(const CliResult& r, int code, const std::string& file, const std::string& phrase) {
  EXPECT_EQ(r.exitCode, code) << r.err;
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  if (!file.empty()) {
    EXPECT_NE(r.err.find(file), std::string::npos) << r.err;
  }
  EXPECT_NE(r.err.find(phrase), std::string::npos) << "wanted '" << phrase << "' in: " << r.err;
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary);
  f << bytes;
}

std::string readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

Eigen::Vector3d labelCentroid(const LabelMap& labels, int label) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double n = 0;
  for (int k = 0; k < labels.grid.dims[2]; ++k)
    for (int j = 0; j < labels.grid.dims[1]; ++j)
      for (int i = 0; i < labels.grid.dims[0]; ++i)
        if (labels.at(i, j, k) == label) {
          sum += labels.grid.toWorld(Eigen::Vector3d(i, j, k));
          n += 1;
        }
  if (n == 0) throw Error("label " + std::to_string(label) + " not found");
  return sum / n;
}

TriangleMesh mirroredTemplate(const LabelMap& labels, int fromLabel, double midX, const TemplateOptions& opts) {
  return mirrorMesh(templateFromLabels(labels, fromLabel, opts), Eigen::Vector3d(midX, 0, 0), Eigen::Vector3d::UnitX());
}

TriangleMesh displacedScaled(const TriangleMesh& mesh, const Eigen::Vector3d& offsetMm, double scale) {
  TriangleMesh out = mesh;
  const Eigen::RowVector3d c = mesh.vertices.colwise().mean();
  out.vertices = ((mesh.vertices.rowwise() - c) * scale).rowwise() + (c + offsetMm.transpose());
  return out;
}

void voxelBox(const Grid& grid, const std::vector<TriangleMesh>& meshes, double marginMm, Eigen::Vector3i& lo,
              Eigen::Vector3i& hi) {
  Eigen::Vector3d a = Eigen::Vector3d::Constant(1e300), b = Eigen::Vector3d::Constant(-1e300);
  for (const TriangleMesh& m : meshes)
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
      const Eigen::Vector3d p = grid.toVoxel(m.vertices.row(v).transpose());
      a = a.cwiseMin(p);
      b = b.cwiseMax(p);
    }
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(marginMm).cwiseQuotient(grid.spacing);
  for (int d = 0; d < 3; ++d) {
    lo[d] = std::clamp(static_cast<int>(std::floor(a[d] - margin[d])), 0, grid.dims[d] - 1);
    hi[d] = std::clamp(static_cast<int>(std::ceil(b[d] + margin[d])), lo[d], grid.dims[d] - 1);
  }
}

namespace {
template <typename T>
Volume<T> cropAny(const Volume<T>& v, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) {
  Grid g = v.grid;
  g.dims = hi - lo + Eigen::Vector3i::Ones();
  g.origin = v.grid.toWorld(lo.cast<double>());
  Volume<T> out(g);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) out.at(i, j, k) = v.at(i + lo[0], j + lo[1], k + lo[2]);
  return out;
}
}  // namespace

ImageF cropVolume(const ImageF& image, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) {
  return cropAny(image, lo, hi);
}

LabelMap cropVolume(const LabelMap& labels, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) {
  return cropAny(labels, lo, hi);
}

ImageF partialVolumeImage(const Grid& grid, const std::function<bool(const Eigen::Vector3d&)>& isInside, float inside,
                          float outside) {
  ImageF img(grid, outside);
  const int ss = 4;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        int in = 0;
        for (int a = 0; a < ss; ++a)
          for (int b = 0; b < ss; ++b)
            for (int c = 0; c < ss; ++c)
              in += isInside(grid.toWorld(Eigen::Vector3d(i + (a + 0.5) / ss - 0.5, j + (b + 0.5) / ss - 0.5,
                                                          k + (c + 0.5) / ss - 0.5)));
        const double f = static_cast<double>(in) / (ss * ss * ss);
        img.at(i, j, k) = static_cast<float>(f * inside + (1 - f) * outside);
      }
  return img;
}

TriangleMesh joinedMeshes(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m = a;
  m.vertices.conservativeResize(a.vertexCount() + b.vertexCount(), 3);
  m.vertices.bottomRows(b.vertexCount()) = b.vertices;
  m.faces.conservativeResize(a.faceCount() + b.faceCount(), 3);
  m.faces.bottomRows(b.faceCount()) = b.faces.array() + a.vertexCount();
  return m;
}

}  // namespace msk::test
