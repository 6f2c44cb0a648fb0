#include "msk/core/atomic_file.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <filesystem>
#include <system_error>

#include "msk/core/error.h"

namespace fs = std::filesystem;

namespace msk {

bool isSafeName(const std::string& name) {
  if (name.empty() || name.size() > 64 || !std::isalnum(static_cast<unsigned char>(name[0]))) return false;
  for (char ch : name) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c >= 128 || !(std::isalnum(c) || c == '_' || c == '.' || c == '-')) return false;
  }
  return true;
}

namespace {
/// Appends byte `c` as \xHH.
void appendEscaped(std::string& out, unsigned char c) {
  static const char* hex = "0123456789abcdef";
  out += "\\x";
  out += hex[c >> 4];
  out += hex[c & 15];
}
}  // namespace

std::string printableText(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    const unsigned char next = i + 1 < text.size() ? static_cast<unsigned char>(text[i + 1]) : 0;
    if ((c < 32 && c != '\t') || c == 127) {
      appendEscaped(out, c);
    } else if (c == 0xc2 && next >= 0x80 && next <= 0x9f) {  // U+0080..U+009F, the C1 controls, in UTF-8
      appendEscaped(out, c);
      appendEscaped(out, next);
      ++i;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

std::string printableName(const std::string& name) {
  std::string out;
  for (char ch : name) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c >= 32 && c < 127)
      out += ch;
    else
      appendEscaped(out, c);
    if (out.size() >= 80) return out + "...";
  }
  return out;
}

std::string fileInFolder(const std::string& folder, const std::string& fileName) {
  if (fileName.empty() || fileName == "." || fileName == ".." || fileName.size() > 255 ||
      fileName.find_first_of(std::string("/\\\0", 3)) != std::string::npos)
    throw IoError(folder, "the file name \"" + printableName(fileName) + "\" would leave the folder or is not a name");
  return (fs::path(folder) / fileName).string();
}

std::string fileExtension(const std::string& path) {
  std::string name = fs::path(path).filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
  auto dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0) return "";
  std::string ext = name.substr(dot);
  if (ext == ".gz") {
    auto dot2 = name.rfind('.', dot - 1);
    if (dot2 != std::string::npos && dot2 != 0) ext = name.substr(dot2);
  }
  return ext;
}

AtomicFile::AtomicFile(std::string target) : target_(std::move(target)) {
  static std::atomic<unsigned> counter{0};
  fs::path t(target_);
  fs::path dir = t.has_parent_path() ? t.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw IoError(target_, "output folder does not exist");
  std::string ext = fileExtension(target_);
  std::string stem = t.filename().string();
  stem = stem.substr(0, stem.size() - ext.size());
  temp_ = (dir / ("." + stem + ".tmp" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + ext)).string();
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void AtomicFile::commit() {
  std::error_code ec;
  if (!fs::exists(temp_, ec)) throw IoError(target_, "writer produced no output");
  fs::rename(temp_, target_, ec);
  if (ec) throw IoError(target_, "cannot move the finished file into place: " + ec.message());
  committed_ = true;
}

void writeAtomically(const std::string& target, const std::function<void(const std::string&)>& write) {
  AtomicFile f(target);
  write(f.tempPath());
  f.commit();
}

}  // namespace msk
