#include "msk/test/cli.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>

#include "msk/test/files.h"

namespace msk::test {

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

}  // namespace msk::test
