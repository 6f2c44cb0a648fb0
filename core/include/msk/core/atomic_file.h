#pragma once
/// Atomic output: write to a temporary file beside the target, then rename over it.
#include <functional>
#include <string>

namespace msk {

/// A temporary path beside `target` that becomes `target` on commit(); removed if never committed.
class AtomicFile {
 public:
  /// Prepares a unique temporary name in the target's folder (the folder must exist).
  explicit AtomicFile(std::string target);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  /// Where to write. Keeps the target's extension(s) so format-sniffing writers still work.
  const std::string& tempPath() const { return temp_; }
  /// The final path.
  const std::string& target() const { return target_; }
  /// Renames the temporary file onto the target; throws IoError if it is missing or the rename fails.
  void commit();

 private:
  std::string target_, temp_;
  bool committed_ = false;
};

/// Runs `write(tempPath)` and commits; on any exception the temporary file is removed and the error rethrown.
void writeAtomically(const std::string& target, const std::function<void(const std::string& tempPath)>& write);

/// Lower-cased extension including ".gz" pairs: "a/b.nii.gz" -> ".nii.gz", "x.VTK" -> ".vtk".
std::string fileExtension(const std::string& path);

}  // namespace msk
