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

/// Runs the program `exe` (e.g. a 3D Slicer module's copy of mskseg) the same way.
CliResult runProgram(const std::string& exe, const std::vector<std::string>& args);

/// The built mskseg running in the background (stdout and stderr into files), started by startCli().
struct CliProcess {
  int pid = -1;
  std::string outFile, errFile;
};

/// Starts the built mskseg with arguments in the background, its output into `outFile` and `errFile`.
CliProcess startCli(const std::vector<std::string>& args, const std::string& outFile, const std::string& errFile);

/// Waits for a process started by startCli() to end: its exit code, 128 + the signal if a signal ended it, -1 if it
/// had not ended after `seconds`.
int waitCli(const CliProcess& p, double seconds);

/// The ids of the running processes whose command line contains `text` (e.g. an output folder).
std::vector<int> processesMentioning(const std::string& text);

/// Number of lines in a text.
int lineCount(const std::string& text);

/// Checks a failed CLI run: the exit code, exactly one line on stderr, naming `file` (if non-empty) and `phrase`.
void expectOneLineError(const CliResult& r, int code, const std::string& file, const std::string& phrase);

}  // namespace msk::test
