#include "msk/test/files.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

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

std::string bundledSample() { return std::string(MSK_SOURCE_DIR) + "/data-samples/thigh-seed1/"; }

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

}  // namespace msk::test
