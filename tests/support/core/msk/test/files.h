#pragma once
/// Files for tests and benchmarks: scratch folders, the bundled sample, the real-scan folder, whole-file bytes.
#include <string>
#include <vector>

namespace msk::test {

/// A fresh empty folder under the system temp dir, removed when the object dies.
class ScratchDir {
 public:
  ScratchDir();
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  /// The folder.
  const std::string& path() const { return path_; }
  /// path()/name.
  std::string file(const std::string& name) const { return path_ + "/" + name; }
  /// Names of the files in the folder (sorted).
  std::vector<std::string> list() const;

 private:
  std::string path_;
};

/// The real scans: $MSK_SHARED_DATA, else the build's MSK_SHARED_DATA (../shared/data); empty string if absent.
std::string sharedData();

/// The bundled phantom data-samples/thigh-seed1 of the source tree, with a trailing slash.
std::string bundledSample();

/// Writes bytes to a file (test fixtures).
void writeBytes(const std::string& path, const std::string& bytes);
/// Reads a whole file (empty if it cannot be read).
std::string readBytes(const std::string& path);

}  // namespace msk::test
