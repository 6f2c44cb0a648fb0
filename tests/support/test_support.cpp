#include "test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <sys/wait.h>

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

}  // namespace msk::test
