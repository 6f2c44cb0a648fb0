#pragma once
/// Running the built mskseg program from a test, and checking its one-line errors.
#include <string>
#include <vector>

namespace msk::test {

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

}  // namespace msk::test
