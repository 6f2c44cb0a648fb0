#include "msk/test/cli.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <thread>

#include "msk/test/files.h"

namespace msk::test {

namespace {
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

CliResult runCli(const std::vector<std::string>& args) { return runProgram(MSKSEG_EXE, args); }

CliResult runProgram(const std::string& exe, const std::vector<std::string>& args) {
  ScratchDir tmp;
  std::string cmd = quote(exe);
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " >" + quote(tmp.file("out")) + " 2>" + quote(tmp.file("err")) + " </dev/null";
  int status = std::system(cmd.c_str());
  CliResult r;
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = readBytes(tmp.file("out"));
  r.err = readBytes(tmp.file("err"));
  return r;
}

CliProcess startCli(const std::vector<std::string>& args, const std::string& outFile, const std::string& errFile) {
  std::vector<std::string> argv = {MSKSEG_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> cargs;
  for (std::string& a : argv) cargs.push_back(a.data());
  cargs.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int out = ::open(outFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = ::open(errFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int in = ::open("/dev/null", O_RDONLY);
    if (out < 0 || err < 0 || in < 0 || ::dup2(out, 1) < 0 || ::dup2(err, 2) < 0 || ::dup2(in, 0) < 0) _exit(126);
    ::execv(MSKSEG_EXE, cargs.data());
    _exit(127);
  }
  return {static_cast<int>(pid), outFile, errFile};
}

int waitCli(const CliProcess& p, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(p.pid, &status, WNOHANG);
    if (r == p.pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (r < 0 || std::chrono::steady_clock::now() > end) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

std::vector<int> processesMentioning(const std::string& text) {
  std::vector<int> pids;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator("/proc", ec)) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::string cmd = readBytes(e.path().string() + "/cmdline");
    std::replace(cmd.begin(), cmd.end(), '\0', ' ');
    if (cmd.find(text) != std::string::npos) pids.push_back(std::stoi(name));
  }
  return pids;
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

}  // namespace msk::test
