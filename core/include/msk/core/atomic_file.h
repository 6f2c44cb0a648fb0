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

/// Whether `name` is a safe object name: 1–64 ASCII letters, digits, '_', '.' or '-', the first a letter or digit.
/// Object names name output files (<name>.vtk, qc/<name>_axial.png), so that no name can leave its output folder,
/// hide a file, or carry bytes a report or a terminal cannot show.
bool isSafeName(const std::string& name);

/// `name` shown in a message: printable ASCII kept, every other byte as \xHH, cut to 80 characters.
std::string printableName(const std::string& name);

/// `text` safe to print on a terminal or into a log: control characters (other than tab), which could move the cursor
/// or recolour the terminal, become \xHH; everything else (printable ASCII, UTF-8) is kept.
std::string printableText(const std::string& text);

/// The path of file `fileName` in `folder`. Throws IoError naming the folder if the file name is empty, ".", "..",
/// contains '/', '\\' or a NUL byte, or is longer than 255 bytes: every output path is built here, so that none
/// leaves its folder.
std::string fileInFolder(const std::string& folder, const std::string& fileName);

/// Lower-cased extension including ".gz" pairs: "a/b.nii.gz" -> ".nii.gz", "x.VTK" -> ".vtk".
std::string fileExtension(const std::string& path);

}  // namespace msk
