#pragma once
/// Shared test helpers: scratch folders, the real-data folder, running the mskseg program.
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

/// ../shared/data (or MSK_SHARED_DATA), empty string if absent.
std::string sharedData();

/// Result of running the CLI.
struct CliResult {
  int exitCode = -1;
  std::string out, err;
};

/// Runs the built mskseg with arguments (each shell-quoted), capturing stdout and stderr.
CliResult runCli(const std::vector<std::string>& args);

/// Number of lines in a text.
int lineCount(const std::string& text);

/// Checks a failed CLI run: the exit code, exactly one line on stderr, naming `file` (if non-empty) and `phrase`.
void expectOneLineError(const CliResult& r, int code, const std::string& file, const std::string& phrase);

/// Writes bytes to a file (test fixtures).
void writeBytes(const std::string& path, const std::string& bytes);
/// Reads a whole file.
std::string readBytes(const std::string& path);

}  // namespace msk::test
